"""Portable clutch files (TOML or JSON).

Clutches are stored by surface points in the body's *rest coordinates*, never by face
ids, so a file made on one mesh loads onto another mesh of the same surface (e.g. a
subdivided one)::

    format = "kgarment.clutches"
    version = 1
    units = "m"

    [[clutch]]
    name = "upper_back"
    start = [0.01, 0.12, 1.35]       # 3D point (snapped onto the surface) or a landmark name
    direction = [1.0, 0.0, 0.0]      # 3D vector; or instead: towards = [x, y, z] / "landmark"
    length = 0.135
    width = 0.01
    prestrain = 0.95
    clip = false
"""

from __future__ import annotations

import json
import tomllib
from collections.abc import Iterable, Mapping
from pathlib import Path

import numpy as np
import tomli_w

from kgarment.clutch.errors import ClutchError
from kgarment.clutch.spec import (
    BaryDirection,
    ClutchSpec,
    SurfacePoint,
    Towards,
    resolve_start,
)
from kgarment.clutch.strip import ClutchStrip
from kgarment.clutch.topology import MeshTopology
from kgarment.io import atomic_write_text

FORMAT = "kgarment.clutches"
VERSION = 1
_FIELDS = {"name", "start", "direction", "towards", "length", "width", "prestrain", "clip"}


def _floats(a: object) -> list[float]:
    return [float(x) for x in np.asarray(a, dtype=np.float64).reshape(3)]


def strip_start_direction(strip: ClutchStrip) -> np.ndarray:
    """(3,) unit start direction of a strip, estimated from its geometry.

    The first centre-line chord with its component along the first row (left - right)
    removed: exact on developable patches up to the tilt out of the start face (which
    loading removes by projecting), otherwise accurate to the side walks' bending
    (~1e-3 rad on a body mesh). Save :class:`ClutchSpec` objects for exact round trips.
    """
    x = strip.vertices
    c = strip.centerline
    r = len(c)
    left, right = x[r], x[2 * r]  # row layout of kgarment.clutch.mesh.build_strip
    ell = left - right
    ell = ell / np.linalg.norm(ell)
    chord = x[c[1]] - x[c[0]]
    d = chord - (chord @ ell) * ell
    return d / np.linalg.norm(d)


def clutch_record(
    item: ClutchSpec | ClutchStrip,
    V: np.ndarray | None = None,
    F: np.ndarray | None = None,
    *,
    topology: MeshTopology | None = None,
    landmarks: Mapping[str, object] | None = None,
) -> dict:
    """The portable record (a plain dict) of one clutch.

    Specs given by 3D points, 3D vectors or landmark names are stored as they are;
    specs given on the mesh (face + barycentric) need the rest mesh V (n, 3), F (m, 3)
    to convert them. Strips are stored by their start point and start direction.
    """
    if isinstance(item, ClutchStrip):
        rec = {
            "name": item.name,
            "start": _floats(item.vertices[item.centerline[0]]),
            "direction": _floats(strip_start_direction(item)),
            "length": float(item.length),
            "width": float(item.width),
            "prestrain": float(item.prestrain),
        }
        return rec
    if not isinstance(item, ClutchSpec):
        raise ClutchError(f"cannot save {type(item).__name__}: expected ClutchSpec or ClutchStrip")
    rec: dict = {"name": item.name}
    on_mesh = isinstance(item.start, SurfacePoint) or isinstance(item.direction, BaryDirection)
    if on_mesh:
        if V is None or F is None:
            raise ClutchError(f"clutch {item.name!r} is given by face ids: saving it needs the "
                              "rest mesh (V, F)")
        st = resolve_start(item, V, F, topology, landmarks)
        rec["start"], rec["direction"] = _floats(st.point), _floats(st.direction)
    else:
        rec["start"] = item.start if isinstance(item.start, str) else list(item.start)
        if isinstance(item.direction, Towards):
            t = item.direction.target
            rec["towards"] = t if isinstance(t, str) else list(t)
        else:
            rec["direction"] = list(item.direction)
    rec.update(length=item.length, width=item.width, prestrain=item.prestrain)
    if item.clip:
        rec["clip"] = True
    return rec


