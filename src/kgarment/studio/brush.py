"""Picking and brushing on the garment: ray casts and brush footprints.

A click in the page arrives as a ray (origin, direction) in world coordinates. It is
intersected with the garment *as displayed* (any pose); the hit is a face and barycentric
coordinates, which name the same material point on the rest garment. Brush footprints are
measured on the rest garment, so a stroke covers the same cloth in every pose.

A brush footprint of radius r around a point p on face f: the faces whose centroid lies
within r of p (Euclidean, rest coordinates) *and* that are joined to f by a chain of
edge-adjacent faces at most 2 r long (centroid to centroid). The second condition keeps
the brush on the surface it was put on: it does not jump across the gap between an arm
and the torso, or through a sleeve to its far side.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import dijkstra

from kgarment.clutch.landmarks import ray_triangles
from kgarment.garment.topology import face_adjacency, triangle_areas

RAY_EPS = 1e-12


@dataclass(frozen=True)
class Hit:
    """Where a ray meets the mesh.

    face : int; bary : (3,) float64 barycentric coordinates in ``face``;
    point : (3,) float64 hit point, metres (in the coordinates of the mesh that was hit);
    distance : float, metres along the (unit) ray.
    """

    face: int
    bary: np.ndarray
    point: np.ndarray
    distance: float


def ray_hit(origin, direction, vertices: np.ndarray, faces: np.ndarray) -> Hit | None:
    """The first hit of a ray on a triangle mesh (both sides count), or None.

    origin, direction : (3,) metres (direction need not be unit);
    vertices : (n, 3) metres; faces : (m, 3) int.
    """
    o = np.asarray(origin, dtype=np.float64).reshape(3)
    d = np.asarray(direction, dtype=np.float64).reshape(3)
    nd = np.linalg.norm(d)
    if not np.isfinite(nd) or nd == 0.0:
        return None
    d = d / nd
    tri = np.asarray(vertices, dtype=np.float64)[np.asarray(faces)]
    t, u, v, good = ray_triangles(o, d, tri, eps=RAY_EPS, tol=1e-9)
    if not good.any():
        return None
    idx = np.flatnonzero(good)
    k = int(idx[np.argmin(t[idx])])
    bary = np.clip(np.array([1.0 - u[k] - v[k], u[k], v[k]]), 0.0, None)
    bary /= bary.sum()
    return Hit(k, bary, o + t[k] * d, float(t[k]))


def camera_ray(camera_position, pointer_position) -> tuple[np.ndarray, np.ndarray]:
    """(origin (3,), unit direction (3,)) of the ray from the camera through a point
    under the pointer (e.g. a drag event's point on the camera-aligned drag plane)."""
    o = np.asarray(camera_position, dtype=np.float64).reshape(3)
    d = np.asarray(pointer_position, dtype=np.float64).reshape(3) - o
    return o, d / max(float(np.linalg.norm(d)), 1e-300)


class FaceGraph:
    """Face adjacency of a rest mesh with centroid-to-centroid edge lengths.

    vertices : (n, 3) rest positions, metres; faces : (m, 3).
    Attributes: centroids (m, 3), areas (m,) m^2, graph (m, m) sparse CSR (metres).
    Built once per garment; brush queries reuse it.
    """

    def __init__(self, vertices: np.ndarray, faces: np.ndarray):
        V = np.asarray(vertices, dtype=np.float64)
        F = np.asarray(faces, dtype=np.int64)
        tri = V[F]
        self.centroids = tri.mean(axis=1)
        self.areas = triangle_areas(V, F)
        adj = face_adjacency(F).tocoo()
        w = np.linalg.norm(self.centroids[adj.row] - self.centroids[adj.col], axis=1)
        self.graph = sp.csr_matrix((np.maximum(w, 1e-12), (adj.row, adj.col)), shape=(len(F), len(F)))

    @property
    def n_faces(self) -> int:
        return len(self.centroids)

    def rest_point(self, vertices: np.ndarray, faces: np.ndarray, face: int, bary) -> np.ndarray:
        """(3,) rest position of barycentric ``bary`` (3,) in ``face`` of the rest mesh."""
        return np.asarray(bary, dtype=np.float64) @ np.asarray(vertices)[np.asarray(faces)[face]]


def brush_faces(graph: FaceGraph, face: int, point, radius: float, mode: str = "surface") -> np.ndarray:
    """(k,) int64 sorted faces under a brush of ``radius`` metres at ``point`` (3,) (rest
    coordinates) on ``face``.

    mode : "surface" (default: Euclidean disc, restricted to faces joined to ``face`` by a
    surface path of at most 2 radius, see the module docstring) or "euclidean" (every face
    whose centroid is within the radius, wherever it is). The hit face is always included.
    """
    if not 0 <= face < graph.n_faces:
        raise ValueError(f"face {face} is not a face of the garment (0..{graph.n_faces - 1})")
    if radius < 0 or not np.isfinite(radius):
        raise ValueError(f"brush radius must be >= 0 metres, got {radius!r}")
    if mode not in ("surface", "euclidean"):
        raise ValueError(f"brush mode {mode!r}; allowed: surface, euclidean")
    p = np.asarray(point, dtype=np.float64).reshape(3)
    near = np.linalg.norm(graph.centroids - p, axis=1) <= radius
    if mode == "surface" and radius > 0:
        dist = dijkstra(graph.graph, directed=False, indices=int(face), limit=2.0 * radius)
        near &= np.isfinite(dist)
    near[int(face)] = True
    return np.flatnonzero(near)


def stroke_faces(graph: FaceGraph, faces_and_points, radius: float, mode: str = "surface") -> np.ndarray:
    """(k,) int64 sorted union of brush footprints along a stroke of (face, point (3,)) dabs."""
    out = [brush_faces(graph, f, p, radius, mode) for f, p in faces_and_points]
    return np.unique(np.concatenate(out)) if out else np.zeros(0, np.int64)


def apply(mask: np.ndarray, faces: np.ndarray, value: bool) -> tuple[np.ndarray, int]:
    """(new mask (m,) bool, number of faces changed) after setting ``faces`` to ``value``."""
    out = np.asarray(mask, dtype=bool).copy()
    faces = np.asarray(faces, dtype=np.int64)
    changed = int(np.count_nonzero(out[faces] != value))
    out[faces] = value
    return out, changed


def coverage(mask: np.ndarray, areas: np.ndarray) -> float:
    """Area share in [0, 1] of the faces set in ``mask`` (m,) given face areas (m,) m^2."""
    a = np.asarray(areas, dtype=np.float64)
    return float(a[np.asarray(mask, dtype=bool)].sum() / max(a.sum(), 1e-300))
