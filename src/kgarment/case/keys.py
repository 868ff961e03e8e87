"""State keys and every string form that names a state, a start or a metrics column.

A state is a motion under one activation of the clutches.  Its key is a
:class:`StateKey` ``(motion, label)``, the label one of the :class:`Kind` of states:

* ``"on"`` (:attr:`Kind.ON`): the motion's activation set;
* ``"off"`` (:attr:`Kind.OFF`): every clutch off;
* ``"none"`` (:attr:`Kind.NONE`): a garment without clutches;
* ``"lock:OTHER"`` (:attr:`Kind.LOCK`): the motion under another motion's activation set;
* ``"solo:CLUTCH"`` (:attr:`Kind.SOLO`): one clutch of the motion's set alone ON;
* anything else (:attr:`Kind.CUSTOM`): a label its caller chose (an activation's values
  ``"1,0,0.5"``, a clutch set's name ``"a+b"``, the rest pose's ``"on:MOTION"``).

The key stays a 2-tuple of strings (a :class:`~typing.NamedTuple`), so that dicts keyed by
it are looked up with ``(motion, "on")`` too and the key is what run folders hold.

The string forms, formatted and parsed here only (run folders written by earlier versions
hold the same forms):

* a state's name (``SimState.name``, the metrics' ``unconverged_states`` joined by ";"):
  ``MOTION[LABEL]`` (:meth:`StateKey.name`, :func:`parse_state_name`);
* a start of a state, its name with ``@TAG`` appended (:class:`Start`, :func:`started`):
  ``@full``, ``@skin-tight``, ``@put-on``, ``@continued``, ``@from-full``, one subdivision level
  down ``@levelL`` (:func:`level_name`), a continuation step ``@F`` (:func:`fraction_name`);
* a motion's name: a wearer's ``MOTION@BODY`` (:func:`wearer_motion`), a ``[design] early``
  pose ``MOTION@t`` (t to 2 decimals, :func:`early_motion`), a frame of the motion from rest
  ``MOTION@t`` (3 decimals, :func:`frame_motion`);
* a checkpoint's reference key ``MOTION|LABEL`` (:func:`checkpoint_key`);
* metrics columns: per state ``rho[MOTION:LABEL]``, ``energy[MOTION:LABEL]``, per clutch of
  an ON state ``tension[MOTION:CLUTCH]`` (:func:`state_column`), per motion ``term[MOTION]``
  and ``gain[MOTION]`` (:func:`motion_column`).  A motion's name holds no ``:``.
"""

from __future__ import annotations

import enum
import functools
from typing import NamedTuple

from kgarment.constants import BODY_SEP

LOCK = "lock:"  # state label prefix: a motion under another motion's activation set
SOLO = "solo:"  # state label prefix: a motion with one clutch of its set ON, the others OFF
START_SEP = "@"  # a start's tag follows a state's name after it
KEY_SEP = "|"  # a checkpoint's reference key: MOTION|LABEL

RHO = "rho"  # metrics column per state: relative energy density
ENERGY = "energy"  # metrics column per state: J stored in the reinforced faces and the clutches
TENSION = "tension"  # metrics column per motion and clutch: N along the clutch in the ON state
TERM = "term"  # metrics column per motion: its term of the objective
GAIN = "gain"  # metrics column per motion (with lockout): its term without the lock: states' penalty


class Kind(enum.Enum):
    """What a state's activation is (its label's form)."""

    ON = "on"
    OFF = "off"
    NONE = "none"
    LOCK = "lock"
    SOLO = "solo"
    CUSTOM = "custom"


class Start(enum.Enum):
    """The fixed start tags (``NAME@TAG``) under which a state is solved once more."""

    FULL = "full"  # from the fully reinforced garment's equilibrium (a design run's skin_start)
    SKIN_TIGHT = "skin-tight"  # from the skin-tight garment
    PUT_ON = "put-on"  # from the garment as put on one subdivision level down
    CONTINUED = "continued"  # on from where a solve ran out of iterations
    FROM_FULL = "from-full"  # along a design run's path, one level down (the evaluator's)


