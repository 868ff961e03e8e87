"""Clutch specifications and building a clutch strip from one."""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np

from kgarment.clutch.errors import ClutchError
from kgarment.clutch.mesh import MIN_SEGMENT, build_strip
from kgarment.clutch.strip import ClutchStrip
from kgarment.clutch.topology import MeshTopology
from kgarment.clutch.walk import trace_path
from kgarment.constants import NAME

MAX_SNAP_DISTANCE = 0.02  # metres: a 3D start point farther from the garment is an error

Vec3 = tuple[float, float, float]


@dataclass(frozen=True)
class SurfacePoint:
    """A point given on the mesh: ``face`` and (3,) barycentric coordinates ``bary``."""

    face: int
    bary: Vec3


@dataclass(frozen=True)
class Towards:
    """Direction towards ``target``: a (3,) point (metres) or a landmark name."""

    target: Vec3 | str


@dataclass(frozen=True)
class BaryDirection:
    """A direction in barycentric coordinates of the start face ((3,), sums to 0)."""

    vector: Vec3


Start = SurfacePoint | Vec3 | str
Direction = Vec3 | Towards | BaryDirection


def _vec3(value: object, who: str, what: str) -> Vec3:
    try:
        a = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError):
        raise ClutchError(f"{who}: {what} must be 3 numbers, got {value!r}") from None
    if a.shape != (3,) or not np.all(np.isfinite(a)):
        raise ClutchError(f"{who}: {what} must be 3 finite numbers, got {value!r}")
    return (float(a[0]), float(a[1]), float(a[2]))


def _start(value: object, who: str) -> Start:
    if isinstance(value, SurfacePoint):
        value = (value.face, value.bary)
    if isinstance(value, str):
        return value
    if isinstance(value, Mapping) and set(value) == {"face", "bary"}:
        value = (value["face"], value["bary"])
    if isinstance(value, (tuple, list)) and len(value) == 2:
        face, bary = value
        if isinstance(face, (bool, float)) or not isinstance(face, (int, np.integer)):
            raise ClutchError(f"{who}: field 'start': face must be an integer, got {face!r}")
        b = _vec3(bary, who, "field 'start' barycentric coordinates")
        if min(b) < -1e-9 or abs(sum(b) - 1.0) > 1e-9:
            raise ClutchError(f"{who}: field 'start': barycentric coordinates {b} must be >= 0 "
                              "and sum to 1")
        return SurfacePoint(int(face), b)
    return _vec3(value, who, "field 'start' (a 3D point, (face, bary) or a landmark name)")


def _direction(value: object, start: Start, who: str) -> Direction:
    if isinstance(value, (Towards, BaryDirection)):
        return value
    if isinstance(value, Mapping):
        if len(value) != 1 or next(iter(value)) not in ("towards", "bary", "bary_point"):
            raise ClutchError(f"{who}: field 'direction': a mapping must have exactly one of "
                              f"'towards', 'bary', 'bary_point', got {sorted(value)}")
        key, v = next(iter(value.items()))
        if key == "towards":
            return Towards(v if isinstance(v, str) else _vec3(v, who, "field 'direction.towards'"))
        b = _vec3(v, who, f"field 'direction.{key}'")
        if key == "bary_point":
            if not isinstance(start, SurfacePoint):
                raise ClutchError(f"{who}: field 'direction.bary_point' needs a (face, bary) start")
            b = tuple(x - y for x, y in zip(b, start.bary))
        if abs(sum(b)) > 1e-9 or max(map(abs, b)) == 0.0:
            raise ClutchError(f"{who}: field 'direction': a barycentric direction must be "
                              f"non-zero and sum to 0, got {b}")
        return BaryDirection(b)
    d = _vec3(value, who, "field 'direction'")
    if max(map(abs, d)) == 0.0:
        raise ClutchError(f"{who}: field 'direction' is the zero vector")
    return d


