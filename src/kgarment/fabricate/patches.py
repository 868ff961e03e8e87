"""Patches: the edge-connected pieces of reinforcement as their own meshes, and seams.

A :class:`PatchMesh` is a piece of the garment's rest surface with its own vertex numbering.
Its vertices are copies of garment vertices: a garment vertex where the piece only touches
itself at a corner (a bowtie), or that lies on a seam we cut, gets one copy per side, so the
patch is a 2-manifold that can be flattened. Seams are paths of garment vertices; cutting
along them either opens a hole to the outer boundary (the patch stays in one piece) or
separates the patch into pieces.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components, dijkstra

from kgarment.garment.topology import boundary_loops, face_adjacency, triangle_areas


@dataclass(frozen=True)
class PatchMesh:
    """A piece of the garment surface as a manifold mesh of its own.

    vertices : (n, 3) float64, rest positions in metres.
    faces : (f, 3) int64, indices into ``vertices`` (garment orientation).
    garment_vertex : (n,) int64, the garment vertex each local vertex copies.
    garment_face : (f,) int64, the garment face of each local face.
    """

    vertices: np.ndarray
    faces: np.ndarray
    garment_vertex: np.ndarray
    garment_face: np.ndarray

    @property
    def n_faces(self) -> int:
        return len(self.faces)

    def face_areas(self) -> np.ndarray:
        """(f,) rest triangle areas, m^2."""
        return triangle_areas(self.vertices, self.faces)

    def area(self) -> float:
        return float(self.face_areas().sum())

    def loops(self) -> list[np.ndarray]:
        """Boundary loops (local vertex ids, in order), the longest (outer) one first."""
        loops = boundary_loops(self.faces)
        return sorted(loops, key=lambda lp: -_loop_length(self.vertices, lp))

    def edges(self) -> np.ndarray:
        """(e, 2) unique undirected local edges."""
        s = np.sort(np.stack([self.faces, np.roll(self.faces, -1, axis=1)], -1).reshape(-1, 2), axis=1)
        return np.unique(s, axis=0)


def _loop_length(V: np.ndarray, loop: np.ndarray) -> float:
    return float(np.linalg.norm(V[np.roll(loop, -1)] - V[loop], axis=1).sum())


def _edge_key(a: np.ndarray, b: np.ndarray, n: int) -> np.ndarray:
    return np.minimum(a, b).astype(np.int64) * n + np.maximum(a, b)


def split_vertices(faces: np.ndarray, n_vertices: int, cut_edges: np.ndarray | None = None):
    """Give every fan of faces around a vertex its own copy of the vertex.

    faces : (f, 3) int, a consistently oriented face set (edges shared by at most two faces).
    cut_edges : (c, 2) int vertex pairs that count as boundary even where two faces meet.
    Two faces at a vertex belong to one fan when they share an edge at that vertex that is
    not cut. Returns (new faces (f, 3) int64, source (n', ) int64 original vertex of each copy).
    """
    faces = np.asarray(faces, dtype=np.int64)
    f = len(faces)
    corner = np.arange(3 * f).reshape(f, 3)  # node id of (face, corner)
    a = faces.reshape(-1)
    b = np.roll(faces, -1, axis=1).reshape(-1)
    ca = corner.reshape(-1)
    cb = np.roll(corner, -1, axis=1).reshape(-1)
    key = _edge_key(a, b, n_vertices)
    if cut_edges is not None and len(cut_edges):
        ce = np.asarray(cut_edges, dtype=np.int64).reshape(-1, 2)
        blocked = np.isin(key, _edge_key(ce[:, 0], ce[:, 1], n_vertices))
    else:
        blocked = np.zeros(len(key), bool)
    order = np.argsort(key, kind="stable")
    ks = key[order]
    pair = np.flatnonzero(ks[1:] == ks[:-1])  # consecutive half-edges of one edge
    i, j = order[pair], order[pair + 1]
    keep = ~blocked[i]
    i, j = i[keep], j[keep]
    # half-edge i = (a_i, b_i) and its twin j = (b_i, a_i): join the corners at each end
    rows = np.concatenate([ca[i], cb[i]])
    cols = np.concatenate([cb[j], ca[j]])
    g = sp.coo_matrix((np.ones(len(rows)), (rows, cols)), shape=(3 * f, 3 * f))
    _, label = connected_components(g, directed=False)
    uniq, new_id = np.unique(label, return_inverse=True)
    source = np.zeros(len(uniq), np.int64)
    source[new_id] = a
    return new_id.reshape(f, 3).astype(np.int64), source


def patch_mesh(garment_vertices: np.ndarray, garment_faces: np.ndarray, face_ids: np.ndarray,
               cut_edges: np.ndarray | None = None) -> PatchMesh:
    """The :class:`PatchMesh` of garment faces ``face_ids`` (k,), split at bowties and cuts.

    garment_vertices : (n, 3) rest positions, metres; garment_faces : (m, 3);
    cut_edges : (c, 2) garment vertex pairs to cut open.
    """
    face_ids = np.asarray(face_ids, dtype=np.int64)
    F, src = split_vertices(garment_faces[face_ids], len(garment_vertices), cut_edges)
    return PatchMesh(garment_vertices[src], F, src, face_ids)


def sub_patch(p: PatchMesh, local_faces: np.ndarray) -> PatchMesh:
    """The faces ``local_faces`` (k,) of patch ``p`` as a patch of their own."""
    local_faces = np.asarray(local_faces, dtype=np.int64)
    used, F = np.unique(p.faces[local_faces], return_inverse=True)
    F, src = split_vertices(F.reshape(-1, 3), len(used))
    used = used[src]
    return PatchMesh(p.vertices[used], F, p.garment_vertex[used], p.garment_face[local_faces])


def split_patches(garment_vertices: np.ndarray, garment_faces: np.ndarray, solid: np.ndarray,
                  adjacency: sp.spmatrix | None = None) -> list[PatchMesh]:
    """Edge-connected components of the reinforced faces ``solid`` (m,) bool, largest first."""
    idx = np.flatnonzero(solid)
    if not len(idx):
        return []
    adj = face_adjacency(garment_faces) if adjacency is None else adjacency
    _, lab = connected_components(adj[idx][:, idx], directed=False)
    parts = [idx[lab == k] for k in range(lab.max() + 1)]
    out = [patch_mesh(garment_vertices, garment_faces, ids) for ids in parts]
    return sorted(out, key=lambda p: -p.area())


def _interior_graph(p: PatchMesh, banned: np.ndarray | None = None, sinks: np.ndarray | None = None) -> sp.csr_matrix:
    """Weighted graph (n, n) of the edges shared by two faces (3D lengths, metres), without
    the edges at ``banned`` vertices and the edges leaving ``sinks`` (n,) bool vertices."""
    s = np.stack([p.faces, np.roll(p.faces, -1, axis=1)], -1).reshape(-1, 2)
    srt = np.sort(s, axis=1)
    e, cnt = np.unique(srt, axis=0, return_counts=True)
    e = e[cnt == 2]
    if banned is not None and len(banned):
        bad = np.zeros(len(p.vertices), bool)
        bad[banned] = True
        e = e[~(bad[e[:, 0]] | bad[e[:, 1]])]
    w = np.linalg.norm(p.vertices[e[:, 0]] - p.vertices[e[:, 1]], axis=1) + 1e-12
    n = len(p.vertices)
    r, c, w = np.r_[e[:, 0], e[:, 1]], np.r_[e[:, 1], e[:, 0]], np.r_[w, w]
    if sinks is not None:
        keep = ~sinks[r]
        r, c, w = r[keep], c[keep], w[keep]
    return sp.coo_matrix((w, (r, c)), shape=(n, n)).tocsr()


def _path_to(pred: np.ndarray, target: int) -> list[int]:
    path = [int(target)]
    while pred[path[-1]] >= 0:
        path.append(int(pred[path[-1]]))
    return path[::-1]


def hole_seams(p: PatchMesh) -> list[np.ndarray]:
    """Shortest paths (local vertex ids) joining every inner boundary loop to the outer one:
    cutting along them leaves a patch with a single boundary (a disk)."""
    loops = p.loops()
    if len(loops) < 2:
        return []
    g = _interior_graph(p)
    reached = {int(v) for v in loops[0]}
    seams = []
    for hole in loops[1:]:
        dist, pred, _ = dijkstra(g, directed=False, indices=hole, return_predecessors=True, min_only=True)
        targets = np.array(sorted(reached))
        k = int(targets[np.argmin(dist[targets])])
        if not np.isfinite(dist[k]):
            continue
        seams.append(np.array(_path_to(pred, k), dtype=np.int64))
        reached.update(int(v) for v in hole)
    return seams


def _line_exits(uv: np.ndarray, loops: list[np.ndarray], point: np.ndarray, direction: np.ndarray):
    """The boundary vertices where the 2D line ``point + t direction`` leaves the patch
    nearest to ``point`` on either side (t < 0, t > 0), or None."""
    best = {-1: (np.inf, None), 1: (np.inf, None)}
    nrm = np.array([-direction[1], direction[0]])
    for lp in loops:
        a, b = uv[lp], uv[np.roll(lp, -1)]
        da, db = (a - point) @ nrm, (b - point) @ nrm
        for k in np.flatnonzero((da <= 0) != (db <= 0)):
            s = da[k] / (da[k] - db[k])
            x = a[k] + s * (b[k] - a[k])
            t = float((x - point) @ direction)
            side = 1 if t > 0 else -1
            if abs(t) < best[side][0]:
                best[side] = (abs(t), int(lp[k] if s < 0.5 else np.roll(lp, -1)[k]))
    return best[-1][1], best[1][1]


def across_direction(uv: np.ndarray) -> np.ndarray:
    """(2,) unit direction at right angles to the longest principal axis of points (n, 2)."""
    _, _, vt = np.linalg.svd(uv - uv.mean(axis=0), full_matrices=False)
    return np.array([-vt[0, 1], vt[0, 0]])


def through_seam(p: PatchMesh, uv: np.ndarray, point: np.ndarray, direction: np.ndarray | None = None):
    """A short path (local vertex ids, (k,) int64) from boundary to boundary along the 2D
    line through ``point`` (2,) in ``direction`` (2,) (default: across the patch's narrow
    way) of the flattening ``uv`` (n, 2), following mesh edges. None when there is none."""
    loops = p.loops()
    d = across_direction(uv) if direction is None else np.asarray(direction, float) / np.linalg.norm(direction)
    b0, b1 = _line_exits(uv, loops, np.asarray(point, float), d)
    if b0 is None or b1 is None or b0 == b1:
        return None
    sinks = np.zeros(len(p.vertices), bool)
    sinks[np.concatenate(loops)] = True
    sinks[b0] = False  # a seam ends where it first meets the boundary again
    dist, pred = dijkstra(_interior_graph(p, sinks=sinks), directed=True, indices=b0, return_predecessors=True)
    if not np.isfinite(dist[b1]):
        return None
    return np.array(_path_to(pred, b1), dtype=np.int64)


def path_edges(path: np.ndarray) -> np.ndarray:
    """(k-1, 2) consecutive vertex pairs of a path (k,)."""
    path = np.asarray(path, dtype=np.int64)
    return np.stack([path[:-1], path[1:]], axis=1)


def cut_patch(p: PatchMesh, seams: list[np.ndarray]) -> list[PatchMesh]:
    """Cut ``p`` along ``seams`` (local vertex paths): the resulting pieces (one or more)."""
    if not seams:
        return [p]
    ce = np.concatenate([path_edges(s) for s in seams])
    F, src = split_vertices(p.faces, len(p.vertices), ce)
    cut = PatchMesh(p.vertices[src], F, p.garment_vertex[src], p.garment_face)
    adj = face_adjacency(cut.faces)
    n, lab = connected_components(adj, directed=False)
    if n == 1:
        return [cut]
    return [sub_patch(cut, np.flatnonzero(lab == k)) for k in range(n)]
