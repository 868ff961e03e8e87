"""Clean-up of a design on the garment's face graph, as the paper's authors did by hand.

Steps (each one optional through its threshold):

1. fill holes: soft regions enclosed by reinforcement (not reaching the garment's edge)
   smaller than ``max_hole_area`` become reinforced, unless a clutch lies over them (the
   optimiser leaves soft cloth under a clutch on purpose);
2. minimum feature width: a morphological opening (erosion, then dilation) with a ball of
   diameter ``min_width`` on the face graph removes necks and spikes thinner than that
   (the garment's edge counts as soft, so spikes along it go too), except near clutch ends;
3. islands: reinforced components smaller than ``min_island_area`` are removed unless they
   touch a clutch end (hold a face under a clutch anchor, or a neighbour of one) or an
   attachment-ring face.

Protected faces are never changed from reinforced to soft.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components

from kgarment.errors import KgarmentError
from kgarment.garment.topology import boundary_edges, face_adjacency, triangle_areas

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class CleanupOptions:
    """Thresholds in SI units; 0 switches a step off.

    min_island_area : m^2, smaller islands of reinforcement are removed.
    max_hole_area : m^2, smaller enclosed soft holes are filled.
    min_width : m, the diameter of the opening's structuring ball.
    """

    min_island_area: float = 4e-4
    max_hole_area: float = 4e-4
    min_width: float = 0.01

    def __post_init__(self):
        for k in ("min_island_area", "max_hole_area", "min_width"):
            v = getattr(self, k)
            if not (np.isfinite(v) and v >= 0):
                raise KgarmentError(f"clean-up: {k} = {v!r} must be >= 0")


@dataclass(frozen=True)
class CleanupResult:
    """What the clean-up did.

    before, after : (m,) bool, reinforced faces.
    holes_filled, islands_removed : counts; faces_opened : faces removed by the opening.
    area_before, area_after : reinforced area, m^2.
    protected : (m,) bool, faces never removed (clutch ends and their neighbours).
    """

    before: np.ndarray
    after: np.ndarray
    holes_filled: int
    islands_removed: int
    faces_opened: int
    area_before: float
    area_after: float
    protected: np.ndarray

    @property
    def changed_faces(self) -> int:
        return int((self.before != self.after).sum())


def clutch_end_faces(strips, n_faces: int) -> np.ndarray:
    """(m,) bool: garment faces under the 6 anchor vertices of every clutch."""
    out = np.zeros(n_faces, bool)
    for c in strips:
        out[np.asarray(c.bind_face)[np.asarray(c.anchors)]] = True
    return out


def clutch_faces(strips, n_faces: int) -> np.ndarray:
    """(m,) bool: garment faces under any vertex of any clutch."""
    out = np.zeros(n_faces, bool)
    for c in strips:
        out[np.asarray(c.bind_face)] = True
    return out


def _components(adj: sp.csr_matrix, mask: np.ndarray) -> list[np.ndarray]:
    idx = np.flatnonzero(mask)
    if not len(idx):
        return []
    _, lab = connected_components(adj[idx][:, idx], directed=False)
    order = np.argsort(lab, kind="stable")
    return np.split(idx[order], np.flatnonzero(np.diff(lab[order])) + 1)


def remove_islands(adj, solid, areas, min_area, keep) -> tuple[np.ndarray, int]:
    """Drop reinforced components of ``solid`` (m,) bool smaller than ``min_area`` m^2 that
    hold no ``keep`` (m,) bool face. adj : (m, m) face adjacency; areas : (m,) m^2.
    Returns (new solid (m,) bool, number removed)."""
    out, n = solid.copy(), 0
    for comp in _components(adj, solid):
        if areas[comp].sum() < min_area and not keep[comp].any():
            out[comp] = False
            n += 1
    return out, n


def fill_holes(adj, faces, solid, areas, max_area, avoid) -> tuple[np.ndarray, int]:
    """Reinforce the soft components of ``solid`` (m,) bool that do not reach the garment
    boundary, are smaller than ``max_area`` m^2 and hold no ``avoid`` (m,) bool face.
    adj : (m, m) face adjacency; faces : (m, 3); areas : (m,) m^2.
    Returns (new solid (m,) bool, number filled)."""
    sides = np.sort(np.stack([faces, np.roll(faces, -1, axis=1)], -1).reshape(-1, 2), axis=1)
    _, inv, cnt = np.unique(sides, axis=0, return_inverse=True, return_counts=True)
    on_edge = (cnt[inv.reshape(-1)] == 1).reshape(-1, 3).any(axis=1)
    out, n = solid.copy(), 0
    for comp in _components(adj, ~solid):
        if on_edge[comp].any() or avoid[comp].any() or areas[comp].sum() >= max_area:
            continue
        out[comp] = True
        n += 1
    return out, n


def ball_matrix(vertices: np.ndarray, faces: np.ndarray, radius: float, adj=None) -> sp.csr_matrix:
    """(m, m) bool sparse structuring ball: face j is in the ball of face i when their
    centroids are closer than ``radius`` plus the mean of their inradii (so the ball reaches
    the faces that come within ``radius`` of the centroid, at any mesh resolution), and a few
    steps apart on the face graph (so it does not jump across gaps between body parts).

    vertices : (n, 3) metres; faces : (m, 3); radius : metres."""
    adj = face_adjacency(faces) if adj is None else adj
    m = len(faces)
    t = vertices[faces]
    cen = t.mean(axis=1)
    area = triangle_areas(vertices, faces)
    inradius = 2 * area / np.linalg.norm(t - np.roll(t, -1, axis=1), axis=2).sum(axis=1).clip(1e-300)
    i, j = adj.nonzero()
    step = float(np.median(np.linalg.norm(cen[i] - cen[j], axis=1))) if len(i) else radius
    reach_r = radius + float(inradius.max())
    hops = int(min(12, max(1, np.ceil(1.5 * reach_r / max(step, 1e-9)))))
    reach = sp.identity(m, format="csr", dtype=np.int8)
    A = (adj + sp.identity(m, format="csr")).astype(bool).astype(np.int8)
    for _ in range(hops):
        reach = (reach @ A).astype(bool).astype(np.int8)
    reach = reach.tocoo()
    d = np.linalg.norm(cen[reach.row] - cen[reach.col], axis=1)
    ok = d <= radius + 0.5 * (inradius[reach.row] + inradius[reach.col])
    return sp.csr_matrix((np.ones(ok.sum(), bool), (reach.row[ok], reach.col[ok])), shape=(m, m))


def near_boundary(vertices: np.ndarray, faces: np.ndarray, radius: float) -> np.ndarray:
    """(m,) bool: faces whose centroid comes within ``radius`` (plus half its inradius) of
    the garment's boundary (sampled along every boundary edge). vertices (n, 3), faces (m, 3)."""
    from scipy.spatial import cKDTree

    be = boundary_edges(faces)
    if not len(be):
        return np.zeros(len(faces), bool)
    t = np.linspace(0.0, 1.0, 5)[:, None, None]
    pts = ((1 - t) * vertices[be[:, 0]] + t * vertices[be[:, 1]]).reshape(-1, 3)
    tri = vertices[faces]
    area = triangle_areas(vertices, faces)
    inradius = 2 * area / np.linalg.norm(tri - np.roll(tri, -1, axis=1), axis=2).sum(axis=1).clip(1e-300)
    d, _ = cKDTree(pts).query(tri.mean(axis=1))
    return d < radius + 0.5 * inradius