def _positive(value: object, who: str, what: str) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float, np.number)):
        raise ClutchError(f"{who}: field {what!r} must be a number (metres), got {value!r}")
    v = float(value)
    if not (math.isfinite(v) and v > 0):
        raise ClutchError(f"{who}: field {what!r} must be > 0 (metres), got {value!r}")
    return v


MAX_LENGTH = 1.0   # metres: the longest clutch accepted
MAX_ASPECT = 0.5   # a clutch's width may be at most this share of its length


@dataclass(frozen=True)
class ClutchSpec:
    """One clutch as a designer places it. Validated (and normalised) on construction.

    Attributes
    ----------
    name : str
    start : the start point, one of: ``(face, (3,) bary)`` / :class:`SurfacePoint`; a
        (3,) point in metres (snapped to the closest surface point, at most
        ``MAX_SNAP_DISTANCE`` away); a landmark name (resolved by ``build_clutch``).
    direction : one of: a (3,) 3D vector (projected onto the start face's plane);
        ``{"towards": point or landmark}`` / :class:`Towards`; ``{"bary": (3,)}`` /
        :class:`BaryDirection`, a barycentric vector in the start face (sums to 0);
        ``{"bary_point": (3,)}``, a second barycentric point in the start face.
    length, width : float, metres (> 0).
    prestrain : float in (0, 1]; rest-shape scale (< 1: the clutch starts taut).
    clip : stop the clutch at the garment boundary instead of failing.
    """

    name: str
    start: Start
    direction: Direction
    length: float
    width: float = 0.01
    prestrain: float = 1.0
    clip: bool = field(default=False)

    def __post_init__(self) -> None:
        if not isinstance(self.name, str) or not self.name:
            raise ClutchError(f"clutch name must be a non-empty string, got {self.name!r}")
        if not NAME.fullmatch(self.name):
            raise ClutchError(f"clutch name {self.name!r}: allowed: letters, digits, _ . + - (at most 64, not "
                              "starting with . + -; file names are made of it)")
        who = f"clutch {self.name!r}"
        start = _start(self.start, who)
        object.__setattr__(self, "start", start)
        object.__setattr__(self, "direction", _direction(self.direction, start, who))
        object.__setattr__(self, "length", _positive(self.length, who, "length"))
        object.__setattr__(self, "width", _positive(self.width, who, "width"))
        if self.length > MAX_LENGTH:
            raise ClutchError(f"{who}: field 'length' = {self.length:g} m; allowed: up to {MAX_LENGTH:g} m")
        if self.width > MAX_ASPECT * self.length:
            raise ClutchError(f"{who}: field 'width' = {self.width:g} m is more than {MAX_ASPECT:g} x its length "
                              f"({self.length:g} m); a clutch is a strip (the paper's: 15 cm x 2.5 cm)")
        d = self.direction
        if isinstance(d, Towards) and not isinstance(start, SurfacePoint) and d.target == start:
            raise ClutchError(f"{who}: field 'towards' is the start itself; give another point or landmark")
        p = self.prestrain
        if isinstance(p, bool) or not isinstance(p, (int, float, np.number)) or not 0 < p <= 1:
            raise ClutchError(f"{who}: field 'prestrain' must be in (0, 1], got {p!r}")
        object.__setattr__(self, "prestrain", float(p))
        if not isinstance(self.clip, (bool, np.bool_)):
            raise ClutchError(f"{who}: field 'clip' must be true or false, got {self.clip!r}")
        object.__setattr__(self, "clip", bool(self.clip))


@dataclass(frozen=True)
class ClutchStart:
    """A spec's start resolved on a mesh.

    face : int; bary : (3,) float64; point : (3,) float64 metres; direction : (3,) unit
    tangent in the plane of ``face``.
    """

    face: int
    bary: np.ndarray
    point: np.ndarray
    direction: np.ndarray


def _landmark(name: str, landmarks: Mapping[str, object] | None, who: str, what: str) -> Vec3:
    if landmarks is None:
        raise ClutchError(f"{who}: {what} is landmark {name!r} but no landmarks were given")
    if name not in landmarks:
        valid = ", ".join(sorted(landmarks)) or "(none)"
        raise ClutchError(f"{who}: unknown landmark {name!r} in {what}; valid names: {valid}")
    return _vec3(landmarks[name], who, f"landmark {name!r}")


