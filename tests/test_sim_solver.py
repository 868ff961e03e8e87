"""Assembled energy, Newton / L-BFGS solves, contact, clutches and error reporting."""

import logging

import numpy as np
import pytest
import scipy.sparse as sp
import torch

from kgarment.sim import (
    TERMS,
    ConvergenceError,
    Motion,
    SimState,
    SimulationError,
    SolverOptions,
    build_model,
    prepare_state,
    solve_states,
)
from kgarment.sim.contact import imls
from kgarment.sim.synthetic import Tube, sphere_body, square_sheet

R = 0.1


def sheet_scene(preset="reference", n=11, pull=0.01):
    """A 10 cm sheet lying on a sphere, its border faces pulled down along the sphere."""
    bv, bn, bf = sphere_body(R, 4)
    v, f = square_sheet(0.1, n, z=R)
    x0 = R * v / np.linalg.norm(v, axis=1, keepdims=True)
    model = build_model(v, f, [], preset=preset)
    edge = np.nonzero((np.abs(v[:, 0]) > 0.0499) | (np.abs(v[:, 1]) > 0.0499))[0]
    border = np.nonzero(np.isin(f, edge).any(1))[0]
    cen = x0[f[border]].mean(1)
    rr = np.linalg.norm(cen, axis=1)
    th = np.arccos(cen[:, 2] / rr) + pull / R
    ph = np.arctan2(cen[:, 1], cen[:, 0])
    targets = np.stack([rr * np.sin(th) * np.cos(ph), rr * np.sin(th) * np.sin(ph), rr * np.cos(th)], 1)
    motion = Motion.create("press", x0, bv, bn, border, targets, bf)
    return model, motion, SimState.create(motion, [])


def tube_scene(preset="reference", clutch=True):
    tube = Tube(0.05, 0.0, 0.3, 24, 12)
    cl = [tube.clutch("c0", 0.3, 0.08, 0.22, 0.01, 14, prestrain=0.97)] if clutch else []
    model = build_model(tube.vertices, tube.faces, cl, preset=preset)
    return model, tube.motion("twist", 0.1, 0.5)


def penetration_and_drift(model, state, design, x):
    prob = prepare_state(model, design, state)
    xt = torch.tensor(x)
    f = imls(xt, *prob._contact_args(xt))[0].numpy()
    mot = state.motion
    cen = x[model.garment_faces[mot.attach_faces]].mean(1)
    return -min(f.min(), 0.0), np.linalg.norm(cen - mot.attach_targets, axis=1).max()


@pytest.mark.parametrize("preset", ["reference", "paper"])
def test_total_gradient_and_hessian_finite_differences(preset):
    model, motion = tube_scene(preset)
    d = np.where(np.random.default_rng(0).random(model.n_faces) < 0.3, 1.0, 0.001)
    prob = prepare_state(model, d, SimState.create(motion, [0.6]))
    rng = np.random.default_rng(1)
    x = torch.tensor(prob.initial_positions() + 2e-4 * rng.normal(size=(model.n_vertices, 3)))
    _e, g, H = prob.evaluate(x, order=2, exact=True)
    Hl = model.pattern.matrix(H)
    Hf = (Hl + Hl.T - sp.diags(Hl.diagonal())).tocsr()
    h = 1e-7
    for k in range(3):
        v = torch.tensor(rng.normal(size=x.shape))
        ep, gp, _ = prob.evaluate(x + h * v, order=1)
        em, gm, _ = prob.evaluate(x - h * v, order=1)
        assert (ep - em) / (2 * h) == pytest.approx(float((g * v).sum()), rel=1e-6)
        hv = Hf @ v.reshape(-1).numpy()
        fd = ((gp - gm) / (2 * h)).reshape(-1).numpy()
        assert np.abs(hv - fd).max() < 1e-5 * np.abs(fd).max()
    assert set(prob.terms(x)[0]) == set(TERMS)