def opening(ball: sp.csr_matrix, solid: np.ndarray, edge: np.ndarray | None = None) -> np.ndarray:
    """Morphological opening of ``solid`` (m,) bool with the structuring ``ball`` (m, m);
    ``edge`` (m,) bool marks faces whose ball reaches past the garment's edge (counted as
    soft, so spikes along the edge go too)."""
    eroded = (ball @ (~solid).astype(np.int32)) == 0
    if edge is not None:
        eroded &= ~edge
    return ((ball @ eroded.astype(np.int32)) > 0) & solid


def clean_design(faces: np.ndarray, vertices: np.ndarray, solid: np.ndarray, strips=(),
                 attached: np.ndarray | None = None, options: CleanupOptions = CleanupOptions()) -> CleanupResult:
    """Clean a design.

    faces : (m, 3) garment faces; vertices : (n, 3) rest positions, metres;
    solid : (m,) bool or float (> 0.5 = reinforced); strips : the clutches (ClutchStrip);
    attached : (m,) bool attachment-ring faces (islands touching them are kept).
    """
    faces = np.asarray(faces)
    solid0 = np.asarray(solid) > 0.5
    if solid0.shape != (len(faces),):
        raise KgarmentError(f"the design has {solid0.size} faces, the garment {len(faces)}")
    areas = triangle_areas(vertices, faces)
    adj = face_adjacency(faces)
    ends = clutch_end_faces(strips, len(faces))
    under = clutch_faces(strips, len(faces))
    ring = np.zeros(len(faces), bool) if attached is None else np.asarray(attached, bool)
    # near a clutch end: the end faces and their edge neighbours
    protected = ends | ((adj @ ends.astype(np.int32)) > 0)
    s = solid0.copy()
    holes = 0
    if options.max_hole_area > 0:
        s, holes = fill_holes(adj, faces, s, areas, options.max_hole_area, under)
    opened = 0
    if options.min_width > 0:
        ball = ball_matrix(vertices, faces, 0.5 * options.min_width, adj)
        edge = near_boundary(vertices, faces, 0.5 * options.min_width)
        o = opening(ball, s, edge) | (s & (protected | ring))
        opened = int((s & ~o).sum())
        s = o
    islands = 0
    if options.min_island_area > 0:
        s, islands = remove_islands(adj, s, areas, options.min_island_area, protected | ring)
    log.debug("clean-up: %d holes filled, %d faces opened, %d islands removed; reinforced %.1f -> %.1f cm^2",
             holes, opened, islands, 1e4 * areas[solid0].sum(), 1e4 * areas[s].sum())
    return CleanupResult(solid0, s, holes, islands, opened, float(areas[solid0].sum()), float(areas[s].sum()),
                         protected)
