"""Small analytic meshes for tests, benchmarks and demos of the clutch code."""

from __future__ import annotations

import numpy as np


def grid_faces(nu: int, nv: int, rng: np.random.Generator | None = None) -> np.ndarray:
    """(2 nu nv, 3) triangles of a (nu + 1) x (nv + 1) vertex grid (index ``i (nv+1) + j``),
    counter-clockwise in (i, j); each quad's diagonal is random if ``rng`` is given."""
    i, j = np.meshgrid(np.arange(nu), np.arange(nv), indexing="ij")
    a = (i * (nv + 1) + j).ravel()
    b, c, d = a + nv + 1, a + nv + 2, a + 1
    flip = rng.random(a.size) < 0.5 if rng is not None else np.zeros(a.size, bool)
    t1 = np.where(flip[:, None], np.stack([a, b, d], 1), np.stack([a, b, c], 1))
    t2 = np.where(flip[:, None], np.stack([b, c, d], 1), np.stack([a, c, d], 1))
    return np.concatenate([t1, t2]).astype(np.int64)


def flat_sheet(
    size: float = 0.3,
    n: int = 40,
    *,
    jitter: float = 0.0,
    thin: bool = False,
    seed: int = 0,
) -> tuple[np.ndarray, np.ndarray]:
    """A square sheet ``[0, size]^2`` in the plane z = 0, normals +z.

    n : quads per side; jitter : random in-plane displacement of interior vertices, as a
    fraction of the spacing (with random diagonals); thin : squeeze a few grid columns and
    rows to 1e-3 of the spacing, making slivers. Returns V (n', 3), F (m, 3).
    """
    rng = np.random.default_rng(seed)
    x = np.linspace(0.0, size, n + 1)
    h = size / n
    if thin:
        for k in range(3, n - 2, 7):  # pull a line next to its neighbour: sliver triangles
            x[k] = x[k - 1] + 1e-3 * h
    X, Y = np.meshgrid(x, x, indexing="ij")
    if jitter:
        inner = np.zeros_like(X, dtype=bool)
        inner[1:-1, 1:-1] = True
        if thin:  # keep the slivers thin: move only columns/rows that were not squeezed
            gap = np.diff(x)
            free = np.r_[True, (gap[:-1] > 0.5 * h) & (gap[1:] > 0.5 * h), True]
            inner &= free[:, None] & free[None, :]
        X = X + inner * rng.uniform(-jitter, jitter, X.shape) * h
        Y = Y + inner * rng.uniform(-jitter, jitter, Y.shape) * h
    V = np.stack([X.ravel(), Y.ravel(), np.zeros(X.size)], axis=1)
    F = grid_faces(n, n, rng if jitter else None)
    return V, F


def open_prism(
    radius: float = 0.05, height: float = 0.3, sides: int = 24, rings: int = 60
) -> tuple[np.ndarray, np.ndarray]:
    """A triangulated open cylinder (a prism: flat rectangular facets), axis z, z in
    [0, height], normals outwards. Vertex ``i (rings + 1) + j`` sits at polygon corner i
    (angle ``2 pi i / sides``) and height ``j height / rings``. Returns V, F."""
    ang = 2 * np.pi * np.arange(sides) / sides
    z = np.linspace(0.0, height, rings + 1)
    A, Z = np.meshgrid(ang, z, indexing="ij")
    V = np.stack([radius * np.cos(A).ravel(), radius * np.sin(A).ravel(), Z.ravel()], axis=1)
    F = grid_faces(sides, rings)
    F = np.where(F >= sides * (rings + 1), F - sides * (rings + 1), F)  # wrap around
    return V, F


def prism_point(
    u: float, z: float, radius: float = 0.05, sides: int = 24
) -> np.ndarray:
    """(3,) point of :func:`open_prism` at unrolled coordinates (u along the polygon, metres
    from corner 0 counter-clockwise, z height): the exact inverse of unrolling the prism."""
    chord = 2 * radius * np.sin(np.pi / sides)
    k, frac = divmod(u / chord, 1.0)
    k = int(k) % sides
    p0 = radius * np.array([np.cos(2 * np.pi * k / sides), np.sin(2 * np.pi * k / sides), 0.0])
    k1 = (k + 1) % sides
    p1 = radius * np.array([np.cos(2 * np.pi * k1 / sides), np.sin(2 * np.pi * k1 / sides), 0.0])
    return p0 + frac * (p1 - p0) + np.array([0.0, 0.0, z])
