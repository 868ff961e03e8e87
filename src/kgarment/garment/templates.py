"""Garment templates: face regions on a rigged body chosen by bones and cut planes.

A face belongs to a template when its dominant bone is in ``bones`` and it lies on the
kept side of every :class:`Cut` that applies to its bone. A cut is the plane through
``joint_a + t (joint_b - joint_a)`` with normal ``joint_b - joint_a`` (rest joints); it
keeps the side of ``keep`` (``"a"`` or ``"b"``) and applies only to faces whose dominant
bone is in ``applies_to`` (so a sleeve cut does not slice the torso). Attachment rings
(faces glued to the body, docs/method/index.md, "The garment") sit at the boundary loops made by the cuts
named in ``attach``; regions ending at an excluded bone (neck, hands) are free openings.
"""

from __future__ import annotations

from dataclasses import dataclass

SIDES = ("L", "R")
_ARM = ("upperarm01", "upperarm02", "lowerarm01", "lowerarm02")
_TORSO = ("spine05", "spine04", "spine03", "spine02", "spine01")
_LEG = ("upperleg01", "upperleg02", "lowerleg01", "lowerleg02")


@dataclass(frozen=True)
class Cut:
    name: str
    applies_to: tuple[str, ...]
    joint_a: str
    joint_b: str
    t: float
    keep: str = "a"


@dataclass(frozen=True)
class GarmentTemplate:
    name: str
    description: str
    bones: tuple[str, ...]
    cuts: tuple[Cut, ...]
    attach: tuple[str, ...]


def _s(names, side):
    return tuple(f"{n}.{side}" for n in names)


def _both(names):
    return _s(names, "L") + _s(names, "R")


def _hem(bones=_TORSO + ("pelvis.L", "pelvis.R")):
    return Cut("hem", bones, "spine05", "spine01", 0.12, keep="b")


def _shirt(name, sleeve_joint_a, sleeve_joint_b, t, desc, arm_bones, attach):
    cuts = [_hem()]
    for side in SIDES:
        cuts.append(Cut(f"cuff.{side}", _s(arm_bones, side), f"{sleeve_joint_a}.{side}", f"{sleeve_joint_b}.{side}", t))
    bones = _TORSO + _both(("clavicle", "shoulder01")) + _both(arm_bones) + ("pelvis.L", "pelvis.R")
    return GarmentTemplate(name, desc, bones, tuple(cuts), attach)


def _sleeve(side):
    bones = _s(("upperarm01", "upperarm02", "lowerarm01", "lowerarm02"), side)
    return GarmentTemplate(
        f"arm_sleeve.{'left' if side == 'L' else 'right'}",
        "sleeve from mid upper arm to mid forearm over the elbow, both ends attached",
        bones,
        (
            Cut("upper", bones, f"upperarm01.{side}", f"lowerarm01.{side}", 0.45, keep="b"),
            Cut("lower", bones, f"lowerarm01.{side}", f"wrist.{side}", 0.7, keep="a"),
        ),
        ("upper", "lower"),
    )


def _knee(side):
    bones = _s(("upperleg01", "upperleg02", "lowerleg01", "lowerleg02"), side)
    return GarmentTemplate(
        f"knee_sleeve.{'left' if side == 'L' else 'right'}",
        "sleeve from lower thigh to upper shin over the knee, both ends attached",
        bones,
        (
            Cut("upper", bones, f"upperleg01.{side}", f"lowerleg01.{side}", 0.6, keep="b"),
            Cut("lower", bones, f"lowerleg01.{side}", f"foot.{side}", 0.35, keep="a"),
        ),
        ("upper", "lower"),
    )


def builtin_templates() -> dict[str, GarmentTemplate]:
    t = [
        _shirt("short_sleeve_shirt", "upperarm01", "lowerarm01", 0.5,
               "T-shirt: torso from the hips to the neck, sleeves to mid upper arm; hem attached",
               ("upperarm01", "upperarm02"), ("hem",)),
        _shirt("long_sleeve_shirt", "lowerarm01", "wrist", 0.9,
               "long-sleeve shirt to the wrists; hem and both cuffs attached",
               _ARM, ("hem", "cuff.L", "cuff.R")),
        _sleeve("L"), _sleeve("R"),
        GarmentTemplate(
            "leggings", "from the waist to the ankles; waist and both ankles attached",
            _TORSO[:2] + ("pelvis.L", "pelvis.R") + _both(_LEG),
            (
                Cut("waist", _TORSO[:2] + ("pelvis.L", "pelvis.R"), "spine05", "spine01", 0.12, keep="a"),
                Cut("ankle.L", _s(_LEG, "L"), "lowerleg01.L", "foot.L", 0.85),
                Cut("ankle.R", _s(_LEG, "R"), "lowerleg01.R", "foot.R", 0.85),
            ),
            ("waist", "ankle.L", "ankle.R"),
        ),
        _knee("L"), _knee("R"),
    ]
    return {g.name: g for g in t}
