"""Activation sets per motion ([motions.activation]) and the lockout penalty: the states the
objective needs, and how their energies and sensitivities combine."""

from __future__ import annotations

import numpy as np
import pytest

from kgarment.case import Case
from kgarment.optimize.objective import combine_sensitivities, objective_value
from kgarment.sim import SolverOptions, build_model
from kgarment.sim.synthetic import Tube


def tube_setup(activation=None, lockout=0.0, objective="active"):
    tube = Tube(0.05, 0.0, 0.3, 16, 9)
    clutches = [tube.clutch("a", 0.0, 0.08, 0.22, 0.01, 8), tube.clutch("b", np.pi, 0.08, 0.22, 0.01, 8)]
    model = build_model(tube.vertices, tube.faces, clutches, preset="paper")
    motions = {"pull": tube.motion("pull", 0.05, 0.0), "twist": tube.motion("twist", 0.0, 0.3)}
    return Case.build(model, motions, objective, SolverOptions(), activation=activation,
                             lockout=lockout)


def test_without_sets_every_motion_switches_every_clutch():
    s = tube_setup()
    keyed = dict(s.states())
    assert list(keyed) == [("pull", "on"), ("pull", "off"), ("twist", "on"), ("twist", "off")]
    np.testing.assert_array_equal(keyed[("pull", "on")].activation, [1.0, 1.0])
    np.testing.assert_array_equal(keyed[("twist", "off")].activation, [0.0, 0.0])
    assert not s.selective()


def test_sets_and_lock_states():
    """Each motion's ON state is its set; with a lockout each motion is also solved under
    the other's set (and not where two motions share a set)."""
    sets = {"pull": np.array([1.0, 0.0]), "twist": np.array([0.0, 0.5])}
    keyed = dict(tube_setup(sets, lockout=1.0).states())
    assert list(keyed) == [("pull", "on"), ("pull", "off"), ("pull", "lock:twist"),
                           ("twist", "on"), ("twist", "off"), ("twist", "lock:pull")]
    np.testing.assert_array_equal(keyed[("pull", "on")].activation, [1.0, 0.0])
    np.testing.assert_array_equal(keyed[("pull", "lock:twist")].activation, [0.0, 0.5])
    np.testing.assert_array_equal(keyed[("twist", "lock:pull")].activation, [1.0, 0.0])
    assert list(dict(tube_setup(sets, lockout=0.0).states())) == [("pull", "on"), ("pull", "off"),
                                                                   ("twist", "on"), ("twist", "off")]
    same = {"pull": np.array([1.0, 0.0]), "twist": np.array([1.0, 0.0])}
    assert all(not k[1].startswith("lock:") for k in dict(tube_setup(same, lockout=1.0).states()))
    # the compliance objective has no OFF states and no lockout
    assert list(dict(tube_setup(sets, lockout=1.0, objective="compliance").states())) == [("pull", "on"),
                                                                                          ("twist", "on")]


def test_the_connected_update_passes_only_clutches_switched_on_together():
    """An OFF clutch is compliant cloth: the connected update may hold a clutch's end
    through another clutch only where some motion switches both on."""
    assert tube_setup().end_partners() is None  # every clutch ON in every motion
    s = tube_setup({"pull": np.array([1.0, 0.0]), "twist": np.array([0.0, 0.5])})
    assert len(s.all_end_faces) == 2
    assert [list(p) for p in s.end_partners()] == [[], []]
    s = tube_setup({"pull": np.array([1.0, 1.0]), "twist": np.array([0.0, 1.0])})
    assert [list(p) for p in s.end_partners()] == [[1], [0]]


def test_a_set_two_motions_share_is_one_lock_state():
    """A motion pays once for each other set, however many motions switch it (an early
    pose of a motion shares the motion's set): the same switch state is not counted twice."""
    tube = Tube(0.05, 0.0, 0.3, 16, 9)
    clutches = [tube.clutch("a", 0.0, 0.08, 0.22, 0.01, 8), tube.clutch("b", np.pi, 0.08, 0.22, 0.01, 8)]
    model = build_model(tube.vertices, tube.faces, clutches, preset="paper")
    motions = {"pull": tube.motion("pull", 0.05, 0.0), "twist": tube.motion("twist", 0.0, 0.3),
               "twist@0.33": tube.motion("twist@0.33", 0.0, 0.1)}
    sets = {"pull": np.array([1.0, 0.0]), "twist": np.array([0.0, 1.0]), "twist@0.33": np.array([0.0, 1.0])}
    s = Case.build(model, motions, "active", SolverOptions(), activation=sets, lockout=1.0)
    locks = [k for k, _ in s.states() if k[1].startswith("lock:")]
    assert locks == [("pull", "lock:twist"), ("twist", "lock:pull"), ("twist@0.33", "lock:pull")]


