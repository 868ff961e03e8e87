"""``[design] weights``: a designer's weight per motion in the objective (the paper counts
every motion equally), parsed, written back, and applied to the motion's share."""

from __future__ import annotations

import tomllib

import numpy as np
import pytest
from tiny_problems import TINY_SLEEVE

from kgarment.case.frames import objective_shares
from kgarment.errors import KgarmentError
from kgarment.optimize.objective import combine_sensitivities, combined_objective, motion_weights
from kgarment.problem import parse_problem, problem_to_dict

WEIGHTED = TINY_SLEEVE + """[design]
weights = { "arm_flexion.right" = 2.5 }
"""


def test_parsed_written_and_read_back():
    p = parse_problem(tomllib.loads(WEIGHTED))
    assert p.design.weights == (("arm_flexion.right", 2.5),)
    assert parse_problem(problem_to_dict(p)).design.weights == p.design.weights
    assert "weights" not in problem_to_dict(parse_problem(tomllib.loads(TINY_SLEEVE)))["design"]  # hashes stay


@pytest.mark.parametrize(("value", "says"), [
    ('{ "arm_raise" = 2 }', "not a motion of the problem; its motions: arm_flexion.right"),
    ('{ "arm_flexion.right" = 0 }', "the weight must be a number in (0, 10]"),
    ('{ "arm_flexion.right" = -1.0 }', "the weight must be a number in (0, 10]"),
    ('{ "arm_flexion.right" = 11 }', "the weight must be a number in (0, 10]"),
    ('{ "arm_flexion.right" = true }', "the weight must be a number in (0, 10]"),
    ("2.0", "must be a table of motion = weight"),
])
def test_bad_weights_are_one_line_naming_what_is_allowed(value, says):
    with pytest.raises(KgarmentError) as e:
        parse_problem(tomllib.loads(TINY_SLEEVE + f"[design]\nweights = {value}\n"))
    assert says in str(e.value) and "\n" not in str(e.value)


def test_a_weight_multiplies_the_motion_and_its_early_poses():
    assert objective_shares((), ()) == {}
    assert objective_shares((), (("a", 2.0),)) == {"a": 2.0}
    got = objective_shares((("a", 0.5),), (("a", 3.0), ("b", 0.5)))
    assert got == pytest.approx({"a": 1.5, "a@0.50": 1.5, "b": 0.5})


def test_weights_scale_the_objective_and_the_sensitivities():
    """With weight w on motion a, the objective is w T_a + T_b and a's normalised
    sensitivities count w times (the sum's gradient, by finite differences of the terms);
    a wearer's state MOTION@BODY takes its motion's weight."""
    rng = np.random.default_rng(3)
    alpha = {(m, s): rng.uniform(0.1, 1.0, 7) for m in ("a", "b") for s in ("on", "off")}
    shares = objective_shares((), (("a", 2.5),))
    terms = {"a": 0.3, "b": 0.2}
    assert combined_objective("sum", terms, shares) == pytest.approx(2.5 * 0.3 + 0.2)
    h = 1e-6
    d_a = (combined_objective("sum", {**terms, "a": 0.3 + h}, shares) - combined_objective("sum", terms, shares)) / h
    assert d_a == pytest.approx(2.5, rel=1e-6)
    w = motion_weights("sum", terms, shares)
    assert w == {"a": 2.5, "b": 1.0}
    plain = combine_sensitivities("active", alpha, ["a", "b"])
    weighted = combine_sensitivities("active", alpha, ["a", "b"], weights=w)
    only_b = combine_sensitivities("active", alpha, ["b"])
    assert np.allclose(weighted - only_b, 2.5 * (plain - only_b))
    assert motion_weights("sum", {"a@body1": 0.3, "b@body1": 0.2}, shares) == {"a@body1": 2.5, "b@body1": 1.0}
    # product: the weight multiplies 1 / T (then scaled to mean 1)
    p = motion_weights("product", terms, shares)
    assert p["a"] / p["b"] == pytest.approx(2.5 * 0.2 / 0.3)


def test_the_report_names_the_weights():
    from kgarment.reproduce.report import early_note, weights_note

    assert weights_note({}) == "" and weights_note({"weights": {}}) == ""
    assert "(`[design] weights`: arm_extension.right 1.5; the others 1)" in weights_note(
        {"weights": {"arm_extension.right": 1.5}})
    assert early_note({"early": {"a": 0.33}}).endswith("(`[design] early`: a at 0.33 of its movement)")