_PLAIN = {Kind.ON: "on", Kind.OFF: "off", Kind.NONE: "none"}
_PREFIX = {Kind.LOCK: LOCK, Kind.SOLO: SOLO}


def format_label(kind: Kind, clutch_set: str | None = None) -> str:
    """The label of a state of ``kind``; ``clutch_set``: the other motion (LOCK), the clutch
    (SOLO) or the label itself (CUSTOM)."""
    if kind in _PLAIN:
        if clutch_set is not None:
            raise ValueError(f"a {kind.value} state has no clutch set ({clutch_set!r})")
        return _PLAIN[kind]
    if not clutch_set:
        raise ValueError(f"a {kind.value} state needs its clutch set")
    if kind is Kind.CUSTOM:
        if parse_label(clutch_set)[0] is not Kind.CUSTOM:
            raise ValueError(f"{clutch_set!r} is the label of a {parse_label(clutch_set)[0].value} state")
        return clutch_set
    return _PREFIX[kind] + clutch_set


@functools.lru_cache(maxsize=4096)
def parse_label(label: str) -> tuple[Kind, str | None]:
    """(kind, clutch set) of a state label: the inverse of :func:`format_label`."""
    for kind, plain in _PLAIN.items():
        if label == plain:
            return kind, None
    for kind, prefix in _PREFIX.items():
        if label.startswith(prefix) and len(label) > len(prefix):
            return kind, label[len(prefix):]
    return Kind.CUSTOM, label


class StateKey(NamedTuple):
    """A state's identity: ``(motion, label)``, the label formatted by :func:`format_label`."""

    motion: str
    label: str

    @classmethod
    def of(cls, motion: str, kind: Kind, clutch_set: str | None = None) -> StateKey:
        """The key of ``motion``'s state of ``kind`` (``clutch_set``: :func:`format_label`)."""
        return cls(motion, format_label(kind, clutch_set))

    @classmethod
    def on(cls, motion: str) -> StateKey:
        return cls(motion, _PLAIN[Kind.ON])

    @classmethod
    def off(cls, motion: str) -> StateKey:
        return cls(motion, _PLAIN[Kind.OFF])

    @classmethod
    def lock(cls, motion: str, other: str) -> StateKey:
        return cls.of(motion, Kind.LOCK, other)

    @classmethod
    def solo(cls, motion: str, clutch: str) -> StateKey:
        return cls.of(motion, Kind.SOLO, clutch)

    @property
    def kind(self) -> Kind:
        return parse_label(self.label)[0]

    @property
    def clutch_set(self) -> str | None:
        """The other motion whose set a LOCK state has, the clutch a SOLO state has alone ON,
        a CUSTOM state's label; None otherwise."""
        return parse_label(self.label)[1]

    @property
    def name(self) -> str:
        """The state's name: ``MOTION[LABEL]``."""
        return f"{self.motion}[{self.label}]"


def key_of(key) -> StateKey:
    """``key`` ((motion, label), a StateKey or not) as a StateKey."""
    return key if isinstance(key, StateKey) else StateKey(*key)


def kind_of(label: str) -> Kind:
    """The kind of a state label."""
    return parse_label(label)[0]


def parse_state_name(name: str) -> tuple[StateKey, tuple[str, ...]]:
    """(key, start tags) of a state's name ``MOTION[LABEL]@TAG...`` (tags: :func:`started`,
    as written, e.g. ``("level1", "from-full")``)."""
    head, bracket, tail = name.rpartition("]")
    motion, open_, label = head.partition("[")
    if not (bracket and open_):
        raise ValueError(f"{name!r} is not a state name MOTION[LABEL]")
    tags = tuple(t for t in tail.split(START_SEP) if t) if tail else ()
    if tail and not tail.startswith(START_SEP):
        raise ValueError(f"{name!r}: a start tag follows {START_SEP!r}")
    return StateKey(motion, label), tags


def started(name: str, start: Start) -> str:
    """The name of the solve of state ``name`` from ``start``: ``NAME@TAG``."""
    return f"{name}{START_SEP}{start.value}"


