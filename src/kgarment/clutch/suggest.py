"""Suggested clutch placements over the highest-strain regions of the garment.

The paper placed clutches by hand over high-strain areas. We measure the strain of the
*unreinforced* garment following the skin (its skin-tight state in each motion, which is
where plain stretch cloth goes), pick the most stretched spots greedily with a minimum
separation, and align each clutch with the principal stretch direction there. The result
is a starting point for the designer to edit.
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
    """Up to ``count`` clutch specs centred on the most stretched spots (metres throughout).

    motions : names of the garment's motions to consider (default: all).
    separation : minimum distance between suggested clutch centres.
    smoothing : radius over which stretch and direction are averaged.
    """
    motions = list(motions or garment.motion_names)
    V, F = garment.rest_vertices, garment.faces
    cent = V[F].mean(axis=1)
    area = garment.face_areas()
    stretches = [principal_stretch(V, garment.vertices(m), F) for m in motions]
    S = np.stack([s.stretch for s in stretches])  # (k, m)
    best_motion = np.argmax(S, axis=0)
    score = S.max(axis=0) - 1.0
    # tensors s d d^T for averaging directions without sign ambiguity
    D = np.stack([s.direction for s in stretches])[best_motion, np.arange(len(F))]
    T = (np.maximum(score, 0) * area)[:, None, None] * D[:, :, None] * D[:, None, :]
    tree = cKDTree(cent)
    nbrs = tree.query_ball_point(cent, smoothing)
    smooth = np.array([np.average(score[n], weights=area[n]) for n in nbrs])
    far_from_edge = ~garment.attached
    boundary = np.zeros(garment.n_vertices, bool)
    for loop in garment.loops.values():
        boundary[loop] = True
    near_boundary = tree.query_ball_point(V[boundary], length / 2)
    ok = far_from_edge.copy()
    for n in near_boundary:
        ok[n] = False
    topo = MeshTopology(V, F)
    specs = []
    order = np.argsort(-smooth)
    taken = []
    for f in order:
        if len(specs) >= count or smooth[f] <= 0:
            break
        if not ok[f] or any(np.linalg.norm(cent[f] - c) < separation for c in taken):
            continue
        Tm = T[nbrs[f]].sum(axis=0)
        w, v = np.linalg.eigh(Tm)
        d = v[:, 2]
        # walk half the length backwards on the surface to find the start
        back = trace_path(V, F, int(f), np.full(3, 1 / 3), -d, 0.5 * length, topology=topo, clip=True)
        start, fwd = back.points[-1], -back.directions[-1]
        taken.append(cent[f])
        specs.append(ClutchSpec(f"suggested{len(specs)}", tuple(map(float, start)), tuple(map(float, fwd)),
                                length, width, clip=True))
    return specs
