"""Equilibria kept on disk (``kgarment.case.store``): a second process's evaluator takes a
run's solves from its store and gives the same numbers without solving; anything that
changes a solve (the solver options, the design, the start) finds no entry; a damaged
entry is solved again."""

from __future__ import annotations

import logging

import numpy as np
import pytest

from kgarment.case import Case
from kgarment.case.store import EquilibriumStore, content_digest
from kgarment.evaluate import Evaluator
from kgarment.sim import SolverOptions, build_model
from kgarment.sim.synthetic import Tube


def _evaluator(store=None, tol=1e-5) -> tuple[Evaluator, np.ndarray]:
    """A tube pulled 5% along its axis with two clutches (as in test_design_loads), one
    linked by reinforcement: a fresh evaluator each call, as a new process would build it."""
    tube = Tube(0.05, 0.0, 0.3, 40, 25)
    clutches = [tube.clutch("linked", 0.0, 0.08, 0.22, 0.01, 24), tube.clutch("loose", np.pi, 0.08, 0.22, 0.01, 24)]
    model = build_model(tube.vertices, tube.faces, clutches, preset="paper")
    c = tube.vertices[tube.faces].mean(axis=1)
    band = np.abs(np.arctan2(c[:, 1], c[:, 0])) < 0.26
    design = np.where(band & ((c[:, 2] < 0.095) | (c[:, 2] > 0.205)), 1.0, 1e-3)
    setup = Case.build(model, {"pull": tube.motion("pull", 0.05, 0.0)}, "active", SolverOptions(tol=tol, max_iter=300))
    return Evaluator(setup, store), design


def _numbers(ev) -> list:
    rows = [(s.motion, s.state, s.rho, s.energy, s.energy_full, s.converged) for s in ev.states]
    loads = [(c.clutch, c.share, c.needed, c.tension_N) for c in ev.loads.clutches]
    return rows + loads


def _count_solves(monkeypatch) -> list:
    calls = []
    orig = Case.solve_now

    def solve_now(self, design, states, *args, **kwargs):
        calls.append(len(states))
        return orig(self, design, states, *args, **kwargs)

    monkeypatch.setattr(Case, "solve_now", solve_now)
    return calls


@pytest.fixture(scope="module")
def stored(tmp_path_factory):
    folder = tmp_path_factory.mktemp("run") / "equilibria"
    ev, design = _evaluator(EquilibriumStore(folder))
    return folder, design, ev.evaluate(design, loads=True)


def test_a_new_evaluator_takes_the_equilibria_from_the_store_and_solves_nothing(stored, monkeypatch):
    folder, design, first = stored
    files = sorted(folder.glob("*.npz"))
    assert len(files) >= 6  # ON and OFF of the design and of the full garment, the one-clutch states
    calls = _count_solves(monkeypatch)
    store = EquilibriumStore(folder)
    ev, _ = _evaluator(store)
    again = ev.evaluate(design, loads=True)
    assert calls == [] and store.misses == 0 and store.hits > 0
    assert _numbers(again) == _numbers(first)  # the same equilibria: equal to the last digit
    for a, b in zip(first.states, again.states):
        np.testing.assert_array_equal(a.result.x, b.result.x)
        assert a.result.convergence == b.result.convergence and a.result.energy == b.result.energy
    assert sorted(folder.glob("*.npz")) == files  # nothing new written


def test_other_solver_options_or_another_design_find_no_entry(stored, monkeypatch):
    folder, design, _ = stored
    calls = _count_solves(monkeypatch)
    store = EquilibriumStore(folder)
    ev, _ = _evaluator(store, tol=2e-5)
    ev.evaluate(design)
    assert store.hits == 0 and calls
    store2 = EquilibriumStore(folder)
    ev2, _ = _evaluator(store2)
    other = design.copy()
    other[np.flatnonzero(design < 0.5)[:3]] = 1.0
    calls.clear()
    ev2.evaluate(other)
    assert calls  # the design's states solved; the full garment's taken from the store:
    assert store2.hits == 3  # ON and OFF from skin-tight, ON again from OFF


