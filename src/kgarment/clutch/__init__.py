"""Electrostatic clutches: specification, surface walk, strip mesh, files and layouts.

Typical use::

    topo = MeshTopology(V, F)                       # once per garment rest mesh
    spec = ClutchSpec("upper_back", start=(face, bary), direction={"bary": (1, -1, 0)},
                      length=0.135, width=0.01, prestrain=0.95)
    strip = build_clutch(spec, V, F, topology=topo)
    save_clutches("clutches.toml", [spec], V, F)    # portable: rest coordinates, no face ids
"""

from kgarment.clutch.errors import ClutchError
from kgarment.clutch.io import (
    clutch_record,
    clutch_spec_from_record,
    load_clutches,
    save_clutches,
    strip_start_direction,
)
from kgarment.clutch.mesh import MIN_SEGMENT, build_strip
from kgarment.clutch.spec import (
    MAX_SNAP_DISTANCE,
    BaryDirection,
    ClutchSpec,
    ClutchStart,
    SurfacePoint,
    Towards,
    build_clutch,
    resolve_start,
)
from kgarment.clutch.strip import ClutchStrip
from kgarment.clutch.topology import MeshTopology, SurfaceHit
from kgarment.clutch.walk import SurfacePath, trace_path

__all__ = [
    "MAX_SNAP_DISTANCE",
    "MIN_SEGMENT",
    "BaryDirection",
    "ClutchError",
    "ClutchSpec",
    "ClutchStart",
    "ClutchStrip",
    "MeshTopology",
    "SurfaceHit",
    "SurfacePath",
    "SurfacePoint",
    "Towards",
    "build_clutch",
    "build_strip",
    "clutch_record",
    "clutch_spec_from_record",
    "load_clutches",
    "resolve_start",
    "save_clutches",
    "strip_start_direction",
    "trace_path",
]
