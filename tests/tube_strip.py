"""A clutch strip along a tube pulled along its axis: the scene the clutch models' hand
calculations share (test_sim_slip, test_sim_cable)."""

from __future__ import annotations

import numpy as np

from kgarment.sim import SimState, SolverOptions, build_model, clutch_tensions, solve_states
from kgarment.sim.synthetic import Tube


def pull_strip(stretch, hold, activation=1.0, cable=False):
    """A 14 x 1 cm clutch along a 30 cm tube (reference materials, fully reinforced) whose
    top ring moves by ``stretch`` of its length, the clutch holding ``hold`` N (None:
    locked) at ``activation``, as a band or a ``cable``.  Returns the strip's centre-line
    strain, its tension (N), its width (m), and the model, state and solve result."""
    tube = Tube(0.05, 0.0, 0.3, 48, 31)
    width = 0.01
    clutch = tube.clutch("c0", 0.3, 0.08, 0.22, width, 28)
    model = build_model(tube.vertices, tube.faces, [clutch], preset="reference",
                        holding_force=None if hold is None else [hold], clutch_cable=cable)
    state = SimState.create(tube.motion("pull", stretch, 0.0), [activation])
    design = np.ones(model.n_faces)
    (r,) = solve_states(model, design, [state], options=SolverOptions(tol=1e-7, max_iter=400))
    assert r.converged
    _, (xc,) = model.split(r.x)
    line, rest = xc[clutch.centerline], clutch.rest_vertices()[clutch.centerline]
    eps = np.linalg.norm(np.diff(line, axis=0), axis=1).sum() / np.linalg.norm(np.diff(rest, axis=0), axis=1).sum() - 1
    (t,) = clutch_tensions(model, design, state, r.x)
    return eps, t, width, model, state, r