def test_newton_converges_quadratically(caplog):
    model, motion = tube_scene("reference")
    state = SimState.create(motion, [1.0])
    d = np.full(model.n_faces, 0.001)
    caplog.set_level(logging.INFO, logger="kgarment.sim")
    r = solve_states(model, d, [state], options=SolverOptions(tol=1e-10))[0]
    assert r.converged
    fc = model.char_force
    h = np.array(r.convergence.history) / fc
    logging.getLogger(__name__).info("Newton force history / F_char: %s", np.array2string(h, precision=2))
    # order of convergence over consecutive residuals below 1e-2 F_char: ~2 (at the very
    # end the 1e-9 damping floor leaves a linear rate ~1e-4, far below the tolerance)
    tail = h[h < 1e-2]
    orders = [np.log(c / b) / np.log(b / a) for a, b, c in zip(tail, tail[1:], tail[2:])]
    assert max(orders) > 1.8, tail
    assert h[-1] < 1e-10
    assert "converged" in caplog.text


def test_newton_and_lbfgs_agree():
    model, _motion, state = sheet_scene("reference")
    d = np.full(model.n_faces, 0.001)
    rn = solve_states(model, d, [state])[0]
    rl = solve_states(model, d, [state], options=SolverOptions(method="lbfgs"))[0]
    assert rn.converged and rl.converged
    assert rl.convergence.method == "lbfgs" and rl.convergence.iterations > rn.convergence.iterations
    assert abs(rn.total_energy - rl.total_energy) < 1e-6 * abs(rn.total_energy)
    span = np.ptp(rn.x, axis=0).max()
    assert np.abs(rn.x - rl.x).max() < 1e-6 * span


def test_a_stuck_exact_hessian_goes_on_adaptive(monkeypatch, caplog):
    """Where the shifted exact Hessian gets stuck (its shift escalates, or the energy stops
    falling), Newton goes on with the adaptive Hessian from where it is, and reaches the
    equilibrium that Newton and L-BFGS agree on (switching at once forces the path)."""
    from kgarment.sim import newton

    model, _motion, state = sheet_scene("reference")
    d = np.full(model.n_faces, 0.001)
    ref = solve_states(model, d, [state])[0]
    monkeypatch.setattr(newton, "STUCK_SHIFT", 0.0)
    caplog.set_level(logging.DEBUG, logger="kgarment.sim.newton")
    r = solve_states(model, d, [state])[0]
    assert "going on with the adaptive Hessian" in caplog.text
    assert r.converged and ref.converged
    assert abs(r.total_energy - ref.total_energy) < 1e-6 * abs(ref.total_energy)


def test_auto_hessian_is_shifted_on_coarse_garments_and_adaptive_on_fine_ones(monkeypatch):
    """``hessian="auto"`` (the evaluations') follows the shifted exact Hessian's iterates bit
    for bit on a garment of at most ``ADAPTIVE_VERTICES`` vertices and the adaptive one's
    above (on the twisted tube with its clutch they end in equilibria 0.2% apart in energy,
    both converged: a buckled strip's are not unique)."""
    from kgarment.sim import options

    model, motion = tube_scene("paper")
    state = SimState.create(motion, [1.0])
    d = np.where(np.arange(model.n_faces) % 3 == 0, 1.0, 0.001)
    runs = {h: solve_states(model, d, [state], options=SolverOptions(hessian=h, tol=1e-6))[0]
            for h in ("shifted", "adaptive", "auto")}
    monkeypatch.setattr(options, "ADAPTIVE_VERTICES", model.n_garment - 1)
    fine = solve_states(model, d, [state], options=SolverOptions(hessian="auto", tol=1e-6))[0]
    assert all(r.converged for r in [*runs.values(), fine])
    assert runs["auto"].convergence.history == runs["shifted"].convergence.history
    assert fine.convergence.history == runs["adaptive"].convergence.history
    assert runs["shifted"].convergence.history != runs["adaptive"].convergence.history
    # the evaluations' choice; design iterations keep the shifted Hessian
    from kgarment.problem import parse_problem
    from kgarment.problem.build import solver_options

    p = parse_problem({})
    assert solver_options(p, "evaluate").hessian == "auto"
    assert solver_options(p, "design").hessian == solver_options(p, "evolution").hessian == "shifted"


