"""Baseline designs at a given area budget, to compare the optimised designs against.

* :func:`manual_design`: what a designer draws (the paper's participants did): a strip of
  reinforcement from each clutch end to where the body pulls the garment -- an attachment
  ring, a band around a limb opening (the short-sleeve shirt's cuffs) or around a limb that
  nothing else holds (a long sleeve's upper arms, :func:`limb_bands`), or a strip already
  so anchored (another clutch's, when less than half as far) -- along the shortest path over the garment (Dijkstra on
  the face adjacency graph, edge weights = distances between face centroids), the band a
  strip reaches drawn all around the limb, then everything widened evenly (faces in order
  of their surface distance to the strips) until the budget is spent.  A clutch's two ends
  go to two different anchors (where the garment has more than one): a clutch whose ends
  both hang on one attachment ring sits between two points the body does not move apart
  and carries nothing (the shirt's lower V, both ends strapped to the hem, did so until
  2026-11-28), so the second end's strip goes to the nearest *other* anchor, never through
  the first end's.  On the sleeves it is
  the forearm line of the paper (clutch ends to the cuff rings).  (It replaces a "line"
  baseline whose strips went to the nearest attachment *or clutch end*: on the shirt the
  clutch ends are nearest to one another, so its strips joined the clutches in a ring held
  by nothing the body moves, and it stored almost nothing: rho ON 0.00.)
* :func:`line_paths` / :func:`line_design`: strips from each clutch end to the nearest
  attachment face or another clutch's end (the previous baseline; on the shirt the clutch
  ends are nearest to one another, so its strips link the clutches in a ring joined to
  nothing the body moves, and it stores almost nothing).
* :func:`random_design`: a random smooth pattern: Gaussian white noise per face, smoothed
  by ``passes`` applications of the one-ring filter, thresholded so that the reinforced
  area equals the budget; seeded, so reproducible.
* :func:`full_design`: every face reinforced (rho = 1 by the definition of rho).

Budgets are fractions of the garment's rest area; designs are (m,) arrays in {x_min, 1}.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components, dijkstra

from kgarment.constants import X_MIN
from kgarment.garment.topology import face_adjacency, triangle_areas
from kgarment.optimize.beso import one_ring_filter


def _take_budget(order_key: np.ndarray, areas: np.ndarray, budget: float, x_min: float) -> np.ndarray:
    """Reinforce faces in increasing ``order_key`` until their area reaches ``budget`` of
    the total (the face that crosses the budget is included when that lands closer)."""
    order = np.argsort(order_key, kind="stable")
    cum = np.cumsum(areas[order]) / areas.sum()
    k = int(np.searchsorted(cum, budget))
    if k < len(order) and (k == 0 or abs(cum[k] - budget) < abs(cum[k - 1] - budget)):
        k += 1
    design = np.full(len(areas), x_min)
    design[order[:k]] = 1.0
    return design


def dual_graph(vertices: np.ndarray, faces: np.ndarray) -> sp.csr_matrix:
    """(m, m) face adjacency weighted by the distance between centroids (m)."""
    adj = face_adjacency(faces).tocoo()
    c = vertices[faces].mean(axis=1)
    w = np.linalg.norm(c[adj.row] - c[adj.col], axis=1)
    return sp.csr_matrix((np.maximum(w, 1e-12), (adj.row, adj.col)), shape=adj.shape)


STRIP_PREFERENCE = 0.5  # join another clutch's strip when it is nearer than this share of the nearest ring


def manual_design(vertices: np.ndarray, faces: np.ndarray, end_faces, rings, held: np.ndarray, budget: float,
                  x_min: float = X_MIN) -> np.ndarray:
    """The manual baseline (module doc): (m,) in {x_min, 1}.

    end_faces : per clutch, (faces under end A, faces under end B);  rings : per free limb
    opening, the (b,) faces along it (drawn all around the limb when a strip reaches it);
    held : (m,) bool faces the body holds already (attachment rings: reaching one is enough).
    The strips come first in the budget, then the rings they reach, then the widening."""
    graph = dual_graph(vertices, faces)
    anchor = anchor_labels(graph, rings, held)  # (m,) which anchor a face is; -1 none
    rings = [np.unique(np.asarray(r, dtype=int)) for r in rings if len(r)]
    ring_of = np.full(len(faces), -1)
    for k, r in enumerate(rings):
        ring_of[r] = k
    strip = np.zeros(len(faces), bool)
    band = np.zeros(len(faces), bool)
    owner = np.full(len(faces), -1)  # the clutch whose strip drew a face
    leads = np.full(len(faces), -1)  # the anchor a strip face leads to
    reached: dict[int, int] = {}  # clutch -> the anchor its first strip reached
    starts = [(k, np.unique(np.asarray(e, dtype=int))) for k, pair in enumerate(end_faces) for e in pair]
    dist0 = [dijkstra(graph, indices=s, min_only=True)[anchor >= 0].min() if (anchor >= 0).any() else np.inf
             for _, s in starts]
    for i in np.argsort(dist0, kind="stable"):
        k, start = starts[i]
        target = _strip_target(graph, start, anchor, strip & (owner != k), leads, reached.get(k, -1))
        if target is None:
            continue
        f, pred = target
        to = int(anchor[f] if anchor[f] >= 0 else leads[f])
        reached.setdefault(k, to)
        if ring_of[f] >= 0:
            band[rings[ring_of[f]]] = True  # the strip's ring goes all around the limb
        path = [int(x) for x in start]  # the whole end, then the way to the target
        while f >= 0:
            path.append(f)
            f = int(pred[f])
        fresh = np.array([x for x in path if not strip[x]], dtype=int)
        strip[fresh], owner[fresh], leads[fresh] = True, k, to
    if not strip.any():
        return np.full(len(faces), x_min)
    drawn = strip | band
    dist = dijkstra(graph, indices=np.flatnonzero(drawn), min_only=True)
    key = np.where(strip, 0.0, np.where(band, 1.0, 2.0 + np.where(np.isfinite(dist), dist, np.inf)))
    return _take_budget(key, triangle_areas(vertices, faces), budget, x_min)


def anchor_labels(graph: sp.csr_matrix, rings, held: np.ndarray) -> np.ndarray:
    """(m,) int: per face, which anchor it is -- each connected piece of ``held`` (an
    attachment ring) one label, each limb ring of ``rings`` the next ones -- or -1."""
    held = np.asarray(held, bool)
    label = np.full(graph.shape[0], -1)
    n = 0
    if held.any():
        n, lab = connected_components(graph[held][:, held], directed=False)
        label[held] = lab
    for k, r in enumerate(r for r in rings if len(r)):
        label[np.asarray(r, dtype=int)] = n + k
    return label


def _strip_target(graph: sp.csr_matrix, start: np.ndarray, anchor: np.ndarray, others: np.ndarray,
                  leads: np.ndarray, avoid: int):
    """Where a strip from the faces ``start`` goes: (target face, Dijkstra predecessors) or
    None.  Targets: anchor faces (``anchor`` >= 0) and ``others`` (m,) bool, other clutches'
    strips (``leads``: the anchor each leads to), a strip preferred when less than
    STRIP_PREFERENCE as far as the nearest anchor.  Never anchor ``avoid`` (where the same
    clutch's other end went) nor a strip leading to it, and the path does not cross them
    (the first end's own strip included) -- unless nothing else is reachable."""
    for skip in ((avoid,) if avoid >= 0 else ()) + (None,):
        g, banned = graph, np.zeros(len(anchor), bool)
        if skip is not None:  # the avoided anchor's faces and strips out of the graph (the ends kept)
            banned = (anchor == skip) | (leads == skip)
            banned[start] = False
            keep = sp.diags((~banned).astype(float))
            g = (keep @ graph @ keep).tocsr()
            g.eliminate_zeros()
        dist, pred = dijkstra(g, indices=start, min_only=True, return_predecessors=True)[:2]
        ok = np.isfinite(dist) & ~banned
        to_anchor = np.flatnonzero((anchor >= 0) & ok)
        to_strip = np.flatnonzero(others & (anchor < 0) & ok)
        if not len(to_anchor) and not len(to_strip):
            continue
        a = to_anchor[np.argmin(dist[to_anchor])] if len(to_anchor) else None
        b = to_strip[np.argmin(dist[to_strip])] if len(to_strip) else None
        # another clutch's (anchored) strip only when much nearer than the limb or the ring
        f = int(b if a is None or (b is not None and dist[b] < STRIP_PREFERENCE * dist[a]) else a)
        return f, pred
    return None


def anchor_rings(garment, body=None) -> tuple[list[np.ndarray], np.ndarray]:
    """Where the body pulls ``garment``: per free named opening (the short sleeves' cuffs;
    not the neck, an unnamed ``opening``), the (b,) faces along it, then with a rigged
    ``body`` the :func:`limb_bands` of the limbs that hold no anchor; and (m,) bool its
    attached faces (attachment rings)."""
    rings = []
    for name, loop in garment.loops.items():
        along = np.flatnonzero(np.isin(garment.faces, loop).any(axis=1))
        if not name.startswith("opening") and not garment.attached[along].any():
            rings.append(along)
    held = np.asarray(garment.attached, bool)
    if body is not None:
        rings += limb_bands(garment, body, held, rings)
    return rings, held


# Limb segments a designer bands (the upper arms): (the bones covering it, the joint at its
# far end). Anny's names; a rig without them gets no bands.
LIMBS = tuple(((f"upperarm01.{s}", f"upperarm02.{s}"), f"lowerarm01.{s}") for s in "LR")
BAND_WIDTH = 0.05  # m, along the limb
BAND_GAP = np.pi / 3  # rad: a band leaving a wider gap round the limb does not close around it


def limb_bands(garment, body, held: np.ndarray, rings=()) -> list[np.ndarray]:
    """Bands a designer wraps around a limb the garment covers all round but where nothing
    holds it (a long sleeve's upper arm: its cuffs are at the wrists): per segment of
    :data:`LIMBS` whose faces (those whose body face the segment's bones move most) hold no
    attached face and no ring of ``rings``, the (b,) faces of a :data:`BAND_WIDTH` slab
    across its middle (rest pose), when they close around it (no angular gap over
    :data:`BAND_GAP`).  garment : a :class:`~kgarment.garment.Garment` on ``body`` (rigged
    :class:`~kgarment.body.Body`);  held : (m,) bool attached faces;  rings : (b,) face arrays."""
    if not body.rigged:
        return []
    names = list(body.bone_names)
    tri = body.faces[garment.body_face]  # (m, 3) the body face under each garment face
    anchored = np.asarray(held, bool).copy()
    for r in rings:
        anchored[np.asarray(r, dtype=int)] = True
    centre = garment.rest_vertices[garment.faces].mean(axis=1)
    bands = []
    for bones, end in LIMBS:
        if not all(b in names for b in (*bones, end)):
            continue
        ids = [names.index(b) for b in bones]  # the segment's faces: its bones' share of their skinning
        on = (body.skin_weights[tri] * np.isin(body.skin_indices[tri], ids)).sum(axis=(1, 2)) > 0.5 * tri.shape[1]
        if not on.any() or anchored[on].any():
            continue
        p0, p1 = body.rest_joints[names.index(bones[0])], body.rest_joints[names.index(end)]
        length = np.linalg.norm(p1 - p0)
        axis = (p1 - p0) / length
        band = np.flatnonzero(on & (np.abs((centre - p0) @ axis - length / 2) <= BAND_WIDTH / 2))
        if len(band) >= 3 and _closes_around(centre[band] - p0, axis):
            bands.append(band)
    return bands


def _closes_around(points: np.ndarray, axis: np.ndarray) -> bool:
    """Whether (k, 3) ``points`` go all round the line through the origin along unit ``axis``:
    no gap between their angles about it wider than :data:`BAND_GAP`."""
    e1 = np.cross(axis, [1.0, 0.0, 0.0] if abs(axis[0]) < 0.9 else [0.0, 1.0, 0.0])
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(axis, e1)
    ang = np.sort(np.arctan2(points @ e2, points @ e1))
    gaps = np.diff(np.concatenate([ang, ang[:1] + 2 * np.pi]))
    return bool(gaps.max() <= BAND_GAP)


def random_design(vertices: np.ndarray, faces: np.ndarray, budget: float, seed: int, passes: int = 8,
                  x_min: float = X_MIN) -> np.ndarray:
    """A random smooth design (module doc) with the given seed: (m,) in {x_min, 1}."""
    areas = triangle_areas(vertices, faces)
    filt = one_ring_filter(faces, areas, len(vertices))
    field = np.random.default_rng(seed).standard_normal(len(faces))
    for _ in range(passes):
        field = filt @ field
    return _take_budget(-field, areas, budget, x_min)


def full_design(n_faces: int) -> np.ndarray:
    """(m,) every face reinforced."""
    return np.ones(n_faces)
