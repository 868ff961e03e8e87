"""Clutch tension against a hand calculation: a strip in uniaxial tension."""

from __future__ import annotations

import numpy as np
import pytest

from kgarment.sim import SimState, SolverOptions, build_model, clutch_tensions, solve_states
from kgarment.sim.materials import REFERENCE
from kgarment.sim.synthetic import Tube


@pytest.mark.parametrize("activation", [1.0, 0.0])
def test_tension_of_a_strip_in_uniaxial_tension(activation):
    """A 14 cm x 1 cm clutch along a tube stretched by 1% along its axis: between its anchors
    the strip is a bar in uniaxial tension, so it carries T = Y t w eps (plane-stress
    neo-Hookean at small strain; Y, t the clutch's material at this activation, w its
    width, eps its measured axial strain).  The anchors hold the strip's full width at its
    ends, where the tube's contraction differs from the strip's own: an end effect of a
    few per cent at this aspect ratio."""
    tube = Tube(0.05, 0.0, 0.3, 48, 31)
    width = 0.01
    clutch = tube.clutch("c0", 0.3, 0.08, 0.22, width, 28)
    model = build_model(tube.vertices, tube.faces, [clutch], preset="reference")
    motion = tube.motion("pull", 0.01, 0.0)
    state = SimState.create(motion, [activation])
    design = np.ones(model.n_faces)
    (r,) = solve_states(model, design, [state], options=SolverOptions(tol=1e-7, max_iter=400))
    assert r.converged
    _, (xc,) = model.split(r.x)
    line = xc[clutch.centerline]
    rest = clutch.rest_vertices()[clutch.centerline]
    eps = np.linalg.norm(np.diff(line, axis=0), axis=1).sum() / np.linalg.norm(np.diff(rest, axis=0), axis=1).sum() - 1
    assert 0.005 < eps < 0.015
    young = activation * REFERENCE.young_clutch_on + (1 - activation) * REFERENCE.young_clutch_off
    thick = activation * REFERENCE.thick_clutch_on + (1 - activation) * REFERENCE.thick_clutch_off
    expected = young * thick * width * eps
    (t,) = clutch_tensions(model, design, state, r.x)
    assert t == pytest.approx(expected, rel=0.05)


def test_no_clutches_no_tensions():
    tube = Tube(0.05, 0.0, 0.3, 12, 8)
    model = build_model(tube.vertices, tube.faces, [], preset="reference")
    state = SimState.create(tube.motion("pull", 0.01, 0.0), [])
    assert clutch_tensions(model, np.ones(model.n_faces), state, model.initial_positions(tube.vertices)).shape == (0,)
