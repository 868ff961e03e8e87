"""Triangle-mesh topology helpers: subdivision with its embedding, manifold checks, loops."""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from kgarment.errors import KgarmentError


def triangle_areas(vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """(m,) areas in m^2 of the triangles faces (m, 3) on vertices (n, 3)."""
    tri = np.asarray(vertices)[np.asarray(faces)]
    return 0.5 * np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1)


def unique_edges(faces: np.ndarray):
    """Unique undirected edges (e, 2) and, for each face side (m, 3), its edge id.

    faces : (m, 3) int. Side k of a face is the edge (f[k], f[(k+1) % 3]).
    """
    sides = np.stack([faces, np.roll(faces, -1, axis=1)], axis=-1).reshape(-1, 2)
    edges, inverse = np.unique(np.sort(sides, axis=1), axis=0, return_inverse=True)
    return edges, inverse.reshape(-1, 3)


def midpoint_subdivide(faces: np.ndarray, n_vertices: int):
    """One level of midpoint subdivision (no smoothing).

    faces : (m, 3) int. Returns (new faces (4m, 3), S) where S is a sparse (n', n) matrix
    with new_vertices = S @ old_vertices (old vertices first, then edge midpoints).
    Orientation is preserved.
    """
    edges, side = unique_edges(faces)
    mid = n_vertices + side  # (m, 3): midpoint of side k = edge (f[k], f[k+1])
    a, b, c = faces.T
    ab, bc, ca = mid.T
    new = np.concatenate([np.stack(t, axis=1) for t in ((a, ab, ca), (b, bc, ab), (c, ca, bc), (ab, bc, ca))])
    ne = len(edges)
    rows = np.concatenate([np.arange(n_vertices), np.repeat(n_vertices + np.arange(ne), 2)])
    cols = np.concatenate([np.arange(n_vertices), edges.reshape(-1)])
    vals = np.concatenate([np.ones(n_vertices), np.full(2 * ne, 0.5)])
    S = sp.csr_matrix((vals, (rows, cols)), shape=(n_vertices + ne, n_vertices))
    return new.astype(np.int64), S


def face_adjacency(faces: np.ndarray) -> sp.csr_matrix:
    """(m, m) sparse symmetric matrix, 1 where two faces share an edge."""
    edges, side = unique_edges(faces)
    f = np.repeat(np.arange(len(faces)), 3)
    e = side.reshape(-1)
    inc = sp.csr_matrix((np.ones(len(e)), (e, f)), shape=(len(edges), len(faces)))
    adj = (inc.T @ inc).tocsr()
    adj.setdiag(0)
    adj.eliminate_zeros()
    adj.data[:] = 1.0
    return adj


def boundary_edges(faces: np.ndarray) -> np.ndarray:
    """Directed boundary edges (b, 2) in face orientation (edges used by exactly one face)."""
    sides = np.stack([faces, np.roll(faces, -1, axis=1)], axis=-1).reshape(-1, 2)
    _, inv, counts = np.unique(np.sort(sides, axis=1), axis=0, return_inverse=True, return_counts=True)
    return sides[counts[inv.reshape(-1)] == 1]


def boundary_loops(faces: np.ndarray) -> list[np.ndarray]:
    """Closed boundary loops, each an array of vertex indices in order."""
    be = boundary_edges(faces)
    nxt = {}
    for a, b in be:
        nxt.setdefault(int(a), []).append(int(b))
    loops, seen = [], set()
    for start in list(nxt):
        if start in seen:
            continue
        loop, v = [], start
        while v not in seen:
            seen.add(v)
            loop.append(v)
            v = nxt[v][0]
        loops.append(np.array(loop, dtype=np.int64))
    return loops


def manifold_problems(vertices: np.ndarray, faces: np.ndarray, min_area: float = 1e-10) -> list[str]:
    """What keeps (vertices (n, 3), faces (m, 3)) from being a 2-manifold with boundary.

    Checks: edges shared by more than two faces, inconsistent orientation, vertices where
    two boundary fans meet (bowties), triangles with area under ``min_area`` m^2, unused
    vertices. Returns a list of human-readable problems (empty when the mesh is fine).
    """
    problems = []
    sides = np.stack([faces, np.roll(faces, -1, axis=1)], axis=-1).reshape(-1, 2)
    _, inv, counts = np.unique(np.sort(sides, axis=1), axis=0, return_inverse=True, return_counts=True)
    if (counts > 2).any():
        problems.append(f"{int((counts > 2).sum())} edges are shared by more than two triangles")
    _, dcounts = np.unique(sides, axis=0, return_counts=True)
    if (dcounts > 1).any():
        problems.append(f"{int((dcounts > 1).sum())} edges have inconsistent triangle orientation")
    be = sides[counts[inv] == 1]
    nb = np.bincount(be.reshape(-1), minlength=len(vertices))
    if (nb > 2).any():
        problems.append(f"{int((nb > 2).sum())} vertices join two boundary fans (bowtie)")
    area = triangle_areas(vertices, faces)
    if (area < min_area).any():
        problems.append(f"{int((area < min_area).sum())} degenerate triangles (area < {min_area:g} m^2)")
    used = np.zeros(len(vertices), bool)
    used[faces.reshape(-1)] = True
    if not used.all():
        problems.append(f"{int((~used).sum())} vertices are not used by any triangle")
    return problems


def check_manifold(vertices: np.ndarray, faces: np.ndarray, what: str = "garment") -> None:
    """Raise KgarmentError naming every problem if the mesh is not a clean 2-manifold."""
    problems = manifold_problems(vertices, faces)
    if problems:
        raise KgarmentError(f"{what} is not a 2-manifold with boundary: {'; '.join(problems)}")


def clean_face_mask(faces: np.ndarray, mask: np.ndarray, iterations: int = 8) -> np.ndarray:
    """Tidy a face selection on a manifold mesh: fill pinholes and notches, drop spikes,
    remove bowtie vertices and keep the largest edge-connected component.

    faces : (m, 3) int; mask : (m,) bool. Returns the cleaned (m,) bool mask.
    """
    from scipy.sparse.csgraph import connected_components

    adj = face_adjacency(faces)
    mask = mask.copy()
    for _ in range(iterations):
        k = adj @ mask.astype(float)
        new = (mask | (k >= 2)) & ~(mask & (k <= 1) & (adj.getnnz(axis=1) >= 3))
        if np.array_equal(new, mask):
            break
        mask = new
    for _ in range(iterations):
        sel = faces[mask]
        be = boundary_edges(sel)
        nb = np.bincount(be.reshape(-1), minlength=faces.max() + 1)
        bow = nb > 2
        if not bow.any():
            break
        mask &= ~bow[faces].any(axis=1)
    idx = np.flatnonzero(mask)
    if idx.size == 0:  # nothing survived the tidying
        return mask
    sub = adj[idx][:, idx]
    _, labels = connected_components(sub, directed=False)
    big = np.argmax(np.bincount(labels))
    out = np.zeros_like(mask)
    out[idx[labels == big]] = True
    return out