def save_clutches(
    path: str | Path,
    clutches: Iterable[ClutchSpec | ClutchStrip],
    V: np.ndarray | None = None,
    F: np.ndarray | None = None,
    *,
    topology: MeshTopology | None = None,
    landmarks: Mapping[str, object] | None = None,
) -> None:
    """Write clutches to ``path`` (``.json`` for JSON, anything else TOML).

    V (n, 3), F (m, 3): the rest mesh, needed only for specs given by face ids."""
    path = Path(path)
    topo = topology
    if topo is None and V is not None and F is not None:
        topo = MeshTopology(V, F)
    records = [clutch_record(c, V, F, topology=topo, landmarks=landmarks) for c in clutches]
    names = [r["name"] for r in records]
    dup = sorted({n for n in names if names.count(n) > 1})
    if dup:
        raise ClutchError(f"{path}: duplicate clutch names {dup}")
    doc = {"format": FORMAT, "version": VERSION, "units": "m", "clutch": records}
    text = json.dumps(doc, indent=2) + "\n" if path.suffix.lower() == ".json" else tomli_w.dumps(doc)
    atomic_write_text(path, text)


def _field(rec: Mapping, key: str, where: str, kind: str) -> object:
    v = rec[key]
    if kind == "number" and (isinstance(v, bool) or not isinstance(v, (int, float))):
        raise ClutchError(f"{where}: field {key!r} must be a number, got {v!r}")
    if kind == "point" and not isinstance(v, str) and not (
        isinstance(v, list) and len(v) == 3
        and all(isinstance(x, (int, float)) and not isinstance(x, bool) for x in v)
    ):
        raise ClutchError(f"{where}: field {key!r} must be [x, y, z] or a landmark name, got {v!r}")
    return v


def clutch_spec_from_record(rec: object, k: int, fname: str) -> ClutchSpec:
    """One clutch table (from a clutch file or a problem's [[clutches.clutch]]) -> ClutchSpec;
    errors name the file (``fname``) and the clutch."""
    where = fname
    if not isinstance(rec, Mapping):
        raise ClutchError(f"{where}: clutch #{k} must be a table, got {type(rec).__name__}")
    name = rec.get("name")
    if not isinstance(name, str) or not name:
        raise ClutchError(f"{where}: clutch #{k}: field 'name' is missing or not a string")
    where = f"{where}: clutch {name!r}"
    extra = sorted(set(rec) - _FIELDS)
    if extra:
        raise ClutchError(f"{where}: unknown field(s) {extra}; valid: {sorted(_FIELDS)}")
    for key in ("start", "length"):
        if key not in rec:
            raise ClutchError(f"{where}: field {key!r} is missing")
    if ("direction" in rec) == ("towards" in rec):
        raise ClutchError(f"{where}: give exactly one of fields 'direction' and 'towards'")
    start = _field(rec, "start", where, "point")
    if "towards" in rec:
        direction: object = {"towards": _field(rec, "towards", where, "point")}
    else:
        direction = _field(rec, "direction", where, "point")
        if isinstance(direction, str):
            raise ClutchError(f"{where}: field 'direction' must be [x, y, z]; use 'towards' "
                              "for a landmark")
    kw = {key: _field(rec, key, where, "number") for key in ("length", "width", "prestrain")
          if key in rec}
    if "clip" in rec and not isinstance(rec["clip"], bool):
        raise ClutchError(f"{where}: field 'clip' must be true or false, got {rec['clip']!r}")
    try:
        return ClutchSpec(name, start, direction, clip=rec.get("clip", False), **kw)
    except ClutchError as e:
        raise ClutchError(f"{fname}: {e}") from None


def load_clutches(path: str | Path) -> list[ClutchSpec]:
    """Read a clutch file written by :func:`save_clutches` (or by hand)."""
    path = Path(path)
    raw = path.read_bytes()
    try:
        if path.suffix.lower() == ".json":
            doc = json.loads(raw)
        else:
            doc = tomllib.loads(raw.decode())
    except (ValueError, UnicodeDecodeError) as e:
        raise ClutchError(f"{path}: not a valid clutch file ({e})") from None
    if not isinstance(doc, Mapping):
        raise ClutchError(f"{path}: not a valid clutch file (top level is not a table)")
    if doc.get("format", FORMAT) != FORMAT:
        raise ClutchError(f"{path}: field 'format' is {doc.get('format')!r}, expected {FORMAT!r}")
    if doc.get("version", VERSION) != VERSION:
        raise ClutchError(f"{path}: field 'version' is {doc.get('version')!r}, "
                          f"this reader knows {VERSION}")
    if doc.get("units", "m") != "m":
        raise ClutchError(f"{path}: field 'units' must be \"m\", got {doc.get('units')!r}")
    recs = doc.get("clutch", [])
    if not isinstance(recs, list):
        raise ClutchError(f"{path}: field 'clutch' must be an array of tables")
    specs = [clutch_spec_from_record(r, k, str(path)) for k, r in enumerate(recs)]
    names = [s.name for s in specs]
    dup = sorted({n for n in names if names.count(n) > 1})
    if dup:
        raise ClutchError(f"{path}: duplicate clutch names {dup}")
    return specs
