"""How the motions' terms combine (``[design] combine``, kgarment.optimize.objective)."""

from __future__ import annotations

import pytest

from kgarment.optimize.objective import (
    PRODUCT_FLOOR,
    combined_objective,
    motion_weights,
    objective_value,
)
from kgarment.problem import parse_problem, problem_to_dict


def test_sum_is_the_plain_sum_with_equal_weights():
    terms = {"a": 0.4, "b": 0.1, "c": -0.2}
    assert combined_objective("sum", terms) == pytest.approx(0.3)
    assert motion_weights("sum", terms) is None


def test_product_weights_are_the_gradient_of_the_geometric_mean():
    """d/dT_m of n (prod T)^(1/n) = G / T_m: the weights are proportional to it (by central
    finite differences), scaled to mean 1, and a term below the floor counts as the floor."""
    terms = {"a": 0.4, "b": 0.1, "c": 0.05}
    w = motion_weights("product", terms)
    assert sum(w.values()) / len(w) == pytest.approx(1.0)
    h = 1e-7
    grad = {m: (combined_objective("product", {**terms, m: t + h})
                - combined_objective("product", {**terms, m: t - h})) / (2 * h) for m, t in terms.items()}
    ratio = [grad[m] / w[m] for m in terms]
    assert max(ratio) == pytest.approx(min(ratio), rel=1e-6)
    # equal terms: the product's objective equals the sum, weights all 1
    assert combined_objective("product", {"a": 0.3, "b": 0.3}) == pytest.approx(0.6)
    assert motion_weights("product", {"a": 0.3, "b": 0.3}) == pytest.approx({"a": 1.0, "b": 1.0})
    # a failing motion weighs at most 1 / PRODUCT_FLOOR against the others' 1 / T
    w = motion_weights("product", {"a": 0.5, "b": -1.0})
    assert w["b"] / w["a"] == pytest.approx(0.5 / PRODUCT_FLOOR)
    assert combined_objective("product", {"a": 0.5, "b": -1.0}) == pytest.approx(2 * (0.5 * PRODUCT_FLOOR) ** 0.5)


def test_shares_weigh_the_terms_and_their_sensitivities():
    """With shares (an early pose and its motion, 1/2 each): the sum is the weighted sum and
    its sensitivity weights are the shares; the product is the share-weighted geometric mean
    (times the shares' sum), and its weights are proportional to its gradient (central finite
    differences); all shares 1 is the plain objective."""
    terms = {"a": 0.4, "a@0.33": 0.2, "b": 0.1}
    shares = {"a": 0.5, "a@0.33": 0.5}
    assert combined_objective("sum", terms, shares) == pytest.approx(0.5 * 0.4 + 0.5 * 0.2 + 0.1)
    assert motion_weights("sum", terms, shares) == {"a": 0.5, "a@0.33": 0.5, "b": 1.0}
    assert combined_objective("product", terms, shares) == pytest.approx(2 * (0.4 ** 0.5 * 0.2 ** 0.5 * 0.1) ** 0.5)
    w = motion_weights("product", terms, shares)
    assert sum(w.values()) / len(w) == pytest.approx(1.0)
    h = 1e-7
    grad = {m: (combined_objective("product", {**terms, m: t + h}, shares)
                - combined_objective("product", {**terms, m: t - h}, shares)) / (2 * h) for m, t in terms.items()}
    ratio = [grad[m] / w[m] for m in terms]
    assert max(ratio) == pytest.approx(min(ratio), rel=1e-6)
    ones = dict.fromkeys(terms, 1.0)
    for combine in ("sum", "product"):
        assert combined_objective(combine, terms, ones) == pytest.approx(combined_objective(combine, terms))


def test_objective_value_combines_the_terms():
    energy = {("a", "on"): 3.0, ("a", "off"): 1.0, ("b", "on"): 5.0, ("b", "off"): 4.0}
    ref = {("a", "on"): 10.0, ("b", "on"): 10.0}  # terms 0.2 and 0.1
    assert objective_value("active", energy, ref, ["a", "b"]) == pytest.approx(0.3)
    assert objective_value("active", energy, ref, ["a", "b"], combine="product") == pytest.approx(2 * 0.02 ** 0.5)


def test_combine_is_written_only_when_not_the_default(tmp_path):
    p = parse_problem({"design": {"combine": "product"}}, tmp_path)
    assert p.design.combine == "product"
    d = problem_to_dict(p)
    assert d["design"]["combine"] == "product"
    assert parse_problem(d, tmp_path).design.combine == "product"
    assert "combine" not in problem_to_dict(parse_problem({}, tmp_path))["design"]