def test_a_damaged_entry_is_solved_again_with_a_warning(stored, tmp_path, caplog, monkeypatch):
    folder, design, first = stored
    copy = tmp_path / "equilibria"
    copy.mkdir()
    for f in folder.glob("*.npz"):  # every entry damaged: the folder also holds other tests' entries, which
        (copy / f.name).write_bytes(b"not an npz file")  # this evaluation would not read
    calls = _count_solves(monkeypatch)
    ev, _ = _evaluator(EquilibriumStore(copy))
    with caplog.at_level(logging.WARNING, logger="kgarment.case.store"):
        again = ev.evaluate(design, loads=True)
    assert "unreadable" in caplog.text and calls
    assert _numbers(again) == _numbers(first)  # solved again: the same equilibrium


def test_a_store_that_cannot_be_written_warns_once_and_the_numbers_stand(stored, tmp_path, caplog):
    """A file where the store's folder goes (a user's RUN/equilibria): every solve is still
    made and the numbers are the stored run's, with one warning, not one per solve."""
    _, design, first = stored
    blocked = tmp_path / "equilibria"
    blocked.write_text("a user's file")
    ev, _ = _evaluator(EquilibriumStore(blocked))
    with caplog.at_level(logging.WARNING, logger="kgarment.case.store"):
        again = ev.evaluate(design, loads=True)
    assert caplog.text.count("could not write") == 1
    assert blocked.read_text() == "a user's file"
    assert _numbers(again) == _numbers(first)


def test_content_digest_sees_arrays_and_fields():
    a = np.arange(6.0)
    b = a.copy()
    b[3] += 1e-15 * b[3]
    assert content_digest(a) == content_digest(a.copy()) != content_digest(b)
    assert content_digest(SolverOptions(tol=1e-4)) != content_digest(SolverOptions(tol=1e-5))
    assert content_digest(a.astype(np.float32)) != content_digest(a)


def test_a_load_state_from_another_start_is_solved_again(stored, monkeypatch):
    """Under --path the ON or OFF equilibrium a one-clutch state starts from can be the
    motion's end instead of the two starts' one: the store keys load states by their start."""
    from kgarment.evaluate.loads import activation_equilibria

    folder, design, first = stored
    ev, _ = _evaluator(EquilibriumStore(folder))
    known = {(s.motion, s.state): s.result for s in first.states}
    keyed = ev.activation_states([1.0, 0.0], ["pull"], "only linked") + \
        ev.activation_states([0.0, 1.0], ["pull"], "only loose")
    calls = _count_solves(monkeypatch)
    same = activation_equilibria(ev, design, keyed, known)
    assert calls == []  # the evaluation solved these from the same starts
    moved = dict(known)
    for k in (("pull", "on"), ("pull", "off")):
        r = known[k]
        moved[k] = type(r)(**{**r.__dict__, "x": r.x + 1e-7})  # another start, a hair away
    again = activation_equilibria(ev, design, keyed, moved)
    assert calls == [2]
    for key in same:
        assert again[key].total_energy == pytest.approx(same[key].total_energy, rel=1e-4)


def test_numpy_scalars_in_a_record_round_trip(tmp_path, stored):
    """A StateResult whose record holds numpy scalars (np.bool_, np.int64) is kept and read
    back as the same values."""
    import dataclasses

    _, _, first = stored
    r = first.states[0].result
    odd = dataclasses.replace(r, convergence=dataclasses.replace(
        r.convergence, converged=np.bool_(r.converged), iterations=np.int64(r.convergence.iterations)))
    store = EquilibriumStore(tmp_path / "eq")
    store.put(("k",), odd)
    back = store.get(("k",))
    assert back.convergence == r.convergence and back.total_energy == r.total_energy
    np.testing.assert_array_equal(back.x, r.x)


