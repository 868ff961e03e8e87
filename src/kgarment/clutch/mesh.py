"""Triangulate a walked path into a clutch strip bound to the garment."""

from __future__ import annotations

import logging

import numpy as np

from kgarment.clutch.errors import ClutchError
from kgarment.clutch.strip import ClutchStrip
from kgarment.clutch.topology import MeshTopology
from kgarment.clutch.walk import SurfacePath, trace_path

log = logging.getLogger(__name__)

MIN_SEGMENT = 1e-3  # metres: centre-line segments shorter than this are merged


def centre_rows(path: SurfacePath, min_segment: float = MIN_SEGMENT) -> np.ndarray:
    """(r,) indices into ``path`` of the centre-line points kept for the strip.

    The start and the end are always kept; an intermediate point is dropped when it is
    closer than ``min_segment`` (along the path) to the previous kept point or to the end.
    """
    s = path.arclength
    keep = [0]
    for k in range(1, len(s) - 1):
        if s[k] - s[keep[-1]] >= min_segment and s[-1] - s[k] >= min_segment:
            keep.append(k)
    keep.append(len(s) - 1)
    return np.asarray(keep, dtype=np.int64)


def strip_faces(r: int) -> np.ndarray:
    """(4 (r-1), 3) triangles of a strip with ``r`` rows laid out as centre ``0..r-1``,
    left ``r..2r-1``, right ``2r..3r-1``; wound like the garment when left = n x d."""
    i = np.arange(r - 1)
    c0, c1, l0, l1, r0, r1 = i, i + 1, r + i, r + i + 1, 2 * r + i, 2 * r + i + 1
    tris = np.stack(
        [
            np.stack([c0, c1, l1], 1),
            np.stack([c0, l1, l0], 1),
            np.stack([c0, r0, r1], 1),
            np.stack([c0, r1, c1], 1),
        ],
        axis=1,
    )
    return tris.reshape(-1, 3).astype(np.int64)


def build_strip(
    path: SurfacePath,
    width: float,
    topology: MeshTopology,
    *,
    name: str,
    prestrain: float = 1.0,
    min_segment: float = MIN_SEGMENT,
) -> ClutchStrip:
    """Three rows of vertices along ``path``, the sides walked ``width / 2`` sideways.

    Parameters
    ----------
    path : the clutch's centre line (from :func:`trace_path`) on the garment ``topology``.
    width : float, metres; each side vertex is reached by a surface walk of ``width / 2``
        from its centre point along ``+-(normal x direction)``.
    topology : :class:`MeshTopology` of the garment's rest mesh.
    name : clutch name (for errors and the strip).
    prestrain : rest-shape scale factor in (0, 1].
    min_segment : metres; shorter centre-line segments are merged.

    Raises :class:`ClutchError` when a side walk leaves the garment (strip too wide).
    """
    rows = centre_rows(path, min_segment)
    r = len(rows)
    n = topology.normal[path.faces[rows]]
    side = np.cross(n, path.directions[rows])
    # keep the side consistent along the strip even if the garment's winding is not
    for k in range(1, r):
        if side[k] @ side[k - 1] < 0:
            side[k] = -side[k]
    half = 0.5 * width
    bind_face = np.empty(3 * r, dtype=np.int64)
    bind_bary = np.empty((3 * r, 3))
    bind_face[:r], bind_bary[:r] = path.faces[rows], path.bary[rows]
    for sign, off, label in ((1.0, r, "left"), (-1.0, 2 * r, "right")):
        for k, pk in enumerate(rows):
            walk = trace_path(
                topology.V, topology.F, int(path.faces[pk]), path.bary[pk], sign * side[k], half,
                topology=topology, clip=True, name=name,
            )
            if not walk.complete:
                raise ClutchError(
                    f"clutch {name!r} is wider than the garment: its {label} side leaves the "
                    f"garment {100 * walk.length:.2f} cm from the centre line at "
                    f"{100 * path.arclength[pk]:.1f} cm along it (width {100 * width:.1f} cm)"
                )
            bind_face[off + k], bind_bary[off + k] = walk.faces[-1], walk.bary[-1]
    tri = topology.V[topology.F[bind_face]]
    vertices = np.einsum("ij,ijk->ik", bind_bary, tri)  # same formula as bound_positions
    centre = np.arange(r, dtype=np.int64)
    anchors = np.array([0, r, 2 * r, r - 1, 2 * r - 1, 3 * r - 1], dtype=np.int64)
    log.debug("clutch %r: %d rows from %d path points", name, r, len(path.faces))
    return ClutchStrip(
        name=name,
        vertices=vertices,
        faces=strip_faces(r),
        bind_face=bind_face,
        bind_bary=bind_bary,
        anchors=anchors,
        centerline=centre,
        length=float(path.length),
        width=float(width),
        prestrain=float(prestrain),
    )
