"""The step guard: a step that breaks a motion's load path is taken back (kgarment.optimize.guard)."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from test_design_loop import _sheet_setup

from kgarment.constants import GUARD_AREA, GUARD_FLOOR, GUARD_RETRIES
from kgarment.design.run import best_iteration, load_checkpoint, save_checkpoint
from kgarment.optimize.guard import (
    blinding,
    boosted,
    collapsed,
    guard_step,
    last_accepted,
    paths_of,
    rejections_in_a_row,
)
from kgarment.optimize.loop import (
    advance,
    initial_state,
    iterate,
    metrics_row,
    sensitivities,
    solve,
)
from kgarment.optimize.objective import objective_terms, objective_value
from kgarment.problem import BesoParams


def test_objective_terms_sum_to_the_objective():
    energy = {("a", "on"): 3.0, ("a", "off"): 1.0, ("b", "on"): 5.0, ("b", "off"): 0.5, ("a", "lock:b"): 2.0,
              ("b", "solo:x"): 1.5, ("b", "solo:y"): 4.0}
    ref = {("a", "on"): 2.0, ("b", "on"): 10.0}
    terms = objective_terms("active", energy, ref, ["a", "b"], lockout=0.5, balance=1.0)
    # a: (3 - 1 - 0.5 (2 - 1)) / 2; b: (5 - 0.5 + h(1) + h(3.5)) / 10 with tau G = 1.125:
    # h(1) = 1 - 1 / 2.25, h(3.5) = 1.125 / 2
    assert terms["a"] == pytest.approx(0.75)
    assert terms["b"] == pytest.approx((4.5 + 1 - 1 / 2.25 + 1.125 / 2) / 10)
    assert objective_value("active", energy, ref, ["a", "b"], 0.5, 1.0) == pytest.approx(sum(terms.values()))


def test_collapse_needs_a_load_path_worth_keeping_and_a_large_drop():
    before = {"a": 0.4, "b": 0.5 * GUARD_FLOOR}
    assert collapsed({"a": 0.19, "b": 0.0}, before, 0.5) == ["a"]  # b was below the floor
    assert collapsed({"a": 0.21, "b": 0.0}, before, 0.5) == []     # a lost less than half
    assert collapsed({"a": 0.0, "b": 0.0}, before, 0.0) == []      # guard off


def _rows(*rejected):
    return [{"rejected": r, "term[a]": 0.4} for r in rejected]


def test_rejections_give_up_after_the_retries_and_the_area_cap():
    areas = np.ones(100)
    removed = np.zeros(100, bool)
    removed[:3] = True
    rows = _rows("")
    motions, guarded = guard_step(rows, {"a": 0.1}, 0.5, removed, None, areas, 0.2)
    assert motions == ["a"] and guarded.sum() == 3  # without sensitivities: every removed face
    score = {"a": np.arange(100.0)}
    motions, guarded = guard_step(rows, {"a": 0.1}, 0.5, removed, None, areas, 0.2, score)
    np.testing.assert_array_equal(np.flatnonzero(guarded), [1, 2])  # the better half
    motions, again = guard_step(rows, {"a": 0.1}, 0.5, removed, guarded, areas, 0.2, score)
    np.testing.assert_array_equal(np.flatnonzero(again), [0, 1, 2])  # half of the rest
    # retries: after GUARD_RETRIES rejections in a row the step goes through
    rows = _rows("", *(["a"] * GUARD_RETRIES))
    assert last_accepted(rows) == 0 and rejections_in_a_row(rows) == GUARD_RETRIES
    assert last_accepted(rows[:1] + [{"rejected": "", "unconverged_states": "a[on]"}]) == 0  # no reference
    assert guard_step(rows, {"a": 0.1}, 0.5, removed, None, areas, 0.2) == ([], None)
    # area cap: the guarded faces stay below GUARD_AREA of the target area
    many = np.zeros(100, bool)
    many[: int(GUARD_AREA * 0.2 * 100) + 1] = True
    assert guard_step(_rows(""), {"a": 0.1}, 0.5, many, None, areas, 0.2) == ([], None)
    # guarded faces rank above all others
    alpha = np.linspace(0, 1, 100)
    assert np.all(boosted(alpha, removed)[:3] > alpha.max())
    np.testing.assert_array_equal(boosted(alpha, None), alpha)


def test_with_a_lockout_the_guard_watches_the_gain_and_is_not_blinded_by_lock_states():
    """A motion's lock states (another set ON in it) enter only the lockout penalty: one that
    did not converge neither keeps the guard from judging a step nor keeps an iteration from
    being its reference, and the guard compares the gains (the terms without the penalty)."""
    assert blinding("a[on];a[lock:b];b[off]") == ["a[on]", "b[off]"]
    assert blinding(["a[lock:b]"]) == [] and blinding("") == []
    rows = [{"rejected": "", "unconverged_states": "", "term[a]": 0.4},
            {"rejected": "", "unconverged_states": "a[lock:b]", "term[a]": 0.1, "gain[a]": 0.4}]
    assert last_accepted(rows) == 1
    assert last_accepted(rows + [{"rejected": "", "unconverged_states": "a[on]"}]) == 1
    assert paths_of(rows[1]) == {"a": 0.4} and paths_of(rows[0]) == {"a": 0.4}
    areas, removed = np.ones(100), np.arange(100) < 3
    # against the reference's gain (0.4), 0.15 is a collapse; against its term (0.1) it would not be
    assert guard_step(rows, {"a": 0.15}, 0.5, removed, None, areas, 0.2)[0] == ["a"]
    assert guard_step(rows, {"a": 0.25}, 0.5, removed, None, areas, 0.2)[0] == []


def test_the_gain_column_is_the_term_without_the_lockout_penalty():
    """metrics_row with a lockout: gain[m] = (ON - OFF) / reference ON, term[m] = that less
    lockout * (LOCK - OFF) / reference ON, from the row's own energies."""
    from test_design_activation import tube_setup

    from kgarment.optimize.setup import BesoSetup, DesignSetup

    def designed(case):
        return DesignSetup(case, BesoSetup.build(case, BesoParams()))

    sets = {"pull": np.array([1.0, 0.0]), "twist": np.array([0.0, 1.0])}
    setup = designed(tube_setup(sets, lockout=0.7))
    st = initial_state(setup)
    solved = solve(setup, st)
    row = metrics_row(setup, st, solved, solved.energy, solved.stored)
    for m, other in (("pull", "twist"), ("twist", "pull")):
        on, off, lock = (row[f"energy[{m}:{s}]"] for s in ("on", "off", f"lock:{other}"))
        assert row[f"gain[{m}]"] == pytest.approx((on - off) / on)
        assert row[f"term[{m}]"] == pytest.approx((on - off - 0.7 * (lock - off)) / on)
    plain = designed(tube_setup(sets))
    assert not any(k.startswith("gain[") for k in metrics_row(plain, st, solve(plain, st), solved.energy,
                                                               solved.stored))


