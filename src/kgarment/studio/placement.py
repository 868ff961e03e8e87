"""Clutch placement for the studio: specs from clicked points, landmarks, moves and aims.

Every clutch the studio makes is a :class:`~kgarment.clutch.ClutchSpec` whose start is a
3D point and whose direction is a 3D vector, both in the body's rest coordinates: the
portable form that :func:`kgarment.clutch.save_clutches` writes and every subdivision
level of the garment reads. Clicks in a posed view are mapped back to the rest garment
through their face and barycentric coordinates before they get here.
"""

from __future__ import annotations

import dataclasses
import re
from collections.abc import Iterable, Mapping

import numpy as np

from kgarment.clutch import ClutchSpec, ClutchStrip, MeshTopology, build_clutch, resolve_start
from kgarment.clutch.errors import ClutchError

DEFAULT_LENGTH = 0.10  # metres (the paper's strips are 8 to 15 cm)
DEFAULT_WIDTH = 0.01  # metres (the paper's hardware)
LENGTH_RANGE = (0.02, 0.40)
WIDTH_RANGE = (0.004, 0.05)


def unique_name(names: Iterable[str], base: str = "clutch") -> str:
    """``base`` if free, else ``base2``, ``base3``, ... (the first free one)."""
    taken = set(names)
    base = re.sub(r"\s+", "_", base.strip()) or "clutch"
    if base not in taken:
        return base
    k = 2
    while f"{base}{k}" in taken:
        k += 1
    return f"{base}{k}"


def _point(p, what: str) -> tuple[float, float, float]:
    a = np.asarray(p, dtype=np.float64).reshape(-1)
    if a.shape != (3,) or not np.all(np.isfinite(a)):
        raise ClutchError(f"{what} must be 3 finite numbers (metres), got {p!r}")
    return (float(a[0]), float(a[1]), float(a[2]))


def clutch_from_points(name: str, start, towards, length: float = DEFAULT_LENGTH, width: float = DEFAULT_WIDTH,
                       prestrain: float = 1.0, clip: bool = False) -> ClutchSpec:
    """A clutch starting at ``start`` (3,) and heading towards ``towards`` (3,) (rest
    coordinates, metres); the direction is projected onto the start face when built."""
    s, t = _point(start, "clutch start"), _point(towards, "clutch direction point")
    d = np.subtract(t, s)
    if np.linalg.norm(d) < 1e-6:
        raise ClutchError(f"clutch {name!r}: the direction point is the start point; click a second, "
                          "different point to give the direction")
    return ClutchSpec(name, s, _point(d, "clutch direction"), length, width, prestrain, clip)


def clutch_from_landmarks(name: str, start: str, towards: str, length: float = DEFAULT_LENGTH,
                          width: float = DEFAULT_WIDTH, prestrain: float = 1.0, clip: bool = False) -> ClutchSpec:
    """A clutch from landmark ``start`` towards landmark ``towards`` (names as in
    :mod:`kgarment.clutch.landmarks`)."""
    if start == towards:
        raise ClutchError(f"clutch {name!r}: start and direction landmarks are both {start!r}")
    return ClutchSpec(name, start, {"towards": towards}, length, width, prestrain, clip)


def resolved_start(spec: ClutchSpec, topology: MeshTopology, landmarks: Mapping | None):
    """The spec's start on the rest garment (:class:`~kgarment.clutch.ClutchStart`)."""
    return resolve_start(spec, topology.V, topology.F, topology, landmarks)


def moved(spec: ClutchSpec, start, topology: MeshTopology, landmarks: Mapping | None) -> ClutchSpec:
    """``spec`` moved to start at ``start`` (3,), keeping its current direction, length, width."""
    d = resolved_start(spec, topology, landmarks).direction
    return dataclasses.replace(spec, start=_point(start, "clutch start"), direction=_point(d, "direction"))


def aimed(spec: ClutchSpec, towards, topology: MeshTopology, landmarks: Mapping | None) -> ClutchSpec:
    """``spec`` turned to head towards ``towards`` (3,), keeping its start (as a point)."""
    st = resolved_start(spec, topology, landmarks)
    return clutch_from_points(spec.name, st.point, towards, spec.length, spec.width, spec.prestrain, spec.clip)


def build(spec: ClutchSpec, topology: MeshTopology, landmarks: Mapping | None) -> ClutchStrip:
    """The strip of ``spec`` on the rest garment (raises ClutchError with a one-line reason)."""
    try:
        return build_clutch(spec, topology.V, topology.F, topology=topology, landmarks=landmarks)
    except ClutchError as exc:
        msg = str(exc)
        if "boundary" in msg and not spec.clip:
            msg += " (shorten it, turn it, or tick 'clip at the edge')"
        raise ClutchError(msg) from None


def nearest_clutch(strips: Iterable[ClutchStrip], point, max_distance: float = 0.02) -> str | None:
    """Name of the strip whose rest vertices come closest to ``point`` (3,), if within
    ``max_distance`` metres, else None."""
    p = np.asarray(point, dtype=np.float64).reshape(3)
    best, best_d = None, max_distance
    for s in strips:
        d = float(np.linalg.norm(s.vertices - p, axis=1).min())
        if d <= best_d:
            best, best_d = s.name, d
    return best