@pytest.mark.parametrize("hessian", ["shifted", "adaptive"])
def test_reusing_the_full_steps_evaluation_changes_no_iterate(monkeypatch, hessian):
    """The full step's trial evaluation (with derivatives) is reused as the next iterate's:
    forcing a fresh evaluation there instead gives bit-identical iterates and fewer
    evaluations are spent with the reuse."""
    from kgarment.sim import newton

    model, motion = tube_scene("paper")
    state = SimState.create(motion, [1.0])
    d = np.where(np.arange(model.n_faces) % 3 == 0, 1.0, 0.001)
    opts = SolverOptions(hessian=hessian, tol=1e-6)
    reused = solve_states(model, d, [state], options=opts)[0]
    monkeypatch.setattr(newton, "_finite", lambda ahead: False)
    fresh = solve_states(model, d, [state], options=opts)[0]
    assert reused.converged and fresh.converged
    assert reused.convergence.history == fresh.convergence.history
    assert np.array_equal(reused.x, fresh.x)
    assert reused.convergence.evaluations < fresh.convergence.evaluations


@pytest.mark.parametrize("preset", ["reference", "paper"])
@pytest.mark.parametrize("dval", [0.001, 1.0])
def test_contact_keeps_penetration_below_1mm(preset, dval):
    model, _motion, state = sheet_scene(preset, pull=0.015)
    d = np.full(model.n_faces, dval)
    r = solve_states(model, d, [state])[0]
    assert r.converged
    pen, drift = penetration_and_drift(model, state, d, r.x)
    assert r.energy["contact"] > 0  # the sheet is pressed onto the sphere
    assert pen < 1e-3 and drift < 2e-3


@pytest.mark.parametrize("preset", ["reference", "paper"])
def test_clutch_on_stores_more_energy(preset):
    model, motion = tube_scene(preset)
    d = np.full(model.n_faces, 0.001)
    on, off = SimState.create(motion, [1.0]), SimState.create(motion, [0.0])
    r_on, r_off = solve_states(model, d, [on, off])
    assert r_on.converged and r_off.converged
    assert r_on.total_energy > r_off.total_energy
    # the stiff clutch itself may store less (it barely stretches); the garment stores more
    assert r_on.energy["membrane_garment"] > r_off.energy["membrane_garment"]
    pen, drift = penetration_and_drift(model, on, d, r_on.x)
    assert pen < 1e-3 and drift < 2e-3
    # the anchors stay on the garment
    c = model.clutches[0]
    off_ = model.vertex_offsets[1]
    bound = c.bound_positions(r_on.x[:off_], model.garment_faces)
    assert np.linalg.norm(r_on.x[off_ + c.anchors] - bound[c.anchors], axis=1).max() < 1e-3


def test_results_warm_start_and_batching():
    model, motion = tube_scene("reference")
    states = [SimState.create(motion, [g]) for g in (1.0, 0.5, 0.0)]
    d = np.full(model.n_faces, 0.001)
    res = solve_states(model, d, states)
    assert [r.name for r in res] == [s.name for s in states]
    r = res[1]
    m = model.n_faces
    assert r.x.shape == (model.n_vertices, 3) and r.garment_x.shape == (model.n_garment, 3)
    assert r.garment_energy.shape == (m,) and r.garment_density.shape == (m,)
    assert np.allclose(r.garment_density * model.elements.area[:m], r.garment_energy)
    assert r.energy["membrane_garment"] == pytest.approx(r.garment_energy.sum(), rel=1e-12)
    assert r.energy["membrane_clutch"] == pytest.approx(sum(e.sum() for e in r.clutch_energy), rel=1e-12)
    assert res[0].total_energy > res[1].total_energy > res[2].total_energy
    again = solve_states(model, d, states, warm_start={s.name: x for s, x in zip(states, res)})
    assert all(a.convergence.iterations == 0 for a in again)
    # a small design change converges quickly from the previous solution
    d2 = d.copy()
    d2[:10] = 1.0
    warm = solve_states(model, d2, states, warm_start=res)
    assert all(w.converged for w in warm)