def test_a_rejected_step_is_made_again_from_the_last_accepted_design(tmp_path):
    """A step whose term collapses is recorded but not taken: the next design comes from the
    last accepted one (its sensitivities, warm starts, the same target) with the faces the
    step removed kept; the rejected iteration is never the reported design; the guarded faces
    survive a checkpoint."""
    setup, _ = _sheet_setup(objective="passive", max_iterations=20)
    setup = dataclasses.replace(setup, beso=dataclasses.replace(setup.beso, guard=0.5))
    st = initial_state(setup)
    for _ in range(3):
        st = iterate(setup, st)
    assert not any(r["rejected"] for r in st.metrics)  # the real run's steps are all accepted
    assert st.metrics[-1]["term[pull]"] >= GUARD_FLOOR
    solved = solve(setup, st)
    row = metrics_row(setup, st, solved, st.reference, st.reference_stored)
    filt = sensitivities(setup, st, solved)
    row["term[pull]"] = 0.1 * st.metrics[-1]["term[pull]"]  # as if the step broke the load path
    nxt = advance(setup, st, solved, filt, row, st.reference, st.reference_stored)
    assert row["rejected"] == "pull" and math.isnan(nxt.objectives[-1])
    # the same drop where the motion-from-rest check ([solver] path_start) moved the state: the
    # measurement's, not the step's; accepted, the guard's next reference
    moved = dataclasses.replace(solved, path_moved=("pull",))
    again = dict(row, rejected="")
    kept = advance(setup, st, moved, filt, again, st.reference, st.reference_stored)
    assert again["rejected"] == "" and kept.guarded is st.guarded
    removed = np.flatnonzero(st.designs[-1] & ~(st.design > 0.5))
    assert len(removed) > 1
    # guarded: the half of the removed faces that ranked highest for the motion when accepted
    best = removed[np.argsort(-st.accepted_alpha["pull"][removed], kind="stable")[: (len(removed) + 1) // 2]]
    np.testing.assert_array_equal(np.flatnonzero(nxt.guarded), np.sort(best))
    assert nxt.target == st.target and nxt.alpha_prev is st.alpha_prev and nxt.warm is st.warm
    assert nxt.accepted_alpha is st.accepted_alpha
    assert np.all(nxt.design[nxt.guarded] == 1.0)  # guarded faces are kept
    save_checkpoint(tmp_path, nxt)
    back = load_checkpoint(tmp_path)
    np.testing.assert_array_equal(back.guarded, nxt.guarded)
    np.testing.assert_array_equal(back.accepted_alpha["pull"], nxt.accepted_alpha["pull"])
    rows = [dict(r, area=setup.beso.params.target_area) for r in nxt.metrics]
    rows[-1]["objective"] = 10.0  # even with the best objective, a rejected step is not reported
    assert best_iteration(rows, setup.beso.params.target_area, setup.beso.params.er) != rows[-1]["iteration"]
