"""The states a motion is solved in.

A state is a motion under one activation of the clutches; its key is a
:class:`~kgarment.case.keys.StateKey` ``(motion, label)`` (:mod:`kgarment.case.keys`
formats and parses every string form).
"""

from __future__ import annotations

from kgarment.case.keys import LOCK, SOLO, Kind, StateKey, format_label
from kgarment.errors import unknown
from kgarment.problem.spec import OBJECTIVE_NAMES

__all__ = ["LOCK", "SOLO", "Kind", "StateKey", "states_needed"]


def states_needed(kind: str) -> tuple[str, ...]:
    """Activation states an objective of ``kind`` needs: ("on", "off"), ("on",) or ("none",)."""
    if kind == "active":
        return (format_label(Kind.ON), format_label(Kind.OFF))
    if kind == "compliance":
        return (format_label(Kind.ON),)
    if kind == "passive":
        return (format_label(Kind.NONE),)
    raise unknown("objective", kind, OBJECTIVE_NAMES)