def test_non_convergence_is_reported_by_name(caplog):
    model, motion = tube_scene("reference")
    state = SimState.create(motion, [1.0], name="tight")
    d = np.full(model.n_faces, 0.001)
    with caplog.at_level(logging.WARNING, logger="kgarment.sim"):
        r = solve_states(model, d, [state], options=SolverOptions(max_iter=1, rescue_shifts=0))[0]
    assert not r.converged and r.convergence.iterations == 1
    # with the rescue (default), a second solve with larger shifts runs; iterations add up
    r = solve_states(model, d, [state], options=SolverOptions(max_iter=1))[0]
    assert not r.converged and r.convergence.iterations == 2
    assert "tight" in caplog.text and "max force" in caplog.text
    with pytest.raises(ConvergenceError) as err:
        solve_states(model, d, [state], options=SolverOptions(max_iter=1, on_fail="raise"))
    assert err.value.states == ["tight"]
    caplog.clear()  # "info": flagged and logged, but no warning (a caller that solves it again another way)
    with caplog.at_level(logging.INFO, logger="kgarment.sim"):
        r = solve_states(model, d, [state], options=SolverOptions(max_iter=1, rescue_shifts=0, on_fail="info"))[0]
    assert not r.converged
    said = [rec for rec in caplog.records if "did not converge" in rec.getMessage()]
    assert said and all(rec.levelno == logging.INFO for rec in said)


def test_non_finite_energy_raises_naming_state_and_term():
    model, motion = tube_scene("reference")
    bad = Motion(name="bad", garment_x0=motion.garment_x0, body=motion.body,
                 attach_faces=motion.attach_faces, attach_targets=motion.attach_targets * np.nan)
    with pytest.raises(SimulationError, match=r"'bad\[1\]'.*'attach'"):
        solve_states(model, np.full(model.n_faces, 0.001), [SimState.create(bad, [1.0])])
    assert issubclass(SimulationError, ValueError)


def test_input_validation():
    model, motion = tube_scene("reference")
    with pytest.raises(ValueError):
        solve_states(model, np.full(model.n_faces, 2.0), [SimState.create(motion, [1.0])])
    with pytest.raises(ValueError):
        solve_states(model, np.full(model.n_faces, 0.5), [SimState.create(motion, [1.0, 0.0])])
    with pytest.raises(ValueError):
        build_model(np.zeros((3, 3)), np.array([[0, 1, 2]]))


def test_worker_processes_give_the_same_results():
    """Bit-identical to solving in this process, also on the second call, whose tasks are
    submitted longest first (the states' last iteration counts differ)."""
    model, motion = tube_scene("reference")
    states = [SimState.create(motion, [g], name=n) for g, n in ((0.0, "off"), (0.5, "half"), (1.0, "on"))]
    d = np.full(model.n_faces, 0.001)
    serial = solve_states(model, d, states)
    assert len({r.convergence.iterations for r in serial}) > 1
    for _ in range(2):
        par = solve_states(model, d, states, options=SolverOptions(workers=2))
        for a, b in zip(serial, par):
            assert a.name == b.name and b.converged
            assert np.array_equal(a.x, b.x) and a.energy == b.energy


INHERIT_SCRIPT = """
import json, sys
import numpy as np
sys.path.insert(0, sys.argv[1])
from test_sim_solver import tube_scene
from kgarment.sim import SimState, SolverOptions, parallel, solve_states

def scene():
    model, motion = tube_scene("reference")
    return model, [SimState.create(motion, [g], name=n) for g, n in ((0.0, "off"), (1.0, "on"))]

model, states = scene()
d = np.full(model.n_faces, 0.001)
serial = solve_states(model, d, states)
carried = []
real_ref = parallel._ref
def ref(obj, workers):
    r = real_ref(obj, workers)
    carried.append(r[1] is not None)
    return r
parallel._ref = ref
same = []
for m, s in ((model, states), (model, states), scene()):  # the first call forks the pool
    par = solve_states(m, d, s, options=SolverOptions(workers=2))
    same.append(all(np.array_equal(a.x, b.x) and a.energy == b.energy for a, b in zip(serial, par)))
print(json.dumps({"carried": carried, "same": same}))
"""


