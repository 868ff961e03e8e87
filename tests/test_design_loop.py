"""The BESO loop on a flat sheet: load path, objective growth, exact resume, end to end."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

from kgarment.design.run import load_checkpoint, save_checkpoint
from kgarment.optimize import BesoParams
from kgarment.optimize.loop import initial_state, run_loop
from kgarment.optimize.setup import DesignSetup


def _sheet_setup(objective="passive", max_iterations=12, target=0.3, n=10):
    from kgarment.sim import Motion, SolverOptions, build_model

    xs, ys = np.meshgrid(np.linspace(0, 0.2, n + 1), np.linspace(0, 0.2, n + 1))
    V = np.c_[xs.ravel(), ys.ravel(), np.zeros(xs.size)]
    idx = np.arange(len(V)).reshape(n + 1, n + 1)
    a, b, c, d = idx[:-1, :-1].ravel(), idx[:-1, 1:].ravel(), idx[1:, 1:].ravel(), idx[1:, :-1].ravel()
    F = np.r_[np.c_[a, b, c], np.c_[a, c, d]]
    cent = V[F].mean(1)
    # clamp two corner patches and pull them apart along the diagonal
    lo = (cent[:, 0] < 0.045) & (cent[:, 1] < 0.045)
    hi = (cent[:, 0] > 0.155) & (cent[:, 1] > 0.155)
    attach = np.flatnonzero(lo | hi)
    u = np.array([1.0, 1.0, 0.0]) / np.sqrt(2)
    X1 = V + 0.1 * ((V - 0.1) @ u)[:, None] * u  # 10% stretch along the diagonal
    targets = X1[F[attach]].mean(1)
    ball = trimesh.creation.icosphere(2, radius=0.02)
    far = ball.vertices + [5.0, 5.0, 5.0]  # a body far away: no contact
    motion = Motion.create("pull", X1, far, ball.vertex_normals, attach, targets, ball.faces)
    model = build_model(V, F, [], preset="reference")
    params = BesoParams(target_area=target, er=0.1, ar_max=0.05, max_iterations=max_iterations)
    return DesignSetup.build(model, {"pull": motion}, objective, params, SolverOptions()), cent


def test_reinforcement_follows_the_load_path_and_the_objective_grows():
    setup, cent = _sheet_setup()
    st = run_loop(setup, initial_state(setup))
    final = st.designs[-1]
    assert abs(st.metrics[-1]["area"] - 0.3) < 0.03
    # distance of each face from the diagonal between the clamped corners
    dist = np.abs(cent[:, 0] - cent[:, 1]) / np.sqrt(2)
    assert dist[final].mean() < 0.6 * dist.mean()
    rho = [r["rho[pull:none]"] for r in st.metrics]
    assert rho[0] == pytest.approx(1.0) and rho[-1] > 1.3
    assert st.metrics[-1]["islands"] == 1


def test_resume_is_bit_identical(tmp_path):
    setup, _ = _sheet_setup(max_iterations=6)
    whole = run_loop(setup, initial_state(setup))

    class Killed(Exception):
        pass

    def checkpoint_then_die(st):
        save_checkpoint(tmp_path, st)
        if st.iteration == 3:
            raise Killed

    setup2, _ = _sheet_setup(max_iterations=6)
    with pytest.raises(Killed):
        run_loop(setup2, initial_state(setup2), checkpoint=checkpoint_then_die)
    setup3, _ = _sheet_setup(max_iterations=6)
    resumed = run_loop(setup3, load_checkpoint(tmp_path))
    assert len(resumed.designs) == len(whole.designs) == 6
    for a, b in zip(whole.designs, resumed.designs):
        np.testing.assert_array_equal(a, b)
    strip = lambda rows: [{k: v for k, v in r.items() if k != "seconds"} for r in rows]  # noqa: E731
    assert strip(whole.metrics) == strip(resumed.metrics)
    np.testing.assert_array_equal(whole.design, resumed.design)


def test_checkpoint_metrics_round_trip_and_old_checkpoints_still_load(tmp_path):
    """The checkpoint keeps the metrics as UTF-8 bytes (uncompressed: it is rewritten every
    iteration), metrics.json holds the same rows; a checkpoint written before, with the
    metrics as a numpy string, loads to the same state."""
    import json

    setup, _ = _sheet_setup(max_iterations=3)
    st = run_loop(setup, initial_state(setup))
    save_checkpoint(tmp_path, st)
    back = load_checkpoint(tmp_path)
    assert back.metrics == st.metrics and back.iteration == st.iteration
    assert json.loads((tmp_path / "metrics.json").read_text()) == list(st.metrics)
    z = dict(np.load(tmp_path / "checkpoint.npz"))
    assert z["metrics"].dtype == np.uint8
    z["metrics"] = np.array(json.dumps(st.metrics))  # the earlier format
    np.savez_compressed(tmp_path / "checkpoint.npz", **z)
    old = load_checkpoint(tmp_path)
    assert old.metrics == st.metrics
    np.testing.assert_array_equal(old.design, st.design)


def test_evolution_tolerance_after_iteration_0():
    """Iteration 0 (the reference of rho) solves to the design tolerance, every later
    iteration to the evolution tolerance, at A* too; only the iterations at A* (and 0) are
    judged for convergence; the design ends as with fine solves throughout, for less than
    half the Newton iterations."""
    import dataclasses
    import math

    fine, _ = _sheet_setup(max_iterations=40)
    fine = dataclasses.replace(fine, case=dataclasses.replace(fine.case, solver=dataclasses.replace(fine.case.solver, tol=1e-4)))
    ref = run_loop(fine, initial_state(fine))
    setup, _ = _sheet_setup(max_iterations=40)
    setup = dataclasses.replace(setup, case=dataclasses.replace(setup.case, solver=fine.case.solver),
                                beso=dataclasses.replace(setup.beso, evolution_solver=dataclasses.replace(fine.case.solver, tol=1e-2)))
    st = run_loop(setup, initial_state(setup))
    tols = [r["solver_tol"] for r in st.metrics]
    at_target = [r["target"] == setup.beso.params.target_area for r in st.metrics]
    assert tols[0] == 1e-4 and st.metrics[0]["target"] == 1.0
    assert all(t == 1e-2 for t in tols[1:])
    assert 0 < sum(at_target) < len(tols) - 1  # both phases happened
    assert [math.isnan(o) for o in st.objectives] == [k > 0 and not a for k, a in enumerate(at_target)]
    assert len(st.metrics) < 40 and len(ref.metrics) < 40  # both converged (not stopped at the maximum)
    assert len(st.metrics) - at_target.index(True) >= 2 * setup.beso.params.window  # judged at A* only
    newton = lambda run: sum(r["newton_iterations"] for r in run.metrics[1:])  # noqa: E731
    assert newton(st) < 0.5 * newton(ref)
    diff = int((st.designs[-1] != ref.designs[-1]).sum())
    assert diff <= 0.02 * len(st.design)


def test_protected_faces(anny_body):
    from kgarment.case.setup import protected_faces
    from kgarment.clutch import build_clutch
    from kgarment.clutch.layouts import default_layout
    from kgarment.garment import make_garment

    g = make_garment(anny_body, "arm_sleeve.right", 0)
    strips = [build_clutch(s, g.rest_vertices, g.faces) for s in default_layout("arm_flexion", anny_body)]
    assert protected_faces(g, strips, False, 0.0) is None
    np.testing.assert_array_equal(protected_faces(g, strips, True, 0.0), g.attached)
    near = protected_faces(g, strips, False, 0.015)
    anchors = strips[0].bind_face[strips[0].anchors]
    assert near[anchors].all() and near.mean() < 0.2


def test_activation_continuation_reaches_the_on_equilibrium(anny_body):
    """Switching the clutches on in steps ends at an equilibrium of the ON state itself."""
    import dataclasses

    import torch

    from kgarment.case import case_from_problem
    from kgarment.case.continuation import CONTINUATION, activation_continuation
    from kgarment.problem import GarmentSpec, Problem, build_clutches, build_garment
    from kgarment.sim.solve import prepare_state

    p = Problem(motions=("arm_flexion.right",), garment=GarmentSpec("arm_sleeve.right", subdivision=0))
    g = build_garment(p, anny_body)
    setup = case_from_problem(p, anny_body, g, build_clutches(p, anny_body, g))
    setup = dataclasses.replace(setup, solver=dataclasses.replace(setup.solver, workers=1))
    design = np.where(np.arange(g.n_faces) % 3 == 0, 1.0, setup.model.preset.x_min)
    on = next(s for k, s in setup.states() if k[1] == "on")
    (r,) = activation_continuation(setup, design, [on])
    assert r.name == on.name and r.converged
    assert r.convergence.iterations >= len(CONTINUATION)
    prob = prepare_state(setup.model, design, on, setup.solver)  # checked independently of the solver
    _, grad, _ = prob.evaluate(torch.as_tensor(r.x), order=1)
    assert prob.residual(grad) <= setup.solver.tol
    # the clutches-off equilibrium from the skin-tight start, solved already (the evaluator's
    # OFF state), is the first step: given, it is not solved again and the end is the same
    off = next(s for k, s in setup.states() if k[1] == "off")
    (r_off,) = setup.solve(design, [off])
    (again,) = activation_continuation(setup, design, [on], [r_off])
    assert again.converged and np.allclose(again.x, r.x, atol=1e-9)
    assert again.convergence.iterations == r.convergence.iterations


def test_settle_cools_the_exchange_at_the_target():
    """With ``settle = 1`` the design of iteration i adds at most ar_max 2^-k of the faces,
    k the iterations before it at the target (ar_max on the way there)."""
    import dataclasses
    import math

    setup, _ = _sheet_setup(max_iterations=20, target=0.4)
    setup = dataclasses.replace(setup, beso=dataclasses.replace(setup.beso, params=dataclasses.replace(setup.beso.params, settle=1, tol=1e-12)))
    st = run_loop(setup, initial_state(setup))
    p, m = setup.beso.params, len(st.design)
    ks = []
    for i in range(1, len(st.designs)):
        k = sum(1 for r in st.metrics[:i] if p.reached(r["area"]))
        added = int((st.designs[i] & ~st.designs[i - 1]).sum())
        assert added <= math.floor(p.ar_max * 0.5 ** k * m), (i, k, added)
        ks.append(k)
    assert ks[-1] >= 6  # the run spent long enough at the target to cool down to no exchange
    assert not (st.designs[-1] ^ st.designs[-2]).any()


def test_skin_start_keeps_the_lowest_energy_of_the_evaluators_starts():
    """With ``skin_start`` an iteration solves every state from the last equilibrium, from
    the skin-tight garment and from the fully reinforced garment's equilibrium (iteration
    0's, kept in the loop state under the state's name + FULL: the evaluator's two starts)
    in one batch and keeps, per state, the lowest-energy solution under the state's own
    name: the same as solving the three starts apart; its Newton iterations count all."""
    import dataclasses

    from kgarment.case.starts import MULTISTABLE
    from kgarment.optimize.loop import FULL, iterate, solve

    setup, _ = _sheet_setup(max_iterations=4)
    setup = dataclasses.replace(setup, case=dataclasses.replace(setup.case, skin_start=True))
    states = [s for _, s in setup.case.states()]
    first = iterate(setup, initial_state(setup))
    full_eq = setup.case.solve(np.ones(setup.case.model.n_faces), states, options=setup.options(0))
    for s, r in zip(states, full_eq):  # iteration 0 is the fully reinforced garment from skin-tight
        assert np.array_equal(first.warm[s.name + FULL], r.x)
    st = iterate(setup, first)
    assert all(np.array_equal(st.warm[s.name + FULL], first.warm[s.name + FULL]) for s in states)  # kept
    solved = solve(setup, st)
    opts = setup.options(st.iteration)
    warm = setup.case.solve(st.design, states, warm_start=[st.warm.get(s.name) for s in states], options=opts)
    cold = setup.case.solve(st.design, states, options=opts)
    full = setup.case.solve(st.design, states, warm_start=[st.warm[s.name + FULL] for s in states], options=opts)
    assert all(r.converged for r in warm + cold + full)
    assert any(c.convergence.iterations != f.convergence.iterations for c, f in zip(cold, full))
    for s, r, *three in zip(states, solved.results, warm, cold, full):
        assert r.name == s.name
        assert any(r.total_energy == t.total_energy and np.array_equal(r.x, t.x) for t in three)
        assert r.total_energy <= min(t.total_energy for t in three) * (1 + MULTISTABLE)
    # the iteration's Newton count is that of every start's solve, not only the kept ones
    assert solved.newton_iterations == sum(r.convergence.iterations for r in warm + cold + full)


def test_a_start_that_stopped_below_the_kept_equilibrium_is_solved_on():
    """A start whose solve ran out of iterations below the kept (converged) equilibrium's
    energy is solved on from where it stopped and replaces it when it converges lower; one
    that stopped above it is left (nothing solved)."""
    import dataclasses

    from kgarment.optimize.loop import _continue_lower, iterate

    setup, _ = _sheet_setup(max_iterations=4)
    setup = dataclasses.replace(setup, case=dataclasses.replace(setup.case, skin_start=True))
    st = iterate(setup, iterate(setup, initial_state(setup)))
    states = [s for _, s in setup.case.states()][:1]
    opts = setup.options(st.iteration)
    (eq,) = setup.case.solve(st.design, states, options=opts)
    (stopped,) = setup.case.solve(st.design, states, options=dataclasses.replace(opts, max_iter=2, rescue_shifts=0,
                                                                             on_fail="info"))
    assert eq.converged and not stopped.converged and stopped.total_energy > eq.total_energy
    # it stopped above the equilibrium: kept as it is
    out, more = _continue_lower(setup, st.design, states, [eq], [(0, stopped)], opts)
    assert out == [eq] and more == []
    # a converged solution of higher energy than where the start stopped (another basin's
    # stand-in): the start is solved on to the equilibrium below and kept
    high = dataclasses.replace(eq, energy={k: 3 * v + stopped.total_energy for k, v in eq.energy.items()})
    (out,), more = _continue_lower(setup, st.design, states, [high], [(0, stopped)], opts)
    assert len(more) == 1 and more[0].converged and out.name == states[0].name
    assert out.total_energy == pytest.approx(eq.total_energy, rel=1e-4)
    assert np.allclose(out.x, eq.x, atol=1e-4)
