"""Suggested clutch placements over the highest-strain regions of the garment.

The paper placed clutches by hand over high-strain areas. We measure the strain of the
*unreinforced* garment following the skin (its skin-tight state in each motion, which is
where plain stretch cloth goes), pick the most stretched spots of each motion in turn with
a minimum separation, and align each clutch with the principal stretch direction there.
Whether a suggested clutch can be felt in a motion is then checked by simulation
(:func:`kgarment.evaluate.control.clutch_control`, printed by ``kgarment clutches suggest``).
The result is a starting point for the designer to edit.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

from kgarment.clutch.spec import ClutchSpec
from kgarment.clutch.topology import MeshTopology
from kgarment.clutch.walk import trace_path
from kgarment.garment.garment import Garment


@dataclass(frozen=True)
class FaceStretch:
    """Principal stretch of each face between the rest and a deformed state.

    stretch : (m,) largest principal stretch (1 = unstretched);
    direction : (m, 3) unit rest-space direction of that stretch.
    """

    stretch: np.ndarray
    direction: np.ndarray


def principal_stretch(rest: np.ndarray, deformed: np.ndarray, faces: np.ndarray) -> FaceStretch:
    """Largest principal stretch per triangle. rest, deformed : (n, 3); faces : (m, 3)."""
    x0, x1, x2 = (rest[faces[:, k]] for k in range(3))
    e1 = x1 - x0
    e1 /= np.linalg.norm(e1, axis=1, keepdims=True)
    nrm = np.cross(x1 - x0, x2 - x0)
    nrm /= np.linalg.norm(nrm, axis=1, keepdims=True)
    e2 = np.cross(nrm, e1)
    Dm = np.stack([np.stack([((x1 - x0) * e1).sum(1), ((x2 - x0) * e1).sum(1)], 1),
                   np.stack([((x1 - x0) * e2).sum(1), ((x2 - x0) * e2).sum(1)], 1)], 1)  # (m, 2, 2)
    y0, y1, y2 = (deformed[faces[:, k]] for k in range(3))
    Ds = np.stack([y1 - y0, y2 - y0], axis=2)  # (m, 3, 2)
    F = Ds @ np.linalg.inv(Dm)
    C = np.swapaxes(F, 1, 2) @ F
    w, v = np.linalg.eigh(C)
    top = v[:, :, 1]  # (m, 2), eigenvector of the largest eigenvalue
    d = top[:, :1] * e1 + top[:, 1:] * e2
    return FaceStretch(np.sqrt(np.maximum(w[:, 1], 0.0)), d / np.linalg.norm(d, axis=1, keepdims=True))


def suggest_clutches(garment: Garment, motions=None, count: int = 3, length: float = 0.10,
                     width: float = 0.01, separation: float = 0.10, smoothing: float = 0.03) -> list[ClutchSpec]:
    """Up to ``count`` clutch specs centred on the most stretched spots (metres throughout),
    taken in turn per motion: the first clutch at the first motion's most stretched spot,
    the second at the second motion's, and so on round the motions, so every motion gets a
    clutch where it stretches the garment when ``count`` >= the number of motions.

    motions : names of the garment's motions to consider (default: all).
    separation : minimum distance between suggested clutch centres.
    smoothing : radius over which stretch and direction are averaged.
    """
    motions = list(motions or garment.motion_names)
    V, F = garment.rest_vertices, garment.faces
    cent = V[F].mean(axis=1)
    area = garment.face_areas()
    stretches = [principal_stretch(V, garment.vertices(m), F) for m in motions]
    tree = cKDTree(cent)
    nbrs = tree.query_ball_point(cent, smoothing)
    ok = _away_from_edges(garment, tree, length)
    topo = MeshTopology(V, F)
    ranked = []  # per motion: faces by smoothed stretch, best first, and the motion's tensors
    for st in stretches:
        score = st.stretch - 1.0
        # tensors s d d^T for averaging directions without sign ambiguity
        T = (np.maximum(score, 0) * area)[:, None, None] * st.direction[:, :, None] * st.direction[:, None, :]
        smooth = np.array([np.average(score[n], weights=area[n]) for n in nbrs])
        order = [int(f) for f in np.argsort(-smooth) if smooth[f] > 0 and ok[f]]
        ranked.append((order, T))
    specs: list[ClutchSpec] = []
    taken: list[np.ndarray] = []
    cursor = [0] * len(motions)
    while len(specs) < count and any(c < len(order) for c, (order, _) in zip(cursor, ranked)):
        for k, (order, T) in enumerate(ranked):
            if len(specs) >= count:
                break
            while cursor[k] < len(order) and any(np.linalg.norm(cent[order[cursor[k]]] - c) < separation
                                                 for c in taken):
                cursor[k] += 1
            if cursor[k] >= len(order):
                continue
            f = order[cursor[k]]
            _, v = np.linalg.eigh(T[nbrs[f]].sum(axis=0))
            d = v[:, 2]
            # walk half the length backwards on the surface to find the start
            back = trace_path(V, F, f, np.full(3, 1 / 3), -d, 0.5 * length, topology=topo, clip=True)
            start, fwd = back.points[-1], -back.directions[-1]
            taken.append(cent[f])
            specs.append(ClutchSpec(f"suggested{len(specs)}", tuple(map(float, start)), tuple(map(float, fwd)),
                                    length, width, clip=True))
    return specs


def _away_from_edges(garment: Garment, tree: cKDTree, length: float) -> np.ndarray:
    """(m,) bool: faces neither attached nor within half a clutch length of an opening."""
    ok = ~garment.attached
    boundary = np.zeros(garment.n_vertices, bool)
    for loop in garment.loops.values():
        boundary[loop] = True
    for n in tree.query_ball_point(garment.rest_vertices[boundary], length / 2):
        ok[n] = False
    return ok
