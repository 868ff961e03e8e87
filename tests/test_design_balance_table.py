"""``[design] balance`` per motion: a table rewards the clutches in the motions it names
only, so a garment of many motions pays one ``solo:`` solve per clutch in those motions,
not in all of them."""

from __future__ import annotations

import tomllib

import numpy as np
import pytest
from test_design_activation import tube_setup
from tiny_problems import TINY_SLEEVE

from kgarment.case import Case
from kgarment.errors import KgarmentError
from kgarment.optimize.objective import combine_sensitivities, objective_value
from kgarment.problem import parse_problem, problem_to_dict
from kgarment.problem.spec import balance_weight
from kgarment.sim import SolverOptions

TWO = TINY_SLEEVE.replace('use = ["arm_flexion.right"]', 'use = ["arm_flexion.right", "arm_extension.right"]')


def test_a_table_is_parsed_written_and_read_back_and_a_number_stays_a_number():
    p = parse_problem(tomllib.loads(TWO + '[design]\nbalance = { "arm_extension.right" = 2.0 }\n'))
    assert p.design.balance == (("arm_extension.right", 2.0),)
    assert p.design.balance_of("arm_extension.right") == 2.0 and p.design.balance_of("arm_flexion.right") == 0.0
    assert parse_problem(problem_to_dict(p)).design.balance == p.design.balance
    q = parse_problem(tomllib.loads(TWO + "[design]\nbalance = 1.5\n"))
    assert q.design.balance == 1.5 and problem_to_dict(q)["design"]["balance"] == 1.5
    assert "balance" not in problem_to_dict(parse_problem(tomllib.loads(TWO)))["design"]  # hashes stay


@pytest.mark.parametrize(("value", "says"), [
    ('{ "arm_raise" = 2.0 }', "not a motion of the problem; its motions: arm_flexion.right, arm_extension.right"),
    ('{ "arm_flexion.right" = 11.0 }', "a number in [0, 10]"),
    ('{ "arm_flexion.right" = "much" }', "a number in [0, 10]"),
    ("-1.0", "a number in [0, 10]"),
    ('"all"', "or a table of motion = weight"),
])
def test_bad_balance_is_one_line_naming_what_is_allowed(value, says):
    with pytest.raises(KgarmentError) as e:
        parse_problem(tomllib.loads(TWO + f"[design]\nbalance = {value}\n"))
    assert says in str(e.value) and "\n" not in str(e.value)


def test_a_design_state_takes_its_motions_weight():
    """A wearer's motion ``MOTION@BODY`` and the beginning of a motion ``MOTION@0.33`` are
    balanced as MOTION; a motion the table does not name is not."""
    table = (("arm_flexion.right", 2.0),)
    assert balance_weight(table, "arm_flexion.right@0.33") == 2.0
    assert balance_weight(dict(table), "arm_flexion.right@small") == 2.0
    assert balance_weight(table, "arm_extension.right") == 0.0
    assert balance_weight(0.5, "anything") == 0.5


def test_solo_states_only_in_the_motions_named():
    s = tube_setup()
    keyed = dict(Case.build(s.model, s.motions, "active", SolverOptions(),
                                   balance={"twist": 0.3}).states())
    assert list(keyed) == [("pull", "on"), ("pull", "off"), ("twist", "on"), ("twist", "off"),
                           ("twist", "solo:a"), ("twist", "solo:b")]


def test_the_objective_and_its_sensitivities_reward_only_the_motions_named():
    """With {pull: w}, pull's term and sensitivity are those of a balance w everywhere and
    twist's those without a balance, term by term."""
    rng = np.random.default_rng(11)
    states = ("on", "off", "solo:a", "solo:b")
    e = {(m, s): float(v) for m in ("pull", "twist") for s, v in zip(states, (5.0, 1.0, 1.3, 4.0), strict=True)}
    ref = {("pull", "on"): 10.0, ("twist", "on"): 8.0}
    a = {(m, s): rng.random(6) for m in ("pull", "twist") for s in states}
    w = 0.8
    mixed = objective_value("active", e, ref, ["pull", "twist"], 0.0, {"pull": w})
    assert mixed == pytest.approx(objective_value("active", e, ref, ["pull"], 0.0, w)
                                  + objective_value("active", e, ref, ["twist"]))
    assert mixed > objective_value("active", e, ref, ["pull", "twist"])  # the reward is there, in pull
    got = combine_sensitivities("active", a, ["pull", "twist"], 0.0, {"pull": w}, e)
    want = combine_sensitivities("active", a, ["pull"], 0.0, w, e) + combine_sensitivities("active", a, ["twist"])
    np.testing.assert_allclose(got, want)
