"""The states a motion is solved in, and how they are named.

A state is a motion under one activation of the clutches.  Its key is ``(motion, label)``:
``"on"`` (the motion's activation set), ``"off"`` (every clutch off), ``"none"`` (a garment
without clutches), ``"lock:OTHER"`` (the motion under another motion's set) or
``"solo:CLUTCH"`` (one clutch of the motion's set alone ON).
"""

from __future__ import annotations

from kgarment.errors import unknown
from kgarment.problem.spec import OBJECTIVE_NAMES

StateKey = tuple[str, str]  # (motion, "on" | "off" | "none" | "lock:OTHER MOTION" | "solo:CLUTCH")
LOCK = "lock:"  # state label prefix: a motion under another motion's activation set
SOLO = "solo:"  # state label prefix: a motion with one clutch of its set ON, the others OFF


def states_needed(kind: str) -> tuple[str, ...]:
    """Activation states an objective of ``kind`` needs: ("on", "off"), ("on",) or ("none",)."""
    if kind == "active":
        return ("on", "off")
    if kind == "compliance":
        return ("on",)
    if kind == "passive":
        return ("none",)
    raise unknown("objective", kind, OBJECTIVE_NAMES)
