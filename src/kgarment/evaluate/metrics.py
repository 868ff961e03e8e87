"""Design metrics: relative energy density, islands, clutch junctions (docs/method/index.md, "The relative energy density").

Relative energy density
    rho(g, d) = (E(x*(g, d), d) / A_d) / (E(x*(g, 1), 1) / A_all)
the energy per reinforced area of a design over that of the fully reinforced garment, in
the same activation state. As in the reference implementation, E(d) counts only the
energy stored in reinforced faces, and when clutches are present their energy and their
area are added to both numerator terms (E and A_d) and to the fully reinforced reference.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.sparse.csgraph import connected_components

from kgarment.garment.topology import face_adjacency


@dataclass(frozen=True)
class Stored:
    """Energy stored in one equilibrium: per garment face (m,) J, and clutches' total J."""

    face_energy: np.ndarray
    clutch_energy: float = 0.0

    @classmethod
    def of(cls, result, clutches: bool = True) -> Stored:
        """From a :class:`kgarment.sim.StateResult`; ``clutches=False`` leaves the
        clutches' energy out (the passive objective)."""
        return cls(result.garment_energy, float(sum(e.sum() for e in result.clutch_energy)) if clutches else 0.0)


def relative_energy_density(design: np.ndarray, areas: np.ndarray, state: Stored, full: Stored,
                            clutch_area: float = 0.0) -> float:
    """rho of a design (m,) in {x_min, 1} given its stored energy and the fully reinforced
    garment's in the same state; areas (m,) m^2; clutch_area m^2 (0 without clutches)."""
    solid = design > 0.5
    e_d = state.face_energy[solid].sum() + state.clutch_energy
    a_d = areas[solid].sum() + clutch_area
    e_full = full.face_energy.sum() + full.clutch_energy
    a_full = areas.sum() + clutch_area
    return float((e_d / max(a_d, 1e-300)) / (e_full / a_full))


def islands(faces: np.ndarray, design: np.ndarray, links=(), adjacency=None) -> int:
    """Connected components of the reinforced faces (edge adjacency).

    faces : (m, 3); design : (m,); links : pairs of face-index arrays (the faces under each
    clutch's two ends) that count as connected through the clutch.
    """
    solid = design > 0.5
    if not solid.any():
        return 0
    adj = face_adjacency(faces) if adjacency is None else adjacency
    adj = adj.tolil(copy=True) if links else adj
    for a, b in links:
        for i in np.atleast_1d(a):
            for j in np.atleast_1d(b):
                adj[i, j] = adj[j, i] = 1
    idx = np.flatnonzero(solid)
    sub = adj.tocsr()[idx][:, idx]
    n, _ = connected_components(sub, directed=False)
    return int(n)


def clutch_end_support(design: np.ndarray, end_faces) -> list[tuple[bool, bool]]:
    """For each clutch, whether each end sits on reinforcement (the majority of the garment
    faces under that end's anchors are reinforced). end_faces: [(faces_a, faces_b), ...]."""
    solid = design > 0.5
    return [(bool(solid[a].mean() > 0.5), bool(solid[b].mean() > 0.5)) for a, b in end_faces]


def structure(case, design: np.ndarray) -> dict:
    """The paper's structural properties of ``design`` (m,) on ``case`` (a :class:`kgarment.case.Case`): ``islands`` (parts of the
    reinforcement), ``islands_with_clutches`` (parts when each clutch joins the parts its
    ends sit on; the most over the wearers), ``clutch_ends_supported`` / ``clutch_ends``
    (over every wearer) and, for a multi-body design, ``by_wearer`` {name: the same three}."""
    faces = case.model.garment_faces
    per = {}
    for name, ends in case.wearer_end_faces().items():
        sup = clutch_end_support(design, ends)
        per[name] = {"islands_with_clutches": islands(faces, design, links=ends, adjacency=case.adjacency),
                     "clutch_ends_supported": int(sum(a + b for a, b in sup)), "clutch_ends": 2 * len(sup)}
    out = {"islands": islands(faces, design, adjacency=case.adjacency),
           "islands_with_clutches": max(v["islands_with_clutches"] for v in per.values()),
           "clutch_ends_supported": sum(v["clutch_ends_supported"] for v in per.values()),
           "clutch_ends": sum(v["clutch_ends"] for v in per.values())}
    if case.wearers:
        out["by_wearer"] = per
    return out
