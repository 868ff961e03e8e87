"""Default clutch layouts for the paper's experiments, placed by landmarks on the body.

Layouts are lists of :class:`ClutchSpec` with 3D start points and 3D directions in the
body's rest coordinates, so they fit any garment and subdivision level on that body.

=================  =====================================================================
``arm_flexion``    one 8 cm clutch over the outer (back of the) right elbow, taut (prestrain 0.9)
``arm_extension``  one 8 cm clutch over the inside of the right elbow, onto the forearm, taut too
``sleeve``         both of the above (the flexion + extension sleeve)
``shirt``          13.5 cm across the upper back, two 10 cm on the lower back in a V
                   60 degrees from horizontal (the three-motion shirt)
``long_sleeve``    the shirt's three plus the sleeve's two (five clutches, five motions)
=================  =====================================================================
"""

from __future__ import annotations

import numpy as np

from kgarment.body.model import Body
from kgarment.clutch.landmarks import body_landmarks
from kgarment.clutch.spec import ClutchSpec
from kgarment.errors import unknown

ELBOW_PRESTRAIN = 0.9  # an elbow clutch's rest length over its laid length (fitted taut)
LAYOUTS = ("arm_flexion", "arm_extension", "sleeve", "shirt", "long_sleeve")


def _unit(v):
    return np.asarray(v, dtype=float) / np.linalg.norm(v)


def _arm_axes(body: Body, side: str):
    J = body.rest_joints
    s = J[body.bone_index(f"upperarm02.{side}")]
    e = J[body.bone_index(f"lowerarm01.{side}")]
    w = J[body.bone_index(f"wrist.{side}")]
    return _unit(e - s), _unit(w - e)


def _pt(p) -> tuple[float, float, float]:
    return tuple(float(x) for x in p)


def _elbow(body: Body, L, side: str, which: str) -> ClutchSpec:
    upper, _ = _arm_axes(body, side)
    if which == "flexion":
        # centred on the outer elbow, running down the arm over the olecranon; taut from the
        # start (prestrain 0.9): a slack clutch lets the sleeve turn about the frictionless arm
        # until the clutch lies over the hinge axis, where flexion hardly stretches it (measured:
        # ~20 degrees of turn, rho ON 0.13 at preview resolution; taut, 1.74)
        start = L[f"elbow_outer.{side}"] - 0.04 * upper
        return ClutchSpec(f"elbow_outer.{side}", _pt(start), _pt(upper), 0.08, prestrain=ELBOW_PRESTRAIN)
    # taut as well: laid at its length (prestrain 1) the ON cable only takes load from a fifth of
    # extension on (the cloth round its ends gives first); fitted as the outer clutch is, it
    # pulls 24-103 N at rest and resists from the start (extension alone, 800 N: rho ON 1.30 -> 1.65;
    # the paper: 1.74; docs/notes/selective.md)
    start = L[f"elbow_inner.{side}"] - 0.03 * upper
    return ClutchSpec(f"elbow_inner.{side}", _pt(start), _pt(upper), 0.08, prestrain=ELBOW_PRESTRAIN)


def _back(L) -> list[ClutchSpec]:
    specs = [ClutchSpec("upper_back", _pt(L["upper_back"] - [0.0675, 0, 0]), (1.0, 0.0, 0.0), 0.135)]
    c, s = np.cos(np.radians(60)), np.sin(np.radians(60))
    for side, sx in (("L", 1.0), ("R", -1.0)):
        start = L["lower_back"] + [sx * 0.015, 0, 0]
        specs.append(ClutchSpec(f"lower_back.{side}", _pt(start), (sx * c, 0.0, s), 0.10))
    return specs


def layout_names(name: str, side: str = "R") -> list[str]:
    """The clutch names of the named layout, in :func:`default_layout`'s order (no body needed)."""
    if name not in LAYOUTS:
        raise unknown("clutch layout", name, LAYOUTS)
    back = ["upper_back", "lower_back.L", "lower_back.R"]
    arm = {"arm_flexion": [f"elbow_outer.{side}"], "arm_extension": [f"elbow_inner.{side}"]}
    arm["sleeve"] = arm["arm_flexion"] + arm["arm_extension"]
    return {**arm, "shirt": back, "long_sleeve": back + arm["sleeve"]}[name]


def default_layout(name: str, body: Body, side: str = "R") -> list[ClutchSpec]:
    """The named default layout on ``body`` (arm clutches on ``side``, "L" or "R")."""
    if name not in LAYOUTS:
        raise unknown("clutch layout", name, LAYOUTS)
    L = body_landmarks(body)
    if name == "arm_flexion":
        return [_elbow(body, L, side, "flexion")]
    if name == "arm_extension":
        return [_elbow(body, L, side, "extension")]
    if name == "sleeve":
        return [_elbow(body, L, side, "flexion"), _elbow(body, L, side, "extension")]
    if name == "shirt":
        return _back(L)
    return _back(L) + [_elbow(body, L, side, "flexion"), _elbow(body, L, side, "extension")]
