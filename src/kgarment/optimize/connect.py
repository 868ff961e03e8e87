"""Designs in one piece with every clutch end on it: the connected BESO update.

Plain BESO ranks faces by their (filtered) energy density and keeps the best ones up to the
target area.  A thin link in series between a clutch end and the rest of the structure
stores little energy per face, so BESO cuts it, although the cut takes the whole load path
(and the clutch) out of service.  The paper names
the properties its designs show: no islands of reinforcement, every clutch end on
reinforcement, a load path through the clutches.

:func:`connect_design` repairs BESO's proposal so that it has them, and changes nothing
when it already does:

1. every clutch end is joined, over reinforcement, to an anchor *without passing through
   that clutch itself* (other clutches may be passed where they are switched on together
   with it: an ON clutch links two parts, an OFF one is compliant cloth), along the cheapest
   path over the face graph: a face costs
   almost nothing when the proposal reinforces it already, otherwise its area, more when
   its sensitivity ranks low.  So a clutch is held at both ends by structure that the body
   moves, in series, which is what lets it carry load (a clutch whose end sits on a patch
   held only through the clutch itself carries nothing).  Anchors are what the body holds
   (:func:`anchored`): the attachment faces, and parts of the proposal that close around
   the body (a band around an arm or the torso cannot slide off it, an open strip on a
   frictionless body can); only where the garment has neither, the root, the proposal's
   most sensitive face;
2. every part holding such a path is joined to the root's part along the cheapest path
   (a path from a clutch end to an attachment face the proposal leaves plain would
   otherwise be an island, and dropping it would take the end off reinforcement);
   reinforcement not joined to the root through reinforcement and clutches (islands) is
   dropped;
3. the area is brought back to the target: the lowest-ranked faces off the joining paths
   go first, in batches that never cut a protected face off the root's part nor a clutch
   end off what holds it (step 1's property: a batch that would is halved, a single face
   that would stays), or the best-ranked faces next to the structure are added.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import breadth_first_order, connected_components, dijkstra

IN_DESIGN_COST = 1e-6  # relative cost of a face the proposal already reinforces
LOW_RANK_COST = 4.0    # a face of the lowest sensitivity costs this many times its area more


def link_graph(adjacency: sp.csr_matrix, ends) -> sp.csr_matrix:
    """(m, m) face graph: edge adjacency plus, for every clutch, links between all faces
    under its two ends.  adjacency : (m, m); ends : [(faces under end A, under end B)]."""
    rows, cols = [], []
    for a, b in ends:
        a, b = np.unique(np.asarray(a)), np.unique(np.asarray(b))
        rows.append(np.repeat(a, len(b)))
        cols.append(np.tile(b, len(a)))
    if not rows:
        return adjacency.tocsr().astype(np.float64)
    r, c = np.concatenate(rows), np.concatenate(cols)
    links = sp.csr_matrix((np.ones(2 * len(r)), (np.r_[r, c], np.r_[c, r])), shape=adjacency.shape)
    return ((adjacency + links) > 0).astype(np.float64).tocsr()


def _reachable(graph: sp.csr_matrix, solid: np.ndarray, root: int) -> np.ndarray:
    """(m,) bool faces of ``solid`` joined to ``root`` through solid faces and clutch links."""
    idx = np.flatnonzero(solid)
    pos = np.full(len(solid), -1)
    pos[idx] = np.arange(len(idx))
    sub = graph[idx][:, idx]
    order = breadth_first_order(sub, pos[root], directed=False, return_predecessors=False)
    out = np.zeros(len(solid), bool)
    out[idx[order]] = True
    return out


def anchored(solid: np.ndarray, adjacency: sp.csr_matrix, attached: np.ndarray, loop_faces) -> np.ndarray:
    """(m,) bool faces of the parts of ``solid`` (m,) bool that the body holds: parts with
    an attachment face, and parts that close around the body, i.e. whose removal separates
    two boundary openings of the garment (hem from cuff: a band around the arm).
    adjacency : (m, m) face adjacency; attached : (a,) attachment faces; loop_faces : per
    boundary loop of the garment, the faces touching it."""
    out = np.zeros(len(solid), bool)
    idx = np.flatnonzero(solid)
    if not len(idx):
        return out
    _, part = connected_components(adjacency[idx][:, idx], directed=False)
    held = np.zeros(len(solid), bool)
    held[np.asarray(attached, dtype=int)] = True
    for p in range(part.max() + 1):
        faces = idx[part == p]
        if held[faces].any() or _separates(faces, adjacency, loop_faces):
            out[faces] = True
    return out


def _separates(faces: np.ndarray, adjacency: sp.csr_matrix, loop_faces) -> bool:
    """Whether removing ``faces`` splits the garment's boundary openings apart."""
    keep = np.ones(adjacency.shape[0], bool)
    keep[faces] = False
    idx = np.flatnonzero(keep)
    pos = np.full(len(keep), -1)
    pos[idx] = np.arange(len(idx))
    _, comp = connected_components(adjacency[idx][:, idx], directed=False)
    seen = set()
    for lf in loop_faces:
        lf = np.asarray(lf)
        lf = lf[keep[lf]]
        seen |= set(comp[pos[lf]].tolist())
    return len(seen) > 1


