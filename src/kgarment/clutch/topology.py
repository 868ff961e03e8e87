"""Per-mesh precomputation for surface walks: edge adjacency and face frames.

Built once per garment mesh (vectorised numpy, well under a second for 50k faces) and
shared by every walk and every clutch on that mesh.

Conventions: local edge ``i`` of face ``f`` is the edge *opposite* local vertex ``i``,
i.e. between ``F[f, (i+1)%3]`` and ``F[f, (i+2)%3]``. A walk leaves a face through edge
``i`` when barycentric coordinate ``i`` reaches zero.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np
from scipy.spatial import cKDTree

from kgarment.clutch.errors import ClutchError


@dataclass(frozen=True)
class SurfaceHit:
    """The closest point of the surface to a query point.

    face : int; bary : (3,) float64 barycentric coordinates in ``face``;
    point : (3,) float64 position, metres; distance : float, metres.
    """

    face: int
    bary: np.ndarray
    point: np.ndarray
    distance: float


class MeshTopology:
    """Adjacency and per-face geometry of a triangle mesh.

    Parameters
    ----------
    V : (n, 3) float64 array
        Vertex positions, metres.
    F : (m, 3) int64 array
        Triangles (any orientation; the walk does not need consistent winding).

    Attributes
    ----------
    V, F : the arrays above (as float64 / int64, not copied if already so).
    neighbor : (m, 3) int64
        Face across local edge ``i`` of each face, ``-1`` on the boundary (and on
        non-manifold edges, which the walk treats as a boundary).
    neighbor_edge : (m, 3) int64
        Local index of that same edge in the neighbouring face (``-1`` on the boundary).
    normal : (m, 3) float64
        Unit face normals (from the winding).
    inward : (m, 3, 3) float64
        ``inward[f, i]``: unit vector in the plane of ``f``, perpendicular to edge ``i``,
        pointing into the face (towards vertex ``i``).
    grad : (m, 3, 3) float64
        ``grad[f, i]``: gradient of barycentric coordinate ``i`` (1/metres), so that a
        tangent vector ``d`` moves the barycentric coordinates by ``grad[f] @ d``.
    area : (m,) float64
        Face areas, m^2.
    """

    def __init__(self, V: np.ndarray, F: np.ndarray):
        V = np.ascontiguousarray(V, dtype=np.float64)
        F = np.ascontiguousarray(F, dtype=np.int64)
        if V.ndim != 2 or V.shape[1] != 3 or F.ndim != 2 or F.shape[1] != 3:
            raise ClutchError(f"mesh must be V (n, 3) and F (m, 3), got {V.shape} and {F.shape}")
        if len(F) == 0 or F.min() < 0 or F.max() >= len(V):
            raise ClutchError("mesh faces index outside the vertex array (or there are none)")
        self.V = V
        self.F = F
        self._build_adjacency()
        self._build_frames()

    @property
    def n_faces(self) -> int:
        return len(self.F)

    def matches(self, V: np.ndarray, F: np.ndarray) -> bool:
        """True if this topology was built for arrays of these shapes (cheap check)."""
        return V.shape == self.V.shape and F.shape == self.F.shape

    def _build_adjacency(self) -> None:
        F, m = self.F, len(self.F)
        a = F[:, [1, 2, 0]].reshape(-1)  # local edge i: (F[i+1], F[i+2])
        b = F[:, [2, 0, 1]].reshape(-1)
        key = np.minimum(a, b) * len(self.V) + np.maximum(a, b)
        order = np.argsort(key, kind="stable")
        ks = key[order]
        start = np.r_[True, ks[1:] != ks[:-1]]
        group = np.cumsum(start) - 1
        counts = np.bincount(group)
        cnt = counts[group]  # faces on the edge of each half-edge (sorted order)
        neighbor = np.full(3 * m, -1, dtype=np.int64)
        neighbor_edge = np.full(3 * m, -1, dtype=np.int64)
        # manifold interior edges: exactly two half-edges, adjacent in sorted order
        first = np.flatnonzero(start & (cnt == 2))
        h0, h1 = order[first], order[first + 1]
        neighbor[h0], neighbor[h1] = h1 // 3, h0 // 3
        neighbor_edge[h0], neighbor_edge[h1] = h1 % 3, h0 % 3
        self.neighbor = neighbor.reshape(m, 3)
        self.neighbor_edge = neighbor_edge.reshape(m, 3)
        self.n_nonmanifold_edges = int(np.count_nonzero(start & (cnt > 2)))

    def _build_frames(self) -> None:
        P = self.V[self.F]  # (m, 3, 3)
        e = np.stack([P[:, 2] - P[:, 1], P[:, 0] - P[:, 2], P[:, 1] - P[:, 0]], axis=1)
        cr = np.cross(e[:, 2], -e[:, 1])  # (p1 - p0) x (p2 - p0)
        dbl = np.linalg.norm(cr, axis=1)
        if np.any(dbl <= 1e-300):
            bad = int(np.flatnonzero(dbl <= 1e-300)[0])
            raise ClutchError(f"mesh has a degenerate (zero-area) face, e.g. face {bad}")
        self.area = 0.5 * dbl
        self.normal = cr / dbl[:, None]
        inward = np.cross(self.normal[:, None, :], e)  # n x edge: in-plane, perpendicular
        inward /= np.linalg.norm(inward, axis=2, keepdims=True)
        # make it point towards the opposite vertex
        s = np.einsum("mij,mij->mi", inward, P - P[:, [1, 2, 0]])
        inward *= np.where(s < 0, -1.0, 1.0)[:, :, None]
        self.inward = inward
        elen = np.linalg.norm(e, axis=2)
        self.grad = inward * (elen / dbl[:, None])[:, :, None]  # 1 / height

    # ------------------------------------------------------------------ closest point
    @cached_property
    def _centroid_tree(self) -> cKDTree:
        return cKDTree(self.V[self.F].mean(axis=1))

    @cached_property
    def _face_radius(self) -> float:
        P = self.V[self.F]
        return float(np.linalg.norm(P - P.mean(axis=1, keepdims=True), axis=2).max())

    def _closest_on_faces(self, faces: np.ndarray, p: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Closest points to ``p`` (3,) on each of ``faces`` (k,): points (k, 3), distances (k,).

        Inside the triangle: the projection onto its plane; otherwise the closest point of
        its three edges (segment projections, stable for sliver triangles too)."""
        P = self.V[self.F[faces]]  # (k, 3, 3)
        n = self.normal[faces]
        q = p - np.einsum("kx,kx->k", p - P[:, 0], n)[:, None] * n
        b = np.einsum("kix,kx->ki", self.grad[faces], q - P[:, 0])
        b[:, 0] = 1.0 - b[:, 1] - b[:, 2]
        inside = b.min(axis=1) >= 0.0
        A, B = P, P[:, [1, 2, 0]]
        AB = B - A
        t = np.einsum("kex,kex->ke", p - A, AB) / np.einsum("kex,kex->ke", AB, AB)
        E = A + np.clip(t, 0.0, 1.0)[:, :, None] * AB  # (k, 3 edges, 3)
        de = np.linalg.norm(E - p, axis=2)
        best = np.argmin(de, axis=1)
        cp = np.where(inside[:, None], q, E[np.arange(len(faces)), best])
        return cp, np.linalg.norm(cp - p, axis=1)

    def closest_point(self, point: np.ndarray) -> SurfaceHit:
        """Exact closest point of the surface to ``point`` ((3,) metres)."""
        p = np.asarray(point, dtype=np.float64).reshape(3)
        _, f0 = self._centroid_tree.query(p)
        _, d0 = self._closest_on_faces(np.array([f0]), p)
        cand = self._centroid_tree.query_ball_point(p, float(d0[0]) + self._face_radius + 1e-12)
        cand = np.asarray(cand if len(cand) else [f0], dtype=np.int64)
        cp, dist = self._closest_on_faces(cand, p)
        k = int(np.argmin(dist))
        face = int(cand[k])
        return SurfaceHit(face, self.barycentric(face, cp[k]), cp[k], float(dist[k]))

    def barycentric(self, face: int, point: np.ndarray) -> np.ndarray:
        """(3,) barycentric coordinates of the projection of ``point`` (3,) onto ``face``'s
        plane, clipped to the triangle and renormalised."""
        P = self.V[self.F[face]]
        b = self.grad[face] @ (np.asarray(point, dtype=np.float64) - P[0])
        b[0] = 1.0 - b[1] - b[2]
        b = np.clip(b, 0.0, None)
        return b / b.sum()

    def position(self, face: int, bary: np.ndarray) -> np.ndarray:
        """(3,) point with barycentric coordinates ``bary`` (3,) in ``face``."""
        return np.asarray(bary, dtype=np.float64) @ self.V[self.F[face]]
