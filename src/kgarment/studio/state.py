"""What the studio edits, without any web wiring: design, attachments, clutches, budget.

A :class:`StudioState` holds one problem's body and garment with the editable layers:

- ``design`` (m,) bool, reinforced faces (the manual design, "A");
- ``attached`` (m,) bool, faces glued to the body (starts as the garment's rings);
- ``clutches``, a list of :class:`~kgarment.clutch.ClutchSpec` (rest coordinates);
- the budget ``problem.design.beso.target_area`` (share of the garment's area).

Every edit bumps ``revision`` and marks the state ``dirty`` until it is saved; edits go
through methods that validate first and change nothing on error, and each can be undone.
All methods hold ``lock`` so the page's callbacks and background jobs may share a state.
"""

from __future__ import annotations

import dataclasses
import logging
import threading
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from kgarment.body import Body
from kgarment.clutch import ClutchSpec, ClutchStrip, MeshTopology
from kgarment.clutch.errors import ClutchError
from kgarment.clutch.landmarks import body_landmarks
from kgarment.constants import BUDGET_RANGE
from kgarment.errors import KgarmentError
from kgarment.garment import Garment
from kgarment.problem import Problem, clutch_specs
from kgarment.studio import brush, placement

log = logging.getLogger(__name__)
UNDO_DEPTH = 50
LAYERS = ("design", "attached")


@dataclass(frozen=True)
class Snapshot:
    """The editable layers at one moment (for undo): design, attached (m,) bool;
    clutches; target_area (the budget, share of the garment's area); activation (the
    problem's per-motion activation sets)."""

    design: np.ndarray
    attached: np.ndarray
    clutches: tuple[ClutchSpec, ...]
    target_area: float
    activation: tuple = ()