def resolve_start(
    spec: ClutchSpec,
    V: np.ndarray,
    F: np.ndarray,
    topology: MeshTopology | None = None,
    landmarks: Mapping[str, object] | None = None,
    max_snap_distance: float = MAX_SNAP_DISTANCE,
) -> ClutchStart:
    """Resolve ``spec``'s start point and direction on the mesh (V (n, 3), F (m, 3))."""
    topo = topology if topology is not None else MeshTopology(V, F)
    who = f"clutch {spec.name!r}"
    start = spec.start
    if isinstance(start, SurfacePoint):
        if not 0 <= start.face < topo.n_faces:
            raise ClutchError(f"{who}: field 'start': face {start.face} is not a face of the "
                              f"garment (0..{topo.n_faces - 1})")
        face, bary = start.face, np.clip(np.array(start.bary), 0.0, None)
        bary /= bary.sum()
        point = topo.position(face, bary)
    else:
        p = _landmark(start, landmarks, who, "field 'start'") if isinstance(start, str) else start
        hit = topo.closest_point(np.array(p))
        if hit.distance > max_snap_distance:
            raise ClutchError(f"{who}: start point is {100 * hit.distance:.1f} cm from the garment "
                              f"surface (at most {100 * max_snap_distance:.1f} cm allowed)")
        face, bary, point = hit.face, hit.bary, hit.point
    n = topo.normal[face]
    direction = spec.direction
    if isinstance(direction, BaryDirection):
        d = np.array(direction.vector) @ topo.V[topo.F[face]]
    elif isinstance(direction, Towards):
        t = direction.target
        target = _landmark(t, landmarks, who, "field 'direction'") if isinstance(t, str) else t
        d = np.array(target) - point
    else:
        d = np.array(direction)
    scale = float(np.linalg.norm(d))
    d = d - (d @ n) * n
    nd = float(np.linalg.norm(d))
    if not nd > 1e-9 * scale:
        raise ClutchError(f"{who}: field 'direction' is normal to the garment at the start "
                          "(or points at the start itself)")
    return ClutchStart(int(face), np.asarray(bary, dtype=np.float64), point, d / nd)


def build_clutch(
    spec: ClutchSpec,
    V: np.ndarray,
    F: np.ndarray,
    topology: MeshTopology | None = None,
    landmarks: Mapping[str, object] | None = None,
    *,
    max_snap_distance: float = MAX_SNAP_DISTANCE,
    min_segment: float = MIN_SEGMENT,
) -> ClutchStrip:
    """Walk ``spec`` on the garment's rest mesh and build its strip.

    Parameters
    ----------
    spec : the clutch.
    V : (n, 3) float64 garment rest vertices, metres; F : (m, 3) int64 triangles.
    topology : :class:`MeshTopology` of (V, F), reused across clutches (built if None).
    landmarks : name -> (3,) point, metres, for landmark starts/targets.
    max_snap_distance : metres; farther 3D start points are an error.
    min_segment : metres; shorter centre-line segments are merged.

    The strip's ``length`` is the walked length (less than ``spec.length`` only when
    ``spec.clip`` stopped it at the boundary). Raises :class:`ClutchError`.
    """
    topo = topology if topology is not None else MeshTopology(V, F)
    if not topo.matches(np.asarray(V), np.asarray(F)):
        raise ClutchError(f"clutch {spec.name!r}: the topology was built for another mesh")
    st = resolve_start(spec, V, F, topo, landmarks, max_snap_distance)
    path = trace_path(topo.V, topo.F, st.face, st.bary, st.direction, spec.length,
                      topology=topo, clip=spec.clip, name=spec.name)
    return build_strip(path, spec.width, topo, name=spec.name, prestrain=spec.prestrain,
                       min_segment=min_segment)