def test_workers_inherit_the_objects_of_the_call_that_forks_them():
    """A forked pool's workers inherit the model and states of the call that creates it:
    those tasks carry only tokens; other objects (the same garment built again) travel
    with their tasks.  Bit-identical to solving in this process either way.  In a fresh
    interpreter, so that the pool is new and forked."""
    import json
    import subprocess
    import sys
    from pathlib import Path

    r = subprocess.run([sys.executable, "-c", INHERIT_SCRIPT, str(Path(__file__).parent)], check=False,
                       capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr[-2000:]
    out = json.loads(r.stdout.strip().splitlines()[-1])
    assert out["same"] == [True, True, True]
    assert out["carried"] == [False] * 8 + [True] * 4


THREAD_SCRIPT = """
import json, sys, threading
import numpy as np
sys.path.insert(0, sys.argv[1])
from test_sim_solver import tube_scene
from kgarment.sim import SimState, SolverOptions, parallel, solve_states

model, motion = tube_scene("reference")
states = [SimState.create(motion, [g], name=n) for g, n in ((0.0, "off"), (1.0, "on"))]
d = np.full(model.n_faces, 0.001)
serial = solve_states(model, d, states)
out = {}
def job():  # like the studio's: the pool is created from a job thread
    par = solve_states(model, d, states, options=SolverOptions(workers=2))
    out["same"] = all(np.array_equal(a.x, b.x) and a.energy == b.energy for a, b in zip(serial, par))
    out["method"] = parallel._POOLS[2]._mp_context.get_start_method()
t = threading.Thread(target=job)
t.start(); t.join()
print(json.dumps(out))
"""


def test_a_pool_created_from_a_thread_is_not_forked():
    """A pool first needed in a thread other than the main one (the studio's jobs) starts
    its workers by forkserver, not fork (a fork copies the other threads' held locks);
    the results are bit-identical to this process's, and the process exits (the
    subprocess's timeout would catch a hang at exit)."""
    import json
    import multiprocessing as mp
    import subprocess
    import sys
    from pathlib import Path

    if "forkserver" not in mp.get_all_start_methods():
        pytest.skip("no forkserver on this platform")
    r = subprocess.run([sys.executable, "-c", THREAD_SCRIPT, str(Path(__file__).parent)], check=False,
                       capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr[-2000:]
    out = json.loads(r.stdout.strip().splitlines()[-1])
    assert out == {"same": True, "method": "forkserver"}


def _blas_thread_counts():
    from threadpoolctl import threadpool_info

    return [i["num_threads"] for i in threadpool_info() if i["user_api"] == "blas"]


def test_solves_run_blas_on_one_thread():
    """Inside a solve and in the worker processes BLAS runs one thread (OpenBLAS's idle
    threads spin and would take the other workers' cores); the caller's setting is
    restored afterwards."""
    from threadpoolctl import threadpool_limits

    from kgarment.sim import parallel
    from kgarment.sim.solve import blas_threads

    with threadpool_limits(limits=2, user_api="blas"):
        before = _blas_thread_counts()
        with blas_threads(1):
            assert set(_blas_thread_counts()) == {1}
        assert _blas_thread_counts() == before
        with blas_threads(None):
            assert _blas_thread_counts() == before
    pool = parallel._pool(2)
    counts = [pool.submit(_blas_thread_counts).result() for _ in range(4)]
    assert all(set(c) == {1} for c in counts)


def test_the_lagged_contact_set_reaches_the_same_equilibrium(monkeypatch):
    """Newton's lagged contact set (``SolverOptions.lag_contact``, newton._anticipate) only
    changes the route: a sheet pressed onto a sphere (one equilibrium) solved with and
    without it lands on the same equilibrium once both are solved on to 1e-7, and the lag
    was used on the way."""
    from kgarment.sim import newton

    used = []
    real = newton._lagged

    def counting(*a, **k):
        out = real(*a, **k)
        used.append(out is not None)
        return out

    monkeypatch.setattr(newton, "_lagged", counting)
    model, _motion, state = sheet_scene("paper", pull=0.02)
    d = np.full(model.n_faces, 0.001)
    ends = []
    for lag in (True, False):
        (coarse,) = solve_states(model, d, [state], options=SolverOptions(tol=1e-3, lag_contact=lag))
        (fine,) = solve_states(model, d, [state], warm_start=[coarse], options=SolverOptions(tol=1e-7))
        assert coarse.converged and fine.converged
        ends.append(fine)
    assert any(used)
    assert abs(ends[0].total_energy - ends[1].total_energy) < 1e-7 * abs(ends[1].total_energy)
    assert np.abs(ends[0].x - ends[1].x).max() < 1e-5 * np.ptp(ends[1].x, axis=0).max()


def test_a_solve_that_runs_out_of_iterations_is_rescued_from_where_it_stopped():
    """The rescue of a solve cut off by ``max_iter`` (not stalled) goes on from where it
    stopped: one iteration short of convergence, it converges to the equilibrium an unlimited
    solve reaches, where a new start would stop short again."""
    model, motion = tube_scene("reference")
    state = SimState.create(motion, [1.0], name="tight")
    d = np.full(model.n_faces, 0.001)
    (full,) = solve_states(model, d, [state], options=SolverOptions(rescue_shifts=0))
    n = full.convergence.iterations
    assert full.converged and n >= 3
    (cut,) = solve_states(model, d, [state], options=SolverOptions(max_iter=n - 1, rescue_shifts=0, on_fail="info"))
    assert not cut.converged
    (r,) = solve_states(model, d, [state], options=SolverOptions(max_iter=n - 1))
    assert r.converged and n - 1 < r.convergence.iterations <= 2 * (n - 1)
    assert r.total_energy == pytest.approx(full.total_energy, rel=1e-8)


def test_a_step_onto_non_finite_derivatives_is_refused_not_raised(monkeypatch):
    """Where the full step lands on finite energy but a non-finite Hessian (an element
    degenerating there), Newton takes a shorter, damped step instead of raising, and still
    reaches the equilibrium it reaches without the fault (the first 3 full-step trials
    poisoned)."""
    from kgarment.sim import energy

    model, motion = tube_scene("paper")
    state = SimState.create(motion, [1.0])
    d = np.full(model.n_faces, 1.0)  # all reinforced: no slack cloth, one equilibrium
    opts = SolverOptions(tol=1e-6)
    clean = solve_states(model, d, [state], options=opts)[0]
    real = energy.StateProblem.evaluate
    poisoned = {"left": 3, "points": []}

    def evaluate(self, x, order=0, check=True, exact=False):
        E, g, H = real(self, x, order=order, check=False, exact=exact)
        if order == 2 and not check and poisoned["left"] > 0:  # a full-step trial point
            poisoned["left"] -= 1
            poisoned["points"].append(x.clone())
        if order == 2 and any(torch.equal(x, p) for p in poisoned["points"]):
            H = np.full_like(H, np.nan)  # the Hessian there, whoever asks
            if check:  # what the real check does
                raise energy.SimulationError(f"state {self.name!r}: non-finite Hessian")
        return E, g, H

    monkeypatch.setattr(energy.StateProblem, "evaluate", evaluate)
    faulty = solve_states(model, d, [state], options=opts)[0]
    assert poisoned["left"] == 0  # the fault was met
    assert clean.converged and faulty.converged
    assert faulty.total_energy == pytest.approx(clean.total_energy, rel=1e-6)
    assert np.abs(faulty.x - clean.x).max() < 1e-3 * model.mean_edge