class StudioState:
    """The editable layers of one problem (see the module docstring).

    problem : Problem; body : Body; garment : Garment (its ``attached`` is the starting
    attachment layer); clutches : ClutchSpec list (default: the problem's); design,
    attached : (m,) bool or None.
    """

    def __init__(self, problem: Problem, body: Body, garment: Garment, clutches: list[ClutchSpec] | None = None,
                 design: np.ndarray | None = None, attached: np.ndarray | None = None):
        self.lock = threading.RLock()
        self.problem = problem
        self.body = body
        self.base_garment = garment
        m = garment.n_faces
        self.topology = MeshTopology(garment.rest_vertices, garment.faces)
        self.graph = brush.FaceGraph(garment.rest_vertices, garment.faces)
        self.landmarks = _landmarks(body)
        self.design = _mask(design, m, "design", False)
        self.attached = _mask(attached, m, "attachments", None, garment.attached)
        specs = list(clutch_specs(problem, body) if clutches is None else clutches)
        self._strips: dict[ClutchSpec, ClutchStrip] = {}
        for s in specs:  # every clutch must fit the garment; the first that does not is the error
            self._strip(s)
        self.clutches: list[ClutchSpec] = specs
        self.revision = 0
        self.dirty = False
        self._undo: list[Snapshot] = []

    # ----- read-only views --------------------------------------------------------------
    @property
    def n_faces(self) -> int:
        return self.base_garment.n_faces

    @property
    def areas(self) -> np.ndarray:
        """(m,) rest face areas, m^2."""
        return self.graph.areas

    @property
    def garment(self) -> Garment:
        """The garment with the current attachment layer."""
        return dataclasses.replace(self.base_garment, attached=self.attached.copy())

    @property
    def budget(self) -> float:
        return float(self.problem.design.beso.target_area)

    def coverage(self) -> float:
        """Reinforced share of the garment's area, in [0, 1]."""
        return brush.coverage(self.design, self.areas)

    def clutch_names(self) -> list[str]:
        return [c.name for c in self.clutches]

    def clutch(self, name: str) -> ClutchSpec:
        for c in self.clutches:
            if c.name == name:
                return c
        raise KgarmentError(f"no clutch named {name!r}; clutches: {', '.join(self.clutch_names()) or '(none)'}")

    def strips(self) -> list[ClutchStrip]:
        with self.lock:
            return [self._strip(s) for s in self.clutches]

    def _strip(self, spec: ClutchSpec) -> ClutchStrip:
        if spec not in self._strips:
            self._strips[spec] = placement.build(spec, self.topology, self.landmarks)
        return self._strips[spec]

    def rest_point(self, face: int, bary) -> np.ndarray:
        """(3,) rest position of a (face, barycentric (3,)) point of the garment."""
        if not 0 <= face < self.n_faces:
            raise KgarmentError(f"face {face} is not a face of the garment (0..{self.n_faces - 1})")
        return self.graph.rest_point(self.base_garment.rest_vertices, self.base_garment.faces, face, bary)

    # ----- undo -------------------------------------------------------------------------
    def snapshot(self) -> Snapshot:
        return Snapshot(self.design.copy(), self.attached.copy(), tuple(self.clutches), self.budget,
                        self.problem.activation)

    def _record(self) -> None:
        self._undo.append(self.snapshot())
        del self._undo[:-UNDO_DEPTH]

    def _changed(self) -> None:
        self.revision += 1
        self.dirty = True

    def undo(self) -> bool:
        """Restore the layers before the last edit; False when there is nothing to undo."""
        with self.lock:
            if not self._undo:
                return False
            s = self._undo.pop()
            self.design, self.attached, self.clutches = s.design, s.attached, list(s.clutches)
            self._set_budget(s.target_area)
            self.problem = dataclasses.replace(self.problem, activation=s.activation)
            self._changed()
            return True

    def mark_saved(self) -> None:
        self.dirty = False

    # ----- painting ---------------------------------------------------------------------
    def paint(self, face: int, point, radius: float, value: bool = True, layer: str = "design",
              mode: str = "surface", record: bool = True) -> int:
        """Set the faces under a brush dab to ``value`` on ``layer`` ("design" or
        "attached"); ``point`` (3,) rest coordinates on ``face``. Returns faces changed.
        ``record=False`` for the later dabs of one stroke (one undo step per stroke)."""
        if layer not in LAYERS:
            raise KgarmentError(f"layer {layer!r}; allowed: {', '.join(LAYERS)}")
        with self.lock:
            try:
                faces = brush.brush_faces(self.graph, int(face), point, float(radius), mode)
            except ValueError as exc:
                raise KgarmentError(str(exc)) from None
            new, changed = brush.apply(getattr(self, layer), faces, bool(value))
            if changed:
                if record:
                    self._record()
                setattr(self, layer, new)
                self._changed()
            return changed

    def set_layer(self, layer: str, mask, record: bool = True) -> None:
        """Replace a whole layer with ``mask`` (m,) bool."""
        if layer not in LAYERS:
            raise KgarmentError(f"layer {layer!r}; allowed: {', '.join(LAYERS)}")
        new = _mask(mask, self.n_faces, layer, False)
        with self.lock:
            if record:
                self._record()
            setattr(self, layer, new)
            self._changed()

    def set_budget(self, target_area: float) -> None:
        """The reinforced-area budget A* in BUDGET_RANGE ([0.01, 1]; problem.design.beso.target_area)."""
        lo, hi = BUDGET_RANGE
        if not lo <= float(target_area) <= hi:
            raise KgarmentError(f"budget {target_area!r} is outside [{lo:g}, {hi:g}]")
        with self.lock:
            if float(target_area) != self.budget:
                self._record()
                self._set_budget(float(target_area))
                self._changed()

    def _set_budget(self, value: float) -> None:
        d = self.problem.design
        beso = dataclasses.replace(d.beso, target_area=float(value))
        self.problem = dataclasses.replace(self.problem, design=dataclasses.replace(d, beso=beso))

    def activation_set(self, motion: str) -> list[str]:
        """The clutches ``motion`` switches on (all of them unless the problem says otherwise)."""
        given = self.problem.activation_of(motion)
        return list(self.clutch_names()) if given is None else [n for n in given if n in self.clutch_names()]

    def set_activation(self, motion: str, clutches) -> None:
        """The clutches ``motion`` switches on ([motions.activation]; every clutch, or an
        empty list, for all of them): names of this garment's clutches."""
        if motion not in self.problem.motions:
            raise KgarmentError(f"{motion!r} is not a motion of this problem; allowed: {', '.join(self.problem.motions)}")
        names = list(dict.fromkeys(clutches))
        unknown = [n for n in names if n not in self.clutch_names()]
        if unknown:
            raise KgarmentError(f"{motion} switches on unknown clutch {unknown[0]!r}; the clutches are: "
                                f"{', '.join(self.clutch_names()) or 'none'}")
        with self.lock:
            if set(names) in (set(), set(self.clutch_names())):
                names = []  # every clutch: the default, written nowhere
            old = self.problem.activation
            new = tuple((m, v) for m, v in old if m != motion) + \
                (((motion, tuple((n, 1.0) for n in names)),) if names else ())
            if dict(new) != dict(old):
                self._record()
                self.problem = dataclasses.replace(self.problem, activation=new)
                self._changed()

    def _rename_in_sets(self, old: str, new: str | None) -> None:
        """Clutch ``old`` renamed to ``new`` (None: deleted) in every activation set; a set
        left empty means every clutch again."""
        sets = []
        for m, v in self.problem.activation:
            v = tuple((new, a) if n == old else (n, a) for n, a in v if n != old or new is not None)
            if v:
                sets.append((m, v))
        self.problem = dataclasses.replace(self.problem, activation=tuple(sets))

    # ----- clutches ---------------------------------------------------------------------
    def add_clutch(self, spec: ClutchSpec) -> ClutchStrip:
        """Add a clutch (its name must be new and it must fit on the garment)."""
        with self.lock:
            if spec.name in self.clutch_names():
                raise ClutchError(f"a clutch named {spec.name!r} exists already")
            strip = self._strip(spec)
            self._record()
            self.clutches.append(spec)
            self._changed()
            return strip

    def replace_clutch(self, name: str, spec: ClutchSpec) -> ClutchStrip:
        """Replace clutch ``name`` by ``spec`` (which may rename it); nothing changes on error."""
        with self.lock:
            old = self.clutch(name)
            if spec.name != name and spec.name in self.clutch_names():
                raise ClutchError(f"a clutch named {spec.name!r} exists already")
            strip = self._strip(spec)
            if spec != old:
                self._record()
                self.clutches[self.clutches.index(old)] = spec
                if spec.name != name:
                    self._rename_in_sets(name, spec.name)
                self._changed()
            return strip

    def edit_clutch(self, name: str, /, **changes) -> ClutchStrip:
        """Change fields of clutch ``name`` (length, width, prestrain, clip, name)."""
        allowed = {"length", "width", "prestrain", "clip", "name"}
        bad = set(changes) - allowed
        if bad:
            raise KgarmentError(f"cannot change {sorted(bad)}; allowed: {sorted(allowed)}")
        with self.lock:
            return self.replace_clutch(name, dataclasses.replace(self.clutch(name), **changes))

    def move_clutch(self, name: str, start) -> ClutchStrip:
        """Move clutch ``name`` to start at ``start`` (3,) (rest coordinates), same heading."""
        with self.lock:
            spec = placement.moved(self.clutch(name), start, self.topology, self.landmarks)
            return self.replace_clutch(name, spec)

    def aim_clutch(self, name: str, towards) -> ClutchStrip:
        """Turn clutch ``name`` to head towards ``towards`` (3,) (rest coordinates)."""
        with self.lock:
            spec = placement.aimed(self.clutch(name), towards, self.topology, self.landmarks)
            return self.replace_clutch(name, spec)

    def delete_clutch(self, name: str) -> None:
        with self.lock:
            spec = self.clutch(name)
            self._record()
            self.clutches.remove(spec)
            self._rename_in_sets(name, None)
            self._changed()

    def new_clutch_name(self, base: str = "clutch") -> str:
        return placement.unique_name(self.clutch_names(), base)


def _landmarks(body: Body) -> Mapping | None:
    if not body.rigged:
        return None
    try:
        return body_landmarks(body)
    except KgarmentError as exc:  # an unusual rig: clutches by point only
        log.warning("no clutch landmarks on this body: %s", exc)
        return None


def _mask(value, m: int, what: str, fill, default=None) -> np.ndarray:
    if value is None:
        return np.full(m, bool(fill)) if default is None else np.asarray(default, bool).copy()
    a = np.asarray(value)
    if a.shape != (m,):
        raise KgarmentError(f"the {what} has {a.size} faces, the garment {m}")
    return a.astype(bool) if a.dtype == bool else a > 0.5
