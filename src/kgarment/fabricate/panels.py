"""The base garment's own panels, flattened: what the stretch fabric is cut from.

The templates carry no seams, so the panels follow the body: with a rigged body, faces
whose dominant bone is an arm bone (``upperarm``, ``lowerarm``) make a sleeve and leg bones a
leg (one per side; the armhole seam lies where the skinning hands over from the shoulder to
the upper arm); the rest is the trunk, split into front and back by the vertical plane
across the body through its centre (side and shoulder seams; the body faces -Y). Without a
rig the whole garment is split into front and back only. Scraps smaller than
:data:`MIN_PANEL_SHARE` of the garment join the neighbouring panel they share most edges
with. Each panel is flattened like the reinforcement pieces (a sleeve, a tube, is opened
along a short seam; a panel too distorted to lie flat is cut once more); stretch fabric takes the rest.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass

import numpy as np
from scipy.sparse import csr_matrix
from scipy.sparse.csgraph import connected_components

from kgarment.fabricate.patterns import Patch, PatternOptions, make_patterns
from kgarment.garment.topology import face_adjacency

log = logging.getLogger(__name__)

MIN_PANEL_SHARE = 0.02
PANEL_PATTERNS = PatternOptions(max_distortion=0.2, max_cuts=1, min_piece_area=2e-3)
LIMBS = {"upperarm": "sleeve", "lowerarm": "sleeve", "upperleg": "leg", "lowerleg": "leg"}


@dataclass(frozen=True)
class Panel:
    """One flat panel of the base garment: name ("front", "sleeve.L", "front 2" where a
    panel was cut further) and its flat :class:`Patch` (mesh, flattening)."""

    name: str
    patch: Patch


def face_regions(garment, body=None) -> tuple[np.ndarray, list[str]]:
    """(labels (m,) int into names, names) of the garment's faces: sleeves, legs, front, back."""
    m = garment.n_faces
    region = np.array(["trunk"] * m, dtype=object)
    if body is not None and getattr(body, "rigged", False):
        bones = np.asarray(body.bone_names, dtype=object)[body.face_bone()[garment.body_face]]
        for i, b in enumerate(bones):
            stem, _, side = str(b).partition(".")
            base = stem.rstrip("0123456789")
            if base in LIMBS:
                region[i] = f"{LIMBS[base]}.{side}" if side else LIMBS[base]
    V, F = garment.rest_vertices, garment.faces
    cen = V[F].mean(axis=1)
    trunk = region == "trunk"
    w = garment.face_areas()
    y0 = float((w[trunk] * cen[trunk, 1]).sum() / max(w[trunk].sum(), 1e-300)) if trunk.any() else 0.0
    region[trunk & (cen[:, 1] < y0)] = "front"
    region[trunk & (cen[:, 1] >= y0)] = "back"
    names = [n for n in ("front", "back", "sleeve.L", "sleeve.R", "sleeve", "leg.L", "leg.R", "leg") if n in region]
    labels = np.array([names.index(r) for r in region])
    return _absorb_scraps(F, w, labels), names


def _absorb_scraps(F: np.ndarray, w: np.ndarray, labels: np.ndarray) -> np.ndarray:
    """Labels (m,) with every connected scrap under MIN_PANEL_SHARE of the area (w (m,) m^2)
    given to the neighbouring label it shares most edges with."""
    adj = face_adjacency(F).tocoo()
    labels = labels.copy()
    for _ in range(10):
        same = labels[adj.row] == labels[adj.col]
        g = csr_matrix((np.ones(same.sum()), (adj.row[same], adj.col[same])), shape=(len(F), len(F)))
        n, comp = connected_components(g, directed=False)
        area = np.bincount(comp, weights=w, minlength=n)
        small = np.flatnonzero(area < MIN_PANEL_SHARE * w.sum())
        if not len(small):
            break
        changed = False
        for c in small:
            inside = comp == c
            border = inside[adj.row] & ~inside[adj.col]
            if border.any():
                nb = labels[adj.col[border]]
                labels[inside] = np.bincount(nb).argmax()
                changed = True
        if not changed:
            break
    return labels


def garment_panels(garment, body=None, options: PatternOptions = PANEL_PATTERNS) -> tuple[Panel, ...]:
    """The garment's panels, flattened (largest first within a region)."""
    labels, names = face_regions(garment, body)
    out = []
    for k, name in enumerate(names):
        mask = labels == k
        if not mask.any():
            continue
        pats = make_patterns(garment.rest_vertices, garment.faces, mask, options)
        many = len(pats.patches) > 1
        for i, p in enumerate(pats.patches):
            out.append(Panel(f"{name} {i + 1}" if many else name, p))
    log.info("%d base garment panels: %s", len(out), ", ".join(p.name for p in out))
    return tuple(out)