def _paths(graph: sp.csr_matrix, cost: np.ndarray, sources: np.ndarray, targets: np.ndarray) -> np.ndarray:
    """(m,) bool faces on the cheapest paths from any of ``sources`` to each of ``targets``
    (entering a face costs ``cost`` of it)."""
    weighted = graph.tocsr(copy=True)
    weighted.data = cost[weighted.indices] + 1e-300
    dist, pred, _ = dijkstra(weighted, indices=sources, min_only=True, return_predecessors=True)
    on = np.zeros(graph.shape[0], bool)
    for t in targets:
        f = int(t)
        if not np.isfinite(dist[f]):
            continue
        while f >= 0 and not on[f]:
            on[f] = True
            f = int(pred[f])
    return on


def _join(graph: sp.csr_matrix, cost: np.ndarray, areas: np.ndarray, solid: np.ndarray, root: int,
          protected: np.ndarray) -> np.ndarray:
    """(m,) bool: the faces to add so that every part of ``solid`` holding ``protected``
    faces is joined to the root's part, each along the cheapest path (a path from a clutch
    end to an attachment face the proposal does not reinforce is otherwise an island)."""
    solid = solid.copy()
    added = np.zeros(len(solid), bool)
    for _ in range(len(solid)):
        main = _reachable(graph, solid, root)
        loose = np.flatnonzero(protected & solid & ~main)
        if not len(loose):
            break
        on = _paths(graph, np.where(solid, IN_DESIGN_COST * areas, cost), np.flatnonzero(main), loose[:1])
        if not on[loose[0]]:
            break  # no path over the garment: the island drop takes it
        added |= on & ~solid
        solid |= on
    return added


def _held_ends(solid: np.ndarray, ends, graphs, adjacency: sp.csr_matrix, attached: np.ndarray,
               loop_faces) -> np.ndarray:
    """(2 * clutches,) bool: whether each clutch end (A, B per clutch of ``ends``) sits on
    reinforcement of ``solid`` (m,) bool joined to what the body holds (:func:`anchored`)
    through reinforcement and the links of ``graphs[k]`` (clutch k's graph: its partners'
    links, not its own)."""
    anchors = anchored(solid, adjacency, attached, loop_faces)
    idx = np.flatnonzero(solid)
    pos = np.full(len(solid), -1)
    pos[idx] = np.arange(len(idx))
    out = np.zeros(2 * len(ends), bool)
    comps = {}
    for k, (a, b) in enumerate(ends):
        g = graphs[k]
        if id(g) not in comps:
            comps[id(g)] = connected_components(g[idx][:, idx], directed=False)[1]
        comp = comps[id(g)]
        held = set(comp[pos[anchors]].tolist())
        for i, end in enumerate((a, b)):
            end = np.asarray(end)
            end = end[solid[end]]
            out[2 * k + i] = bool(len(end)) and bool(held & set(comp[pos[end]].tolist()))
    return out


