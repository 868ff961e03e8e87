"""The design loop's sensitivities with activation sets against finite differences of the
equilibrium energies (issue #22): on a small tube with two clutches, pull switching clutch a
on, twist clutch b at half voltage, a lockout, every state's BESO sensitivity (element energy
density times the interpolation factor, docs/method/index.md, "BESO") times ``p A_e`` is the derivative
of that state's equilibrium energy along a design perturbation (the envelope theorem: at an
equilibrium only the explicit dependence counts), and the objective's combined sensitivities
are the derivative of the objective's terms, each motion's normalisation held."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from kgarment.optimize.loop import initial_state, solve
from kgarment.optimize.objective import combine_sensitivities, objective_value
from kgarment.optimize.setup import DesignSetup
from kgarment.problem import BesoParams
from kgarment.sim import SolverOptions, build_model
from kgarment.sim.synthetic import Tube

LOCKOUT = 0.7
SETS = {"pull": np.array([1.0, 0.0]), "twist": np.array([0.0, 0.5])}


@pytest.fixture(scope="module")
def perturbed():
    """The tube, its design (two reinforced bands of 2 rad round the clutches, plain cloth
    between, and isolated test faces inside the bands at 0.3 and at 2e-3, near plain cloth), the
    loop's solve of every state, and the equilibrium energies at the design moved by
    ``+- h d_e u_e`` on the test faces (u in [0.2, 1])."""
    tube = Tube(0.05, 0.0, 0.3, 16, 9)
    clutches = [tube.clutch("a", 0.0, 0.08, 0.22, 0.01, 8), tube.clutch("b", np.pi, 0.08, 0.22, 0.01, 8)]
    model = build_model(tube.vertices, tube.faces, clutches, preset="paper")
    motions = {"pull": tube.motion("pull", 0.05, 0.0), "twist": tube.motion("twist", 0.0, 0.3)}
    opts = SolverOptions(tol=1e-9, max_iter=400)
    setup = DesignSetup.build(model, motions, "active", BesoParams(), opts, activation=SETS, lockout=LOCKOUT)
    F, m = tube.faces, len(tube.faces)
    c = tube.vertices[F].mean(1)
    theta = np.arctan2(c[:, 1], c[:, 0])
    band = (np.abs(theta) < 1.0) | (np.abs(np.abs(theta) - np.pi) < 1.0)
    row = np.arange(m) % tube.n_cells % (tube.n_z - 1)
    # test faces: the penalties scale with the stiffest face round each vertex (sim.energy.
    # penalty_weights), so a test face's vertices must touch reinforced faces only, and
    # no two test faces share a vertex; none under a clutch or in the held end rows
    soft_vertex = np.zeros(len(tube.vertices), bool)
    soft_vertex[F[~band].ravel()] = True
    ok = band & ~soft_vertex[F].any(1) & (row > 0) & (row < tube.n_z - 2)
    ok[np.concatenate([cl.bind_face for cl in clutches])] = False
    test, used = [], np.zeros(len(tube.vertices), bool)
    for e in np.nonzero(ok)[0]:
        if not used[F[e]].any():
            test.append(e)
            used[F[e]] = True
    test = np.array(test)
    design = np.where(band, 1.0, 1e-3)
    design[test] = np.where(np.arange(len(test)) % 2 == 0, 0.3, 2e-3)
    u = np.zeros(m)
    u[test] = np.random.default_rng(0).uniform(0.2, 1.0, len(test)) * design[test]
    st = dataclasses.replace(initial_state(setup), design=design)
    solved = solve(setup, st)
    states = [s for _, s in setup.case.states()]
    h = 1e-3
    warm = [r.x for r in solved.results]
    plus = setup.case.solve(design + h * u, states, warm_start=warm, options=opts)
    minus = setup.case.solve(design - h * u, states, warm_start=warm, options=opts)
    return setup, setup.case.areas, test, u, h, solved, plus, minus


def test_every_states_sensitivity_is_its_energys_derivative(perturbed):
    setup, area, test, u, h, solved, plus, minus = perturbed
    assert len(test) >= 6 and set(solved.keys) == {("pull", "on"), ("pull", "off"), ("pull", "lock:twist"),
                                                    ("twist", "on"), ("twist", "off"), ("twist", "lock:pull")}
    assert all(r.converged for r in [*solved.results, *plus, *minus])
    p = setup.case.model.preset.penal
    for k, rp, rm in zip(solved.keys, plus, minus):
        fd = (rp.total_energy - rm.total_energy) / (2 * h)
        assert fd == pytest.approx(p * float(np.sum(area * solved.alpha[k] * u)), rel=1e-4), k
        assert abs(fd) > 1e-3  # a derivative, not a cancellation


def test_the_combined_sensitivities_are_the_objectives_derivative(perturbed):
    """The objective's terms (ON - OFF - lockout x (LOCK - OFF)) / n_m, n_m each motion's
    largest ON sensitivity (docs/method/index.md: the per-motion normalisation), differentiated by finite
    differences of the equilibrium energies, against the loop's combined sensitivities."""
    setup, area, _, u, h, solved, plus, minus = perturbed
    motions = list(setup.case.motions)
    norm = {(mo, "on"): float(solved.alpha[(mo, "on")].max()) for mo in motions}
    combined = combine_sensitivities("active", solved.alpha, motions, LOCKOUT)
    value = {}
    for sign, results in ((1, plus), (-1, minus)):
        energy = {k: r.total_energy for k, r in zip(solved.keys, results)}
        value[sign] = objective_value("active", energy, norm, motions, LOCKOUT)
    fd = (value[1] - value[-1]) / (2 * h)
    assert fd == pytest.approx(setup.case.model.preset.penal * float(np.sum(area * combined * u)), rel=1e-4)
    # the lock states count: without the lockout the derivative differs
    plain = combine_sensitivities("active", solved.alpha, motions, 0.0)
    assert abs(float(np.sum(area * (plain - combined) * u))) > 1e-3 * abs(float(np.sum(area * combined * u)))
