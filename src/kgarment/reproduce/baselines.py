"""Baseline designs at a given area budget, to compare the optimised designs against.

* :func:`line_design`: the manual-style design common in the literature: strips of
  reinforcement from each clutch end to the nearest attachment ring or to another clutch,
  along the shortest path over the garment (Dijkstra on the face adjacency graph, edge
  weights = distances between face centroids), widened evenly (faces in order of their
  surface distance to the strips) until the budget is spent.
* :func:`random_design`: a random smooth pattern: Gaussian white noise per face, smoothed
  by ``passes`` applications of the one-ring filter, thresholded so that the reinforced
  area equals the budget; seeded, so reproducible.
* :func:`full_design`: every face reinforced (rho = 1 by the definition of rho).

Budgets are fractions of the garment's rest area; designs are (m,) arrays in {x_min, 1}.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import dijkstra

from kgarment.constants import X_MIN
from kgarment.design.beso import one_ring_filter
from kgarment.garment.topology import face_adjacency, triangle_areas


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


def line_paths(vertices: np.ndarray, faces: np.ndarray, end_faces, attached: np.ndarray) -> np.ndarray:
    """(m,) bool faces on the shortest paths from each clutch end to the nearest target.

    end_faces : per clutch, (faces under end A, faces under end B) index arrays;
    attached : (m,) bool attachment-ring faces.  Targets of an end: attachment faces and
    the ends of the *other* clutches (an end is never linked to its own clutch).
    """
    graph = dual_graph(vertices, faces)
    on_path = np.zeros(len(faces), bool)
    for k, ends in enumerate(end_faces):
        others = [np.asarray(f) for j, e in enumerate(end_faces) if j != k for f in e]
        targets = np.zeros(len(faces), bool)
        targets |= np.asarray(attached, bool)
        for f in others:
            targets[f] = True
        for src in ends:
            src = np.unique(np.asarray(src))
            on_path[src] = True
            if not targets.any():
                continue
            dist, pred, origin = dijkstra(graph, indices=src, min_only=True, return_predecessors=True)
            cand = np.flatnonzero(targets & np.isfinite(dist))
            if len(cand) == 0:
                continue
            f = int(cand[np.argmin(dist[cand])])
            while f >= 0:
                on_path[f] = True
                f = int(pred[f])
    return on_path


def line_design(vertices: np.ndarray, faces: np.ndarray, end_faces, attached: np.ndarray, budget: float,
                x_min: float = X_MIN) -> np.ndarray:
    """The manual-style line design (module doc): (m,) in {x_min, 1}."""
    path = line_paths(vertices, faces, end_faces, attached)
    graph = dual_graph(vertices, faces)
    dist = dijkstra(graph, indices=np.flatnonzero(path), min_only=True)
    return _take_budget(np.where(np.isfinite(dist), dist, np.inf), triangle_areas(vertices, faces), budget, x_min)


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
