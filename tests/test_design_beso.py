"""BESO building blocks: interpolation, filters, schedule, update, convergence, metrics."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from kgarment.evaluate.metrics import Stored, clutch_end_support, islands, relative_energy_density
from kgarment.optimize.beso import (
    BesoParams,
    converged,
    expected_iterations,
    interpolate,
    next_target,
    one_ring_filter,
    radius_filter,
    sensitivity_factor,
    settled_ar,
    update_design,
)
from kgarment.optimize.objective import combine_sensitivities


def _sheet(n=12):
    xs, ys = np.meshgrid(np.linspace(0, 1, n + 1), np.linspace(0, 1, n + 1))
    V = np.c_[xs.ravel(), ys.ravel(), np.zeros(xs.size)]
    idx = np.arange(V.shape[0]).reshape(n + 1, n + 1)
    a, b, c, d = idx[:-1, :-1].ravel(), idx[:-1, 1:].ravel(), idx[1:, 1:].ravel(), idx[1:, :-1].ravel()
    F = np.r_[np.c_[a, b, c], np.c_[a, c, d]]
    return V, F


def test_interpolation_ends_and_factor():
    assert interpolate(np.array([1.0]), 2.0, 5.0)[0] == 5.0
    assert interpolate(np.array([0.0]), 2.0, 5.0)[0] == 2.0
    # the factor is d ln Y / dx divided by p: check by finite differences
    x, y0, y1, p, h = 0.3, 0.5e6, 0.5e9, 1.6, 1e-7
    dlny = (np.log(interpolate(np.array([x + h]), y0, y1, p)) - np.log(interpolate(np.array([x - h]), y0, y1, p))) / (2 * h)
    assert sensitivity_factor(np.array([x]), y0, y1, p)[0] == pytest.approx(dlny[0] / p, rel=1e-6)
    assert sensitivity_factor(np.array([1.0]), y0, y1)[0] == pytest.approx(1 - y0 / y1)


@pytest.mark.parametrize("kind", ["one_ring", "radius"])
def test_filters_keep_constants_and_smooth(kind):
    V, F = _sheet()
    tri = V[F]
    areas = 0.5 * np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1)
    H = one_ring_filter(F, areas, len(V)) if kind == "one_ring" else radius_filter(tri.mean(1), areas, 0.15)
    np.testing.assert_allclose(H @ np.full(len(F), 3.7), 3.7)
    spike = np.zeros(len(F))
    spike[len(F) // 2] = 1.0
    out = H @ spike
    assert out.max() < 1.0 and (out > 0).sum() > 3 and out.sum() > 0


def test_schedule_reaches_target_in_the_expected_iterations():
    p = BesoParams(target_area=0.15, er=0.015)
    v, k = 1.0, 0
    while v > 0.15:
        v, k = next_target(v, p), k + 1
    assert k == math.ceil(math.log(0.15) / math.log(0.985))  # 126, as in the reference
    assert next_target(0.15, p) == 0.15
    # the progress bars' estimate: the schedule and two convergence windows, at most the cap
    assert expected_iterations(dataclasses.replace(p, window=5)) == 126 + 10
    assert expected_iterations(dataclasses.replace(p, window=5, max_iterations=50)) == 50


def test_update_meets_the_target_and_the_add_ratio():
    rng = np.random.default_rng(0)
    m = 2000
    areas = rng.uniform(0.5, 1.5, m)
    x = np.where(rng.random(m) < 0.5, 1.0, 1e-3)
    alpha = rng.random(m)
    p = BesoParams(ar_max=0.015)
    new = update_design(x, alpha, areas, 0.45, p)
    frac = areas[new > 0.5].sum() / areas.sum()
    assert abs(frac - 0.45) < 2 * areas.max() / areas.sum()
    assert ((new > 0.5) & (x < 0.5)).sum() <= int(0.015 * m)
    # without the add limit it is a pure ranking
    free = update_design(x, alpha, areas, 0.45, BesoParams(ar_max=1.0))
    s = free > 0.5
    assert alpha[s].min() >= alpha[~s].max()


def test_settle_halves_the_additions_at_the_target():
    p = BesoParams(ar_max=0.016, settle=4)
    assert settled_ar(p, 0) == 0.016  # on the way to the target: the paper's ratio
    assert settled_ar(p, 4) == pytest.approx(0.008) and settled_ar(p, 8) == pytest.approx(0.004)
    assert settled_ar(p, 2) == pytest.approx(0.016 / math.sqrt(2))
    assert settled_ar(BesoParams(ar_max=0.016), 50) == 0.016  # settle = 0: off
    # an update allowed no addition keeps the design's reinforced faces, whatever alpha says
    rng = np.random.default_rng(1)
    m = 1000
    areas = np.ones(m)
    x = np.where(np.arange(m) < 300, 1.0, 1e-3)
    new = update_design(x, rng.random(m), areas, 0.3, p, ar=0.0)
    np.testing.assert_array_equal(new, x)
    few = update_design(x, rng.random(m), areas, 0.3, p, ar=0.005)
    assert ((few > 0.5) & (x < 0.5)).sum() == 5 and (few > 0.5).sum() == 300


def test_convergence_test():
    p = BesoParams(window=5, tol=1e-3)
    flat = [1.0] * 10
    assert converged(flat, True, p) and not converged(flat, False, p)
    assert not converged(list(np.linspace(1, 2, 10)), True, p)


def test_metrics_rho_islands_and_clutch_ends():
    V, F = _sheet(4)
    areas = np.full(len(F), 1.0)
    full = Stored(np.ones(len(F)))
    d = np.full(len(F), 1e-3)
    d[:4] = 1.0
    # a design storing all of the full garment's energy in a quarter of... 4 faces:
    state = Stored(np.where(d > 0.5, 2.0, 0.0))
    assert relative_energy_density(d, areas, state, full) == pytest.approx((8 / 4) / (32 / 32))
    assert islands(F, np.ones(len(F))) == 1
    two = np.full(len(F), 1e-3)
    two[[0, len(F) - 1]] = 1.0
    assert islands(F, two) == 2
    assert islands(F, two, links=[(np.array([0]), np.array([len(F) - 1]))]) == 1
    assert clutch_end_support(two, [(np.array([0]), np.array([5]))]) == [(True, False)]


def test_active_objective_normalises_each_motion():
    on = {("a", "on"): np.array([1.0, 2.0]), ("a", "off"): np.array([0.5, 0.0]),
          ("b", "on"): np.array([100.0, 0.0]), ("b", "off"): np.array([0.0, 0.0])}
    s = combine_sensitivities("active", on, ["a", "b"])
    np.testing.assert_allclose(s, [0.25 + 1.0, 1.0 + 0.0])