def test_the_lockout_subtracts_what_other_sets_store():
    """Per motion: (ON - OFF - w * sum(LOCK - OFF)) / max(ON sensitivity), summed; the
    scalar objective likewise over the fully reinforced garment's ON energy."""
    rng = np.random.default_rng(3)
    a = {(m, s): rng.random(7) for m in ("pull", "twist") for s in ("on", "off", "lock:x")}
    w = 0.7
    want = sum((a[(m, "on")] - a[(m, "off")] - w * (a[(m, "lock:x")] - a[(m, "off")])) / a[(m, "on")].max()
               for m in ("pull", "twist"))
    np.testing.assert_allclose(combine_sensitivities("active", a, ["pull", "twist"], w), want)
    plain = sum((a[(m, "on")] - a[(m, "off")]) / a[(m, "on")].max() for m in ("pull", "twist"))
    np.testing.assert_allclose(combine_sensitivities("active", a, ["pull", "twist"], 0.0), plain)
    e = {("pull", "on"): 5.0, ("pull", "off"): 1.0, ("pull", "lock:x"): 3.0}
    ref = {("pull", "on"): 10.0}
    assert objective_value("active", e, ref, ["pull"], w) == pytest.approx((5 - 1 - w * (3 - 1)) / 10)
    assert objective_value("active", e, ref, ["pull"]) == pytest.approx(0.4)


def test_balance_adds_one_solo_state_per_clutch_of_a_set():
    """With a balance, each clutch of a motion's set is also solved alone ON (at its set's
    value); a set of one clutch needs none (its share is 1 by definition)."""
    keyed = dict(Case.build(tube_setup().model, tube_setup().motions, "active", SolverOptions(),
                                   activation={"twist": np.array([0.0, 0.5])}, balance=0.3).states())
    assert list(keyed) == [("pull", "on"), ("pull", "off"), ("pull", "solo:a"), ("pull", "solo:b"),
                           ("twist", "on"), ("twist", "off")]
    np.testing.assert_array_equal(keyed[("pull", "solo:a")].activation, [1.0, 0.0])
    np.testing.assert_array_equal(keyed[("pull", "solo:b")].activation, [0.0, 1.0])
    assert all(not k[1].startswith("solo:") for k in dict(tube_setup().states()))


def test_balance_pushes_only_clutches_that_carry_little():
    """The balance weight of a clutch is h'(G_c) = clip(1 - s_c / tau, 0, 1): the derivative
    of the scalar balance term h (finite differences, G held); a clutch at or above the share
    tau gets none (the strongest is not counted twice); the sensitivity adds each weighted
    solo gain scaled to the size of the ON - OFF gain's."""
    from kgarment.optimize.objective import BALANCE_SHARE as tau
    from kgarment.optimize.objective import balance_weights

    e = {("pull", "on"): 5.0, ("pull", "off"): 1.0, ("pull", "solo:a"): 4.9, ("pull", "solo:b"): 1.2,
         ("pull", "solo:c"): 0.9}
    w = balance_weights(e, "pull")
    assert w[("pull", "solo:a")] == 0.0  # share 0.975
    assert w[("pull", "solo:b")] == pytest.approx(1 - 0.05 / tau)
    assert w[("pull", "solo:c")] == 1.0  # below OFF
    ref = {("pull", "on"): 10.0}
    h = 1e-6
    for key in w:
        up, down = dict(e), dict(e)
        up[key] += h
        down[key] -= h
        fd = (objective_value("active", up, ref, ["pull"], 0.0, 1.0)
              - objective_value("active", down, ref, ["pull"], 0.0, 1.0)) / (2 * h) * 10.0
        assert fd == pytest.approx(w[key], abs=1e-5)
    assert objective_value("active", e, ref, ["pull"]) == pytest.approx(0.4)
    rng = np.random.default_rng(5)
    a = {("pull", s): rng.random(6) for s in ("on", "off", "solo:a", "solo:b", "solo:c")}
    bw = 0.4
    want = (a[("pull", "on")] - a[("pull", "off")]) / a[("pull", "on")].max()
    for key, wk in w.items():
        g = a[key] - a[("pull", "off")]
        want = want + bw * wk * g / np.abs(g).max()
    np.testing.assert_allclose(combine_sensitivities("active", a, ["pull"], 0.0, bw, e), want)
    with pytest.raises(ValueError, match="energies"):
        combine_sensitivities("active", a, ["pull"], 0.0, bw)


def test_the_control_table_agrees_with_the_evaluation_on_designed_and_locking_sets():
    """Pull's set {a}, twist's {b}, a lockout: in the control table, each motion's own set
    is its evaluated ON state and the other motion's set its evaluated lock state (solved
    the evaluator's way, the same equilibria), so the two never give two energies for one
    state."""
    from kgarment.evaluate import Evaluator
    from kgarment.evaluate.plan import make_plan

    sets = {"pull": np.array([1.0, 0.0]), "twist": np.array([0.0, 1.0])}
    ev = Evaluator(tube_setup(sets, lockout=1.0))
    design = np.where(np.arange(ev.n_faces) % 3 == 0, 1e-3, 1.0)
    res = ev.evaluate(design)
    energy = {s.key: s.result.total_energy for s in res.states}
    plan = make_plan(ev, design)
    for m, own, other in (("pull", "a", "b"), ("twist", "b", "a")):
        assert plan.get(m, [own]).energy_J == pytest.approx(energy[(m, "on")], rel=1e-12)
        lock = "twist" if m == "pull" else "pull"
        assert plan.get(m, [other]).energy_J == pytest.approx(energy[(m, f"lock:{lock}")], rel=1e-9)
        assert plan.energy_off_J[m] == pytest.approx(energy[(m, "off")], rel=1e-12)
