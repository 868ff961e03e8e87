"""Bi-directional evolutionary structural optimization (BESO), split along its seams:
interpolation, sensitivities, filter, history, area schedule and the add/remove update.

All functions are pure; the loop in :mod:`kgarment.optimize.loop` strings them together.
Design variable x_e in {x_min, 1} per garment triangle (soft-kill, docs/method/index.md, "BESO").
"""

from __future__ import annotations

import math

import numpy as np
import scipy.sparse as sp

from kgarment.case.values import design_values
from kgarment.constants import PENALTY, X_MIN
from kgarment.problem.spec import BesoParams

__all__ = [
    "PENALTY",
    "X_MIN",
    "BesoParams",
    "converged",
    "expected_iterations",
    "interpolate",
    "next_target",
    "one_ring_filter",
    "radius_filter",
    "sensitivity_factor",
    "settled_ar",
    "update_design",
]


def interpolate(x: np.ndarray, y0: float | np.ndarray, y1: float | np.ndarray, p: float = PENALTY) -> np.ndarray:
    """Y(x) = x^p Y1 + (1 - x^p) Y0 for x (m,) in [x_min, 1]."""
    xp = np.power(x, p)
    return xp * y1 + (1.0 - xp) * y0


def sensitivity_factor(x: np.ndarray, y0: float, y1: float, p: float = PENALTY) -> np.ndarray:
    """(m,) factor turning element energy density into the BESO sensitivity:
    x^(p-1) (Y1 - Y0) / Y(x), which is 1 - Y0/Y1 for reinforced faces (docs/method/index.md, "BESO")."""
    return np.power(x, p - 1.0) * (y1 - y0) / interpolate(x, y0, y1, p)


def one_ring_filter(faces: np.ndarray, areas: np.ndarray, n_vertices: int) -> sp.csr_matrix:
    """(m, m) filter matrix: area-weighted average of face values onto vertices over the
    one-ring, then back to faces as the mean of their three vertices. Rows sum to 1.

    faces : (m, 3) int; areas : (m,) m^2.
    """
    m = len(faces)
    rows = faces.reshape(-1)
    cols = np.repeat(np.arange(m), 3)
    W = sp.csr_matrix((np.repeat(areas, 3), (rows, cols)), shape=(n_vertices, m))
    W = sp.diags(1.0 / np.maximum(np.asarray(W.sum(1)).ravel(), 1e-300)) @ W
    B = sp.csr_matrix((np.full(3 * m, 1.0 / 3.0), (cols, rows)), shape=(m, n_vertices))
    return (B @ W).tocsr()


def radius_filter(centroids: np.ndarray, areas: np.ndarray, radius: float) -> sp.csr_matrix:
    """(m, m) classic BESO filter: weights (r - distance)_+ times area, rows normalized.

    centroids : (m, 3) metres; areas : (m,) m^2; radius : metres.
    """
    from scipy.spatial import cKDTree

    tree = cKDTree(centroids)
    D = tree.sparse_distance_matrix(tree, radius, output_type="coo_matrix")
    i, j, d = D.row, D.col, D.data
    diag = np.arange(len(centroids))
    i, j, d = np.r_[i, diag], np.r_[j, diag], np.r_[d, np.zeros(len(diag))]
    keep = np.r_[i[:-len(diag)] != j[:-len(diag)], np.ones(len(diag), bool)]
    w = (radius - d[keep]) * areas[j[keep]]
    H = sp.csr_matrix((w, (i[keep], j[keep])), shape=(len(centroids),) * 2)
    return (sp.diags(1.0 / np.asarray(H.sum(1)).ravel()) @ H).tocsr()


def next_target(current: float, params: BesoParams) -> float:
    """The next iteration's target area fraction: shrink by ER until A*, then stay."""
    if current > params.target_area:
        return max(params.target_area, current * (1.0 - params.er))
    return min(params.target_area, current * (1.0 + params.er))


def expected_iterations(params: BesoParams) -> int:
    """About how many iterations a run takes (for progress bars' ETA): the schedule down to the
    target area (:func:`next_target`) and two convergence windows there, at most
    ``max_iterations``."""
    return min(params.max_iterations,
               math.ceil(math.log(params.target_area) / math.log(1 - params.er)) + 2 * params.window)


def settled_ar(params: BesoParams, at_target: int) -> float:
    """The share of faces that may be added in the next update after ``at_target``
    iterations at the target area: ``ar_max`` until the target, then halved every
    ``settle`` iterations there (``ar_max`` with ``settle = 0``)."""
    if params.settle <= 0 or at_target <= 0:
        return params.ar_max
    return params.ar_max * 0.5 ** (at_target / params.settle)


def update_design(x: np.ndarray, alpha: np.ndarray, areas: np.ndarray, target: float,
                  params: BesoParams, ar: float | None = None) -> np.ndarray:
    """One BESO add/remove step.

    x : (m,) current design in {x_min, 1}; alpha : (m,) filtered sensitivities (higher =
    more useful as reinforcement); areas : (m,) m^2; target : reinforced area fraction for
    the next design. Faces are ranked by alpha and thresholded at the target area; at most
    ``ar`` (default ``params.ar_max``) of the faces are added, and then removals are
    adjusted so that the target area is met. Returns the new (m,) design.
    """
    solid = x > 0.5
    total = areas.sum()
    order = np.argsort(-alpha, kind="stable")
    cum = np.cumsum(areas[order])
    k = int(np.searchsorted(cum, target * total, side="left")) + 1
    k = min(k, len(order))
    new_solid = np.zeros_like(solid)
    new_solid[order[:k]] = True
    added = new_solid & ~solid
    max_add = int(np.floor((params.ar_max if ar is None else ar) * len(x)))
    if added.sum() > max_add:
        # keep only the best max_add additions, then fill the target with the best
        # currently-solid faces (i.e. remove the worst solid ones)
        cand = np.flatnonzero(~solid)
        best_add = cand[np.argsort(-alpha[cand], kind="stable")[:max_add]]
        budget = target * total - areas[best_add].sum()
        sol = np.flatnonzero(solid)
        sol = sol[np.argsort(-alpha[sol], kind="stable")]
        ks = int(np.searchsorted(np.cumsum(areas[sol]), budget, side="left")) + 1
        new_solid = np.zeros_like(solid)
        new_solid[best_add] = True
        new_solid[sol[:max(0, min(ks, len(sol)))]] = True
    return design_values(new_solid)


def converged(history: list[float], reached: bool, params: BesoParams) -> bool:
    """Target reached and |sum of the last N objectives - the N before| / sum < tol."""
    n = params.window
    if not reached or len(history) < 2 * n:
        return False
    a, b = np.sum(history[-n:]), np.sum(history[-2 * n:-n])
    return abs(a - b) <= params.tol * max(abs(a), 1e-300)
