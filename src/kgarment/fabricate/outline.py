"""2D outlines: the jagged triangle boundary of a flattened patch smoothed into curves.

A flattened patch's boundary follows triangle edges, a staircase at the mesh resolution.
Taubin smoothing (a shrink step, then an inflate step, repeated) removes that
high-frequency zigzag without shrinking the patch; every point's total move is clamped to
``max_shift`` so the outline stays within a fraction of an edge of the mesh boundary; two
rounds of Chaikin corner cutting then turn the polygon into a smooth curve for the cutter.
"""

from __future__ import annotations

import numpy as np


def polygon_area(poly: np.ndarray) -> float:
    """Signed area of a closed polygon (k, 2) (positive = counter-clockwise)."""
    x, y = poly[:, 0], poly[:, 1]
    return 0.5 * float(np.dot(x, np.roll(y, -1)) - np.dot(np.roll(x, -1), y))


def taubin_smooth(poly: np.ndarray, iterations: int = 10, lam: float = 0.5, mu: float = -0.53,
                  max_shift: float = np.inf) -> np.ndarray:
    """Taubin smoothing of a closed polyline (k, 2); no point moves more than ``max_shift``
    (same units as ``poly``) from where it started."""
    p0 = np.asarray(poly, dtype=np.float64)
    p = p0.copy()
    if len(p) < 4:
        return p
    for _ in range(iterations):
        for f in (lam, mu):
            lap = 0.5 * (np.roll(p, 1, axis=0) + np.roll(p, -1, axis=0)) - p
            p = p + f * lap
        d = p - p0
        n = np.linalg.norm(d, axis=1, keepdims=True)
        p = p0 + d * np.minimum(1.0, max_shift / np.maximum(n, 1e-300))
    return p


def chaikin(poly: np.ndarray, rounds: int = 2) -> np.ndarray:
    """Chaikin corner cutting of a closed polyline (k, 2): (k * 2**rounds, 2)."""
    p = np.asarray(poly, dtype=np.float64)
    for _ in range(rounds):
        q = np.roll(p, -1, axis=0)
        p = np.stack([0.75 * p + 0.25 * q, 0.25 * p + 0.75 * q], axis=1).reshape(-1, 2)
    return p


def smooth_outline(poly: np.ndarray, iterations: int = 10, max_shift: float | None = None,
                   rounds: int = 2) -> np.ndarray:
    """The smoothed, curved version of a closed boundary polygon (k, 2).

    max_shift : largest move of a point; default 0.3 of the median edge length."""
    poly = np.asarray(poly, dtype=np.float64)
    if iterations <= 0 and rounds <= 0:
        return poly.copy()
    if max_shift is None:
        max_shift = 0.3 * float(np.median(np.linalg.norm(np.roll(poly, -1, axis=0) - poly, axis=1)))
    return chaikin(taubin_smooth(poly, iterations, max_shift=max_shift), rounds)


def point_segment_distance(points: np.ndarray, poly: np.ndarray) -> np.ndarray:
    """(k,) distance of each point (k, 2) to the closed polyline ``poly`` (s, 2)."""
    a = np.asarray(poly, dtype=np.float64)
    b = np.roll(a, -1, axis=0)
    ab = b - a
    pts = np.asarray(points, dtype=np.float64)[:, None, :]
    t = np.clip(((pts - a) * ab).sum(-1) / np.maximum((ab * ab).sum(-1), 1e-300), 0.0, 1.0)
    return np.linalg.norm(pts - (a + t[..., None] * ab), axis=-1).min(axis=1)


def inside(points: np.ndarray, poly: np.ndarray) -> np.ndarray:
    """(k,) bool: even-odd test of points (k, 2) against a closed polygon (s, 2)."""
    x, y = np.asarray(points, dtype=np.float64).T[:, :, None]
    a = np.asarray(poly, dtype=np.float64)
    b = np.roll(a, -1, axis=0)
    cond = (a[:, 1] > y) != (b[:, 1] > y)
    xc = a[:, 0] + (y - a[:, 1]) * (b[:, 0] - a[:, 0]) / np.where(b[:, 1] == a[:, 1], 1e-300, b[:, 1] - a[:, 1])
    return ((cond & (x < xc)).sum(axis=1) % 2) == 1