def _trim(graph: sp.csr_matrix, solid: np.ndarray, root: int, protected: np.ndarray, alpha: np.ndarray,
          areas: np.ndarray, excess: float, holds=None) -> np.ndarray:
    """(m,) bool: ``solid`` less about ``excess`` m^2 of its lowest-ranked unprotected faces,
    removed in batches that never cut a protected face off the root's part and, with
    ``holds`` (a function of a design giving (n,) bool per clutch end, see
    :func:`_held_ends`), never take a clutch end that is held off what holds it (a batch
    that would is halved; a single face that would is kept)."""
    solid = solid.copy()
    keep = protected.copy()
    before = None if holds is None else holds(solid)
    while excess > 1e-12 * areas.sum():
        free = np.flatnonzero(solid & ~keep)
        if not len(free):
            break
        free = free[np.argsort(alpha[free], kind="stable")]
        k = int(np.searchsorted(np.cumsum(areas[free]), excess, side="left")) + 1
        k = max(1, min(k, len(free), int(solid.sum()) // 20))  # at most 5% of the structure per batch
        while True:
            trial = solid.copy()
            trial[free[:k]] = False
            reach = _reachable(graph, trial, root)
            if not (protected & solid & ~reach).any() and (before is None or not (before & ~holds(reach)).any()):
                excess -= areas[solid & ~reach].sum()
                solid = reach
                break
            if k == 1:
                keep[free[0]] = True
                break
            k //= 2
    return solid


def connect_design(solid: np.ndarray, alpha: np.ndarray, areas: np.ndarray, target: float,
                   adjacency: sp.csr_matrix, ends, attached: np.ndarray | None = None,
                   loop_faces=(), keep: np.ndarray | None = None, partners=None) -> np.ndarray:
    """BESO's proposal ``solid`` (m,) bool repaired into one part in which every clutch is
    held at both ends (module docstring).  alpha : (m,) filtered sensitivities (higher =
    more useful); areas : (m,) m^2; target : the reinforced area share to meet; adjacency :
    (m, m) face adjacency; ends : [(faces under end A, under end B)] per clutch; attached :
    (a,) attachment faces; loop_faces : per boundary loop, the faces touching it
    (:func:`anchored`);  keep : (m,) bool faces of ``solid`` that stay, joined to the rest
    like the clutch ends' paths (the step guard's, :mod:`kgarment.optimize.guard`), or None;
    partners : per clutch of ``ends``, the indices of the clutches switched on together with
    it in some motion (the only ones its ends' paths may pass), or None: every other clutch
    (all clutches ON together).  Returns (m,) bool."""
    solid = np.asarray(solid, bool).copy()
    if not len(ends) or not solid.any():
        return solid
    rank = np.empty(len(alpha))
    rank[np.argsort(alpha, kind="stable")] = np.linspace(0.0, 1.0, len(alpha))
    cost = areas * np.where(solid, IN_DESIGN_COST, 1.0 + LOW_RANK_COST * (1.0 - rank))
    root = int(np.flatnonzero(solid)[np.argmax(alpha[solid])])
    attached = np.asarray(attached if attached is not None else [], dtype=int)
    sources = np.unique(np.r_[attached, np.flatnonzero(anchored(solid, adjacency, attached, loop_faces))])
    if not len(sources):
        sources = np.array([root])
    protected = np.zeros(len(solid), bool)
    protected[root] = True
    graphs, by_links = [], {}
    for k, (a, b) in enumerate(ends):
        links = tuple(j for j in (range(len(ends)) if partners is None else partners[k]) if j != k)
        if links not in by_links:
            by_links[links] = link_graph(adjacency, [ends[j] for j in links])
        graphs.append(by_links[links])
        protected |= _paths(graphs[k], cost, sources, np.r_[a, b])
    if keep is not None:
        protected |= keep & solid
    graph = link_graph(adjacency, ends)
    solid |= protected
    added = _join(graph, cost, areas, solid, root, protected)
    solid = _reachable(graph, solid | added, root)  # islands dropped
    protected = (protected | added) & solid
    total = areas.sum()
    area = areas[solid].sum() / total
    if area > target + 1e-12:
        solid = _trim(graph, solid, root, protected, alpha, areas=areas, excess=(area - target) * total,
                      holds=lambda d: _held_ends(d, ends, graphs, adjacency, attached, loop_faces))
        area = areas[solid].sum() / total
    grow = target - area
    while grow > 1e-12:
        ring = np.flatnonzero((graph @ solid.astype(np.float64) > 0) & ~solid)
        if len(ring) == 0:
            break
        ring = ring[np.argsort(-alpha[ring], kind="stable")]
        k = int(np.searchsorted(np.cumsum(areas[ring]) / total, grow, side="left")) + 1
        solid[ring[:k]] = True
        grow -= areas[ring[:k]].sum() / total
    return solid
