"""Where a frame of the force over the motion starts (kgarment.evaluate.path.predicted): on a
smooth path of equilibria the secant predictor lands much closer to the next equilibrium
than the last one carried with the body, and Newton needs fewer iterations from it."""

from __future__ import annotations

import numpy as np

from kgarment.evaluate.path import carried, predicted
from kgarment.sim import SimState, SolverOptions, build_model, solve_states
from kgarment.sim.model import Motion
from kgarment.sim.synthetic import Tube, sphere_body


def test_the_secant_start_of_a_frame_is_closer_than_the_carried_equilibrium():
    tube = Tube(0.05, 0.0, 0.3, 32, 21)
    model = build_model(tube.vertices, tube.faces, [], preset="reference")
    far_body = sphere_body(0.05, 2)  # 5 m away: a free membrane, held by its two rings
    far_body = (far_body[0] + [0.0, 0.0, 5.0],) + far_body[1:]

    def frame(k: int) -> Motion:  # the top ring pulled 2% of the length further at each frame
        m = tube.motion(f"f{k}", 0.02 * k, 0.0)
        return Motion.create(m.name, m.garment_x0, far_body[0], far_body[1], m.attach_faces, m.attach_targets,
                             far_body[2], on_surface=False)

    frames = [frame(k) for k in (1, 2, 3)]
    design = np.ones(model.n_faces)
    opts = SolverOptions(tol=1e-10, max_iter=400)
    x = [r.x for r in solve_states(model, design, [SimState.create(f, [], name=f.name) for f in frames],
                                   options=opts)]
    assert predicted(model, [], frames[2]) is None  # nothing before: the skin-tight start
    one = predicted(model, [(x[1], frames[1])], frames[2])
    assert np.array_equal(one, carried(model, x[1], frames[1], frames[2]))
    two = predicted(model, [(x[0], frames[0]), (x[1], frames[1])], frames[2])
    # the cloth narrows as it is pulled (its skin-tight start keeps the tube's radius): the
    # secant extrapolates that move against the start, the carried equilibrium does not
    far, near = np.abs(one - x[2]).max(), np.abs(two - x[2]).max()
    assert near < 0.2 * far, (near, far)
    state = SimState.create(frames[2], [], name="again")
    (from_one,), (from_two,) = (solve_states(model, design, [state], warm_start=[w], options=opts) for w in (one, two))
    assert from_one.converged and from_two.converged
    assert from_two.convergence.iterations < from_one.convergence.iterations
    np.testing.assert_allclose(from_two.x, x[2], atol=1e-7)  # the same equilibrium either way
