"""Motions: named bone rotations relative to the rest A-pose.

A motion is a sequence of keyframes; each keyframe is a tuple of :class:`Rotation`.
The target pose (the one the design loop uses) is the last keyframe; ``Motion.at(t)``
interpolates angles linearly in between, for animation.

Axes are fixed in the rest pose and given as ``"x"``, ``"y"``, ``"z"`` (world axes; the
body faces -Y, Z up, its left side is +X), a negated one (``"-x"``), a 3-vector, or a
geometric name resolved on the rest skeleton:

``hinge``  the normal of the plane of the bone and its parent, signed so that a positive
           angle bends the joint further (flexion); needs a bent joint (elbow).
``twist``  the bone's own long axis (head to first child's head).

Rotations on one bone are applied in the order listed. Built-in motions are written for
the left side and mirrored (x -> -x) for ``.right``; the plain name moves both sides.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from kgarment.errors import KgarmentError, unknown

NAMED_AXES = ("x", "y", "z", "-x", "-y", "-z", "hinge", "twist")


@dataclass(frozen=True)
class Rotation:
    """Rotate ``bone`` by ``degrees`` about ``axis`` (a name from NAMED_AXES or a 3-vector)."""

    bone: str
    axis: str | tuple[float, float, float]
    degrees: float

    def mirrored(self) -> "Rotation":
        bone = _mirror_bone(self.bone)
        if isinstance(self.axis, str):
            if self.axis == "twist":
                return Rotation(bone, "twist", -self.degrees)
            if self.axis == "hinge":
                return Rotation(bone, "hinge", self.degrees)
            vec = tuple(_world_axis(self.axis))
        else:
            vec = tuple(self.axis)
        # a rotation axis is a pseudo-vector: mirroring x -> -x maps (a, b, c) to (a, -b, -c)
        return Rotation(bone, (vec[0], -vec[1], -vec[2]), self.degrees)


@dataclass(frozen=True)
class Motion:
    """A named motion: keyframes of bone rotations from the rest pose."""

    name: str
    keyframes: tuple[tuple[Rotation, ...], ...]
    description: str = ""

    @property
    def target(self) -> tuple[Rotation, ...]:
        return self.keyframes[-1]

    def bones(self) -> set[str]:
        return {r.bone for kf in self.keyframes for r in kf}

    def at(self, t: float) -> tuple[Rotation, ...]:
        """Rotations at time t in [0, 1]: linear in angle through the keyframes (0 = rest)."""
        t = float(np.clip(t, 0.0, 1.0))
        frames = ((),) + self.keyframes
        s = t * (len(frames) - 1)
        i = min(int(np.floor(s)), len(frames) - 2)
        a = s - i
        lo, hi = _by_key(frames[i]), _by_key(frames[i + 1])
        out = []
        for key in list(lo) + [k for k in hi if k not in lo]:
            d0 = lo[key].degrees if key in lo else 0.0
            d1 = hi[key].degrees if key in hi else 0.0
            out.append(Rotation(key[0], key[1], (1 - a) * d0 + a * d1))
        return tuple(out)


def _by_key(rotations):
    return {(r.bone, r.axis): r for r in rotations}


def _mirror_bone(bone: str) -> str:
    if bone.endswith(".L"):
        return bone[:-2] + ".R"
    if bone.endswith(".R"):
        return bone[:-2] + ".L"
    return bone


def _world_axis(name: str) -> np.ndarray:
    sign = -1.0 if name.startswith("-") else 1.0
    return sign * np.eye(3)["xyz".index(name[-1])]


def resolve_axis(rotation: Rotation, bone_names, bone_parents, rest_joints) -> np.ndarray:
    """The unit rotation axis (3,) in the rest world frame.

    bone_names : sequence of B str; bone_parents : (B,) int; rest_joints : (B, 3) metres.
    """
    axis = rotation.axis
    if not isinstance(axis, str):
        vec = np.asarray(axis, dtype=float)
        if vec.shape != (3,) or not np.all(np.isfinite(vec)) or np.linalg.norm(vec) == 0:
            raise KgarmentError(f"bone {rotation.bone!r}: axis must be a nonzero 3-vector or one of {', '.join(NAMED_AXES)}")
        return vec / np.linalg.norm(vec)
    if axis not in NAMED_AXES:
        raise unknown("axis", axis, NAMED_AXES)
    if axis not in ("hinge", "twist"):
        return _world_axis(axis)
    b = list(bone_names).index(rotation.bone)
    children = np.flatnonzero(np.asarray(bone_parents) == b)
    if len(children) == 0:
        raise KgarmentError(f"axis {axis!r} needs a bone with a child; {rotation.bone!r} has none")
    d_b = rest_joints[children[0]] - rest_joints[b]
    if axis == "twist":
        return d_b / np.linalg.norm(d_b)
    p = int(bone_parents[b])
    d_p = rest_joints[b] - rest_joints[p]
    h = np.cross(d_p, d_b)
    s = np.linalg.norm(h) / (np.linalg.norm(d_p) * np.linalg.norm(d_b))
    if s < 0.05:
        raise KgarmentError(
            f"axis 'hinge' of bone {rotation.bone!r} is undefined: the joint is straight at rest; give x, y, z or a vector"
        )
    return h / np.linalg.norm(h)


def rotation_matrix(axis: np.ndarray, degrees: float) -> np.ndarray:
    """(3, 3) rotation about the unit ``axis`` (3,) by ``degrees`` (right-hand rule)."""
    a = np.deg2rad(degrees)
    k = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    return np.eye(3) + np.sin(a) * k + (1 - np.cos(a)) * (k @ k)


def bone_rotations(rotations, bone_names, bone_parents, rest_joints) -> dict[str, np.ndarray]:
    """Compose the rotations per bone: {bone: (3, 3)}; unknown bones raise KgarmentError."""
    out: dict[str, np.ndarray] = {}
    for r in rotations:
        if r.bone not in bone_names:
            raise unknown("bone", r.bone, bone_names)
        R = rotation_matrix(resolve_axis(r, bone_names, bone_parents, rest_joints), r.degrees)
        out[r.bone] = R @ out.get(r.bone, np.eye(3))
    return out


# ---------------------------------------------------------------------------------------
# The built-in library. Left-side definitions; see module docstring for sign conventions
# (about +x: the top of the spine goes forward; an arm or leg hanging down goes back).

def _L(*rots) -> tuple[Rotation, ...]:
    return tuple(Rotation(b, a, d) for b, a, d in rots)


_ARM_FORWARD = _L(("clavicle.L", "-x", 10.0), ("upperarm01.L", "-x", 33.0))
_ARM_RAISE = _L(("upperarm01.L", "twist", 29.0), ("upperarm01.L", "-y", 46.0))
_ARM_FLEX = _L(("lowerarm01.L", "hinge", 46.0))
# Anny's rest elbow is already bent about 42 degrees; "straightened fully" leaves 2.
_ARM_EXT = _L(("lowerarm01.L", "hinge", -40.0))
_ARM_BACK = _L(("upperarm01.L", "x", 30.0))
_ARM_DOWN = _L(("upperarm01.L", "y", 25.0))
_KNEE = _L(("lowerleg01.L", "x", 60.0))
_HIP_FLEX = _L(("upperleg01.L", "-x", 45.0))
_HIP_EXT = _L(("upperleg01.L", "x", 20.0))
_HIP_ABD = _L(("upperleg01.L", "-y", 30.0))
_BEND = (
    _L(("spine03", "x", 37.0), ("spine01", "x", 17.0), ("neck01", "x", -11.0))
    + _L(("clavicle.L", "-x", 5.0), ("upperarm01.L", "-x", 15.0), ("lowerarm01.L", "hinge", 10.0))
)
_SLOUCH = _L(("spine02", "x", 12.0), ("spine01", "x", 12.0), ("neck01", "x", -10.0), ("clavicle.L", "-z", 10.0))

# name -> (left-side rotations, description, sided?) ; paper motions first
_SIDED = {
    "arms_forward": (_ARM_FORWARD, "shoulder flexion 43 deg (10 clavicle + 33 shoulder)"),
    "arms_raise": (_ARM_RAISE, "abduction 46 deg to near horizontal + 29 deg upper-arm rotation"),
    "arm_flexion": (_ARM_FLEX, "elbow flexion by 46 deg more"),
    "arm_extension": (_ARM_EXT, "elbow straightened (40 deg)"),
    "arm_back": (_ARM_BACK, "shoulder extension 30 deg"),
    "arm_down": (_ARM_DOWN, "shoulder adduction 25 deg"),
    "knee_flexion": (_KNEE, "knee flexion 60 deg"),
    "hip_flexion": (_HIP_FLEX, "hip flexion 45 deg"),
    "hip_extension": (_HIP_EXT, "hip extension 20 deg"),
    "hip_abduction": (_HIP_ABD, "hip abduction 30 deg"),
}
_SYMMETRIC = {
    "bend_forward": (_BEND, "spine flexion 37 + 17 deg, neck -11, clavicles and arms slightly forward"),
    "slouch": (_SLOUCH, "upper spine flexion 24 deg, shoulders rolled forward 10 deg"),
}
_DIRECTED = {
    "torso_twist_left": (_L(("spine03", "z", 20.0), ("spine01", "z", 15.0)), "torso turned 35 deg to the left"),
    "torso_twist_right": (_L(("spine03", "-z", 20.0), ("spine01", "-z", 15.0)), "torso turned 35 deg to the right"),
    "side_bend_left": (_L(("spine03", "y", 15.0), ("spine01", "y", 10.0)), "torso bent 25 deg to the left"),
    "side_bend_right": (_L(("spine03", "-y", 15.0), ("spine01", "-y", 10.0)), "torso bent 25 deg to the right"),
}

PAPER_MOTIONS = ("arms_forward", "arms_raise", "arm_flexion", "arm_extension", "bend_forward")


def _both(rots):
    mirrored = tuple(r.mirrored() for r in rots if r.bone.endswith(".L"))
    return rots + mirrored


def builtin_motions() -> dict[str, Motion]:
    """All built-in motions by name (paper motions first)."""
    lib: dict[str, Motion] = {}
    for name, (rots, desc) in _SIDED.items():
        lib[name] = Motion(name, (_both(rots),), desc + " (both sides)")
        lib[f"{name}.left"] = Motion(f"{name}.left", (rots,), desc + " (left)")
        lib[f"{name}.right"] = Motion(f"{name}.right", (tuple(r.mirrored() for r in rots),), desc + " (right)")
    for name, (rots, desc) in _SYMMETRIC.items():
        lib[name] = Motion(name, (_both(rots),), desc)
    for name, (rots, desc) in _DIRECTED.items():
        lib[name] = Motion(name, (rots,), desc)
    order = list(PAPER_MOTIONS) + [n for n in lib if n not in PAPER_MOTIONS]
    return {n: lib[n] for n in order}


@dataclass
class MotionLibrary:
    """Built-in motions plus user-defined ones (from a problem file)."""

    user: dict[str, Motion] = field(default_factory=dict)

    def all(self) -> dict[str, Motion]:
        return {**builtin_motions(), **self.user}

    def get(self, name: str) -> Motion:
        lib = self.all()
        if name not in lib:
            raise unknown("motion", name, lib)
        return lib[name]
