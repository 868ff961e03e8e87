"""Editing from the page: the tools on a clicked garment point, clutch actions, undo.

A click arrives as a garment face and barycentric coordinates (the page maps a ray in
the displayed pose to those); the point is mapped to the rest garment, where every edit is
made (:class:`~kgarment.studio.state.StudioState`), so an edit in any pose changes the
same cloth.  Failing edits raise :class:`~kgarment.errors.KgarmentError` before changing
anything; the page shows the message.
"""

from __future__ import annotations

import logging

import numpy as np

from kgarment.errors import KgarmentError
from kgarment.studio.page import Page
from kgarment.studio.placement import clutch_from_landmarks, clutch_from_points, nearest_clutch
from kgarment.studio.settings import BRUSH_TOOLS

log = logging.getLogger(__name__)
CENTRE = (1 / 3, 1 / 3, 1 / 3)
HINTS = {"place clutch": "click the clutch's start on the garment, then a point it should head to",
         "move clutch": "click where the selected clutch should start",
         "aim clutch": "click a point the selected clutch should head to",
         "select": "click a clutch to select it; drag to turn the view"}


class Editor:
    """The edit tools of the page (see the module docstring).

    selected : name of the selected clutch or None;  pending_start : (3,) rest point, m, of
    a clutch being placed (its start is clicked, its direction not yet), or None.
    """

    def __init__(self, page: Page):
        self.page = page
        self.selected: str | None = None
        self.pending_start: np.ndarray | None = None

    def reset(self) -> None:
        self.selected, self.pending_start = None, None

    def set_tool(self, tool: str) -> None:
        """Switch the tool (a clutch half placed is dropped) and say how to use it."""
        page = self.page
        page.settings.tool = tool
        self.pending_start = None
        page.say(HINTS.get(tool, f"{tool}: click or drag on the garment (radius {page.settings.radius:.3f} m)"))
        page.refresh(scene=True)

    # ----- clicks -----------------------------------------------------------------------
    def click_face(self, face: int, bary=CENTRE) -> None:
        """A click on the garment at (face, barycentric (3,)), by the current tool."""
        page = self.page
        st, s = page.state, page.settings
        tool = s.tool
        with page.lock:
            p = st.rest_point(int(face), bary)
            if tool in BRUSH_TOOLS:
                layer, value = BRUSH_TOOLS[tool]
                n = st.paint(int(face), p, s.radius, value, layer, s.brush_mode)
                page.say(f"{tool}: {n} faces changed at face {face}")
            elif tool == "place clutch":
                self._place(p)
            elif tool in ("move clutch", "aim clutch"):
                if self.selected is None:
                    raise KgarmentError(f"{tool}: select a clutch first (Edit tab, or click it with 'select')")
                if tool == "move clutch":
                    st.move_clutch(self.selected, p)
                else:
                    st.aim_clutch(self.selected, p)
                page.say(f"clutch {self.selected} {'moved' if tool == 'move clutch' else 'aimed'}")
            else:
                name = nearest_clutch(st.strips(), p)
                if name is not None:
                    self.select_clutch(name)
                page.say(f"face {face} at {np.round(p, 3).tolist()} m" + (f"; clutch {name} selected" if name else ""))
            page.refresh(scene=True, clutch=True)

    def _place(self, p: np.ndarray) -> None:
        page = self.page
        if self.pending_start is None:
            self.pending_start = p
            page.say("clutch start set: now click where the clutch should head")
            return
        start, self.pending_start = self.pending_start, None
        spec = clutch_from_points(page.state.new_clutch_name(), start, p, **page.clutch_defaults())
        page.state.add_clutch(spec)
        self.selected = spec.name
        page.say(f"clutch {spec.name} placed ({100 * spec.length:.1f} cm x {100 * spec.width:.1f} cm)")

    def dab(self, face: int, bary, start: bool) -> None:
        """One dab of a brush stroke dragged over the garment (``start``: its first dab,
        which opens one undo step for the whole stroke); other tools ignore drags."""
        page = self.page
        if page.settings.tool not in BRUSH_TOOLS:
            return
        layer, value = BRUSH_TOOLS[page.settings.tool]
        with page.lock:
            s = page.settings
            p = page.state.rest_point(face, bary)
            page.state.paint(face, p, s.radius, value, layer, s.brush_mode, record=start)
            page.refresh(scene=True)

    # ----- clutches ---------------------------------------------------------------------
    def select_clutch(self, name: str | None) -> None:
        if name is not None:
            self.page.state.clutch(name)
        self.selected = name
        self.page.refresh(clutch=True, scene=True)

    def add_clutch_at_landmarks(self, start: str, towards: str) -> None:
        page = self.page
        base = start.replace(".", "_")
        spec = clutch_from_landmarks(page.state.new_clutch_name(base), start, towards, **page.clutch_defaults())
        page.state.add_clutch(spec)
        self.selected = spec.name
        page.say(f"clutch {spec.name} placed at {start}, heading to {towards}")
        page.refresh(clutch=True, scene=True)

    def edit_selected(self, **changes) -> None:
        """Change the selected clutch (length, width, ...); on error the controls go back."""
        if self.selected is None:
            return
        try:
            strip = self.page.state.edit_clutch(self.selected, **changes)
        except KgarmentError:
            self.page.refresh(clutch=True)
            raise
        self.selected = strip.name
        self.page.refresh(clutch=True, scene=True)

    def delete_selected(self) -> None:
        if self.selected is None:
            raise KgarmentError("no clutch selected")
        name = self.selected
        self.page.state.delete_clutch(name)
        self.selected = None
        self.page.say(f"clutch {name} deleted")
        self.page.refresh(clutch=True, scene=True)

    # ----- layers -----------------------------------------------------------------------
    def clear_design(self) -> None:
        """No reinforcement (undoable)."""
        st = self.page.state
        st.set_layer("design", np.zeros(st.n_faces, bool))
        self.page.say("reinforcement cleared (undo restores it)")
        self.page.refresh(scene=True)

    def undo(self) -> None:
        st = self.page.state
        self.page.say("undone" if st.undo() else "nothing to undo")
        if self.selected not in st.clutch_names():
            self.selected = None
        self.page.refresh(clutch=True, scene=True)