def is_started(name: str, start: Start) -> bool:
    """Whether ``name`` is a solve from ``start`` (:func:`started`)."""
    return name.endswith(f"{START_SEP}{start.value}")


def level_name(name: str, level: int, start: Start | None = None) -> str:
    """The name of state ``name`` one subdivision level down at ``level`` (a level tag it has
    replaced), with ``start``'s tag after it."""
    base = name.split(f"{START_SEP}level")[0]
    return f"{base}{START_SEP}level{level}" + (f"{START_SEP}{start.value}" if start is not None else "")


def fraction_name(name: str, fraction: float) -> str:
    """The name of state ``name`` at the share ``fraction`` of its activation (a continuation step)."""
    return f"{name}{START_SEP}{fraction:g}"


def wearer_motion(motion: str, body: str) -> str:
    """The motion ``motion`` on wearer ``body``: ``MOTION@BODY``."""
    return f"{motion}{BODY_SEP}{body}"


def split_wearer(name: str) -> tuple[str, str | None]:
    """(motion, wearer) of a motion's name (wearer None for a one-body design's)."""
    motion, sep, body = name.partition(BODY_SEP)
    return motion, (body if sep else None)


def base_motion(name: str) -> str:
    """The motion a wearer's motion or a pose of it (``MOTION@...``) belongs to."""
    return name.partition(BODY_SEP)[0]


def early_motion(motion: str, t: float) -> str:
    """A ``[design] early`` pose: ``motion`` at the share ``t`` of its movement, ``MOTION@t``."""
    return f"{motion}{BODY_SEP}{t:.2f}"


def frame_motion(motion: str, t: float) -> str:
    """A frame of the motion from rest: ``motion`` at the share ``t``, ``MOTION@t``."""
    return f"{motion}{BODY_SEP}{t:.3f}"


def checkpoint_key(key) -> str:
    """A reference key as a checkpoint holds it: ``MOTION|LABEL``."""
    return KEY_SEP.join(key)


def parse_checkpoint_key(text: str) -> StateKey:
    """The inverse of :func:`checkpoint_key`."""
    motion, sep, label = str(text).partition(KEY_SEP)
    if not sep:
        raise ValueError(f"{text!r} is not a reference key MOTION{KEY_SEP}LABEL")
    return StateKey(motion, label)


def state_column(prefix: str, key) -> str:
    """A per-state metrics column: ``PREFIX[MOTION:LABEL]`` (``key``: (motion, label), or
    (motion, clutch) for :data:`TENSION`)."""
    return f"{prefix}[{state_text(key)}]"


def state_text(key) -> str:
    """A state in a curve's legend or a summary line: ``MOTION:LABEL`` (its column's bracket)."""
    return f"{key[0]}:{key[1]}"


def motion_column(prefix: str, motion: str) -> str:
    """A per-motion metrics column: ``PREFIX[MOTION]``."""
    return f"{prefix}[{motion}]"


def parse_column(column: str) -> tuple[str, str, str | None] | None:
    """(prefix, motion, label or None) of a per-state or per-motion metrics column, or None
    for another column ("area", "objective", ...)."""
    prefix, open_, rest = column.partition("[")
    if not (open_ and rest.endswith("]") and prefix):
        return None
    inner = rest[:-1]
    if prefix in (TERM, GAIN):
        return prefix, inner, None
    motion, colon, label = inner.partition(":")
    return (prefix, motion, label) if colon else None


def state_columns(row: dict, prefix: str) -> dict[StateKey, object]:
    """{StateKey: value} of a per-state metrics column (``prefix`` e.g. :data:`RHO`) in ``row``,
    in the row's order."""
    out = {}
    for col, v in row.items():
        p = parse_column(col)
        if p is not None and p[0] == prefix and p[2] is not None:
            out[StateKey(p[1], p[2])] = v
    return out


def motion_columns(row: dict, prefix: str) -> dict[str, float]:
    """{motion: value} of a per-motion metrics column (:data:`TERM`, :data:`GAIN`) in ``row``."""
    out = {}
    for col, v in row.items():
        p = parse_column(col)
        if p is not None and p[0] == prefix:
            out[p[1]] = float(v)
    return out