def test_the_full_garment_is_solved_once_per_machine(tmp_path, monkeypatch):
    """The fully reinforced garment's solves (iteration 0, the references of rho) go to the
    shared store in kgarment's cache: a second evaluator of the same problem, in a new
    process and without a run folder, solves only the design's states and gives the same
    numbers; a design's own solves are not kept there."""
    from kgarment.case.store import SHARED

    monkeypatch.setenv("KGARMENT_CACHE_DIR", str(tmp_path / "cache"))
    monkeypatch.delenv("KGARMENT_SOLVE_CACHE", raising=False)
    ev, design = _evaluator()
    first = ev.evaluate(design)
    (version,) = (tmp_path / "cache" / SHARED).iterdir()
    kept = sorted(version.glob("*.npz"))
    assert len(kept) == 3  # ON and OFF from skin-tight, ON again from OFF: the design's are not shared
    calls = _count_solves(monkeypatch)
    ev2, _ = _evaluator()
    again = ev2.evaluate(design)
    assert calls == [2 * len(first.states)]  # the design from its two starts, nothing else
    assert [(s.rho, s.energy, s.energy_full) for s in again.states] == \
        [(s.rho, s.energy, s.energy_full) for s in first.states]
    full = ev2.case.solve(np.ones(len(design)), [s for _, s in ev2.keyed()])  # iteration 0 of a run
    assert calls == [2 * len(first.states)]  # read back: solved by the first evaluator
    assert all(r.converged for r in full)
    assert sorted(version.glob("*.npz")) == kept
    run = EquilibriumStore(tmp_path / "run" / "equilibria")  # a run's store takes them from the shared one
    calls.clear()
    third, _ = _evaluator(run)
    third.evaluate(design)
    assert calls == [2 * len(first.states)] and run.hits == 0
    assert run.borrowed == 3 and run.misses - run.borrowed == 2 * len(first.states)
    assert len(list(run.folder.glob("*.npz"))) == 3 + 2 * len(first.states)  # the run keeps a copy


def test_the_shared_store_can_be_turned_off_and_keeps_only_converged_solves(tmp_path, monkeypatch):
    from kgarment.case.store import SHARED

    monkeypatch.setenv("KGARMENT_CACHE_DIR", str(tmp_path / "cache"))
    monkeypatch.setenv("KGARMENT_SOLVE_CACHE", "0")
    ev, design = _evaluator()
    ev.case.solve(np.ones(len(design)), [s for _, s in ev.keyed()])
    assert not (tmp_path / "cache" / SHARED).exists()
    monkeypatch.setenv("KGARMENT_SOLVE_CACHE", "1")
    stopped = SolverOptions(tol=1e-5, max_iter=2, rescue_shifts=0)  # cannot converge in two iterations
    (r,) = ev.case.solve(np.ones(len(design)), [ev.keyed()[0][1]], options=stopped)
    assert not r.converged
    assert not list((tmp_path / "cache" / SHARED).rglob("*.npz"))  # solved again, and reported, next time


def test_the_shared_store_keeps_the_latest_code_versions_only(tmp_path, monkeypatch):
    """Entries of older code are never read (the key names the code); the store removes the
    folders of all but the most recently used versions, and nothing else in its folder."""
    import os

    from kgarment.case.store import SHARED, SHARED_VERSIONS, shared_store

    monkeypatch.setenv("KGARMENT_CACHE_DIR", str(tmp_path / "cache"))
    monkeypatch.delenv("KGARMENT_SOLVE_CACHE", raising=False)
    root = tmp_path / "cache" / SHARED
    old = [root / f"{i:032x}" for i in range(SHARED_VERSIONS + 2)]
    for i, p in enumerate(old):
        p.mkdir(parents=True)
        (p / "entry.npz").write_bytes(b"x")
        os.utime(p, (1e9 + i, 1e9 + i))  # old[-1] the most recently used
    (root / "notes").mkdir()  # not a version's folder: left alone
    store = shared_store()
    assert store is not None and store.folder.parent == root
    left = sorted(p.name for p in root.iterdir())
    assert "notes" in left and store.folder.name in left
    assert [p.name for p in old if p.exists()] == [p.name for p in old[-(SHARED_VERSIONS - 1):]]
