"""The studio's control panel (viser GUI): tabs View, Edit, Simulate, Optimise, File.

Every control calls an action of the studio or of one of its parts (``edit``, ``sims``,
``optimiser``) through ``studio.guarded``, so a bad input shows a message and changes
nothing. Values the server sets itself (when a clutch is selected, a file opened, ...)
fire the update callbacks with no client; those are ignored, so only the user's changes act.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any, Protocol

import numpy as np

from kgarment.constants import BUDGET_RANGE
from kgarment.errors import KgarmentError
from kgarment.studio import view
from kgarment.studio.edit import Editor
from kgarment.studio.forces import force_image
from kgarment.studio.optimise import Optimiser
from kgarment.studio.page import Page
from kgarment.studio.placement import LENGTH_RANGE, WIDTH_RANGE
from kgarment.studio.runs import progress_image
from kgarment.studio.settings import TOOLS
from kgarment.studio.simulations import MAX_PATH_FRAMES, Simulations

NONE = "(none)"
CLAMP_ECHO_SECONDS = 2.0  # how long after a refused budget the number box's clamped value is ignored


class Host(Page, Protocol):
    """What the panel drives: the page (:class:`~kgarment.studio.page.Page`), its parts and
    its own actions (:class:`kgarment.studio.app.Studio`)."""

    server: Any  # a viser.ViserServer (viser is an optional extra, imported by the app only)
    edit: Editor
    sims: Simulations
    optimiser: Optimiser
    session_dir: Path | None
    files_root: Path

    def guarded(self, fn: Callable, *args, **kwargs): ...
    def redraw(self, body: bool = True) -> None: ...
    def play(self, seconds: float = 2.0, steps: int = 24) -> None: ...
    def save(self, folder: str | None = None) -> list[Path] | None: ...
    def open(self, path: str, force: bool = False) -> None: ...
    def export_a(self, name: str) -> Path | None: ...
    def export_shown(self, name: str) -> Path | None: ...


class Panel:
    """Builds the controls for ``studio`` and keeps them in step with its state."""

    def __init__(self, studio: Host):
        self.s = studio
        self._path_drawn = None  # the force path whose picture is shown
        self._clamp_echo: tuple[float, float] | None = None  # (value, until): see _set_budget
        gui = studio.server.gui
        gui.configure_theme(control_width="large", show_share_button=False)  # a public tunnel: not offered
        self.status = gui.add_markdown("")
        self.message = gui.add_markdown("")
        tabs = gui.add_tab_group()
        with tabs.add_tab("View"):
            self._view_tab(gui)
        with tabs.add_tab("Edit"):
            self._edit_tab(gui)
        with tabs.add_tab("Simulate"):
            self._simulate_tab(gui)
        with tabs.add_tab("Optimise"):
            self._optimise_tab(gui)
        with tabs.add_tab("File"):
            self._file_tab(gui)
        self.rebuild_for_state()

    # ----- helpers ----------------------------------------------------------------------
    def _on(self, handle, fn):
        """Call ``fn(value)`` guarded when the *user* changes ``handle``."""
        @handle.on_update
        def _(event):
            if event.client is not None:
                self.s.guarded(fn, handle.value)
        return handle

    def _button(self, gui, label, fn, **kw):
        b = gui.add_button(label, **kw)

        @b.on_click
        def _(event):
            self.s.guarded(fn)
        return b

    # ----- tabs -------------------------------------------------------------------------
    def _view_tab(self, gui) -> None:
        s = self.s
        self.motion = self._on(gui.add_dropdown("Motion", ["rest"]), self._set("motion"))
        self.clutch_state = self._on(gui.add_dropdown("Clutches", ["ON", "OFF"]),
                                     lambda v: self._apply("clutches_on", v == "ON"))
        self.pose = self._on(gui.add_slider("Pose (rest to target)", 0.0, 1.0, 0.05, 1.0), self._set("pose"))
        self._button(gui, "Play motion", s.play)
        self.mode = self._on(gui.add_dropdown("Colour", list(view.MODES)), self._set("mode"))
        self.show_body = self._on(gui.add_checkbox("Show body", True), self._set("show_body"))
        self.legend = gui.add_markdown("")

    def _edit_tab(self, gui) -> None:
        e = self.s.edit
        self.tool = self._on(gui.add_dropdown("Tool", list(TOOLS)), e.set_tool)
        self.radius = self._on(gui.add_slider("Brush radius (m)", 0.005, 0.15, 0.005, 0.02), self._set("radius", False))
        self.brush_mode = self._on(gui.add_dropdown("Brush reach", ["surface", "euclidean"]),
                                   self._set("brush_mode", False))
        self.coverage = gui.add_markdown("")
        self.budget = self._on(gui.add_slider("Budget (area share)", *BUDGET_RANGE, 0.01, 0.15), self._set_budget)
        self.face = gui.add_number("Face id", 0, min=0, step=1)
        self._button(gui, "Apply tool at face", lambda: e.click_face(int(self.face.value)))
        self._button(gui, "Clear reinforcement", e.clear_design)
        self._button(gui, "Undo", e.undo)
        with gui.add_folder("Clutches"):
            self.clutch = self._on(gui.add_dropdown("Clutch", [NONE]), lambda v: e.select_clutch(None if v == NONE else v))
            self.cname = self._on(gui.add_text("Name", ""), lambda v: e.edit_selected(name=v.strip()))
            self.length = self._on(gui.add_slider("Length (m)", *LENGTH_RANGE, 0.005, 0.10),
                                   lambda v: e.edit_selected(length=float(v)))
            self.width = self._on(gui.add_slider("Width (m)", *WIDTH_RANGE, 0.001, 0.01),
                                  lambda v: e.edit_selected(width=float(v)))
            self.prestrain = self._on(gui.add_slider("Prestrain", 0.8, 1.0, 0.01, 1.0),
                                      lambda v: e.edit_selected(prestrain=float(v)))
            self.clip = self._on(gui.add_checkbox("Clip at the edge", False), lambda v: e.edit_selected(clip=bool(v)))
            self._button(gui, "Delete clutch", e.delete_selected, color="red")
            self.start_mark = gui.add_dropdown("Start landmark", [NONE])
            self.towards_mark = gui.add_dropdown("Towards landmark", [NONE])
            self._button(gui, "Add clutch at landmarks",
                         lambda: e.add_clutch_at_landmarks(self.start_mark.value, self.towards_mark.value))

    def _simulate_tab(self, gui) -> None:
        sims = self.s.sims
        self.sim_folder = gui.add_folder("Motions to simulate")
        self.sim_boxes: dict = {}
        self.set_fields: dict = {}  # per motion: the clutches it switches on ([motions.activation])
        self._button(gui, "Simulate design A", lambda: sims.simulate("A", self._sim_motions()))
        self._button(gui, "Simulate design B", lambda: sims.simulate("B", self._sim_motions()))
        self._button(gui, "Stop simulation", sims.stop)
        self._button(gui, "Pin A as B", sims.pin_as_b)
        self.b_source = gui.add_text("Design B from", "", hint="a design .npz/.npy/.txt, a run folder or RUN@K")
        self._button(gui, "Load design B", lambda: sims.load_b(self.b_source.value))
        self.sim_status = gui.add_markdown("")
        self.results = gui.add_markdown("")
        self.path_frames = gui.add_number("Frames from rest", 5, min=1, max=MAX_PATH_FRAMES, step=1)
        self._button(gui, "Force over the motion of A", lambda: sims.force_path(int(self.path_frames.value)))
        self.path_results = gui.add_markdown("")
        self.path_plot = gui.add_image(np.full((30, 52, 3), 255, np.uint8), label="Clutch tension from rest")

    def _optimise_tab(self, gui) -> None:
        o = self.s.optimiser
        self.run_out = gui.add_text("New run folder", "", hint=f"a name under {o.runs_root}; "
                                    "empty: studio-<date>-<time>")
        self.max_it = gui.add_number("Max iterations", 0, min=0, step=1, hint="0: the problem's setting")
        self._button(gui, "Start optimisation",
                     lambda: o.optimise(self.run_out.value.strip() or None, int(self.max_it.value) or None))
        self._button(gui, "Stop optimisation", o.stop)
        self.opt_status = gui.add_markdown("")
        self.plot = gui.add_image(np.full((30, 52, 3), 255, np.uint8), label="Progress")
        self.run_path = gui.add_text("Run folder", "")
        self._button(gui, "Open run", lambda: o.open(self.run_path.value.strip()))
        self.iteration = self._on(gui.add_slider("Iteration", 0, 1, 1, 0, disabled=True), lambda v: o.show_iteration(int(v)))
        self.follow = self._on(gui.add_checkbox("Follow the latest iteration", o.follow),
                               lambda v: setattr(o, "follow", bool(v)))
        self.run_info = gui.add_markdown("")
        self._button(gui, "Load iteration into design A", o.use_iteration)
        self._button(gui, "Use iteration as design B", lambda: o.use_iteration(as_b=True))
        self.export_path = gui.add_text("Export iteration as", "design.npz", hint=f"a name; written to "
                                        f"{o.runs_root / 'exports'}")
        self._button(gui, "Export iteration", lambda: o.export_iteration(self.export_path.value))

    def _file_tab(self, gui) -> None:
        s = self.s
        self.session_path = gui.add_text("Save as session", "", hint=f"a name under {s.files_root / 'sessions'}; "
                                         "empty: the session's own folder")
        self._button(gui, "Save session", lambda: s.save(self.session_path.value))
        self.open_path = gui.add_text("Open", "", hint="a problem file (.toml), a run folder or a session folder")
        self._button(gui, "Open", lambda: s.open(self.open_path.value))
        self.export_a_path = gui.add_text("Export the design shown as", "design.npz", hint=f"a name; written to "
                                          f"{s.files_root / 'exports'}: the run's iteration in the run colour "
                                          "mode, else design A")
        self._button(gui, "Export the design shown", lambda: s.export_shown(self.export_a_path.value))

    # ----- callbacks --------------------------------------------------------------------
    def _set(self, name: str, redraw: bool = True):
        def fn(value):
            self._apply(name, value, redraw)
        return fn

    def _apply(self, name: str, value, redraw: bool = True) -> None:
        setattr(self.s.settings, name, value)
        if redraw:
            self.s.redraw(body=name in ("motion", "pose", "show_body"))

    def _set_budget(self, value) -> None:
        """The budget typed or slid.  An out-of-range one is refused and the slider goes back
        to the last valid budget; the number box beside it clamps what was typed (5 to 1)
        when it loses focus, and when that happens before the slider is back, the clamped
        value that follows the refusal is the box's, not the user's: it is ignored too."""
        v = float(value)
        echo, self._clamp_echo = self._clamp_echo, None
        if echo is not None and v == echo[0] and time.monotonic() < echo[1]:
            self.budget.value = round(self.s.state.budget, 2)
            return
        try:
            self.s.state.set_budget(v)
        except KgarmentError:
            if math.isfinite(v):
                self._clamp_echo = (min(max(v, BUDGET_RANGE[0]), BUDGET_RANGE[1]), time.monotonic() + CLAMP_ECHO_SECONDS)
            self.budget.value = round(self.s.state.budget, 2)
            raise
        self.refresh_status()

    def _set_activation(self, motion: str, text: str) -> None:
        self.s.state.set_activation(motion, [n.strip() for n in str(text).split(",") if n.strip()])
        self.s.say(f"{motion} switches on: {', '.join(self.s.state.activation_set(motion)) or 'no clutch'}")
        self.refresh_status()

    def _sim_motions(self) -> list[str]:
        chosen = [m for m, box in self.sim_boxes.items() if box.value]
        self.s.settings.sim_motions = chosen
        return chosen

    # ----- showing state ----------------------------------------------------------------
    def rebuild_for_state(self) -> None:
        """Options that depend on the opened problem (motions, landmarks, clutches)."""
        st, s = self.s.state, self.s.settings
        self.motion.options = ["rest"] + list(st.base_garment.motion_names)
        marks = sorted(k for k in (st.landmarks or {}) if not k.endswith((".left", ".right")))
        self.start_mark.options = marks or [NONE]
        self.towards_mark.options = marks or [NONE]
        for box in [*self.sim_boxes.values(), *self.set_fields.values()]:
            box.remove()
        gui = self.s.server.gui
        with self.sim_folder:
            self.sim_boxes, self.set_fields = {}, {}
            for m in st.problem.motions:
                self.sim_boxes[m] = gui.add_checkbox(m, m in s.sim_motions)
                self.set_fields[m] = self._on(
                    gui.add_text(f"{m}: ON set", "", hint="clutches this motion switches on, comma-separated "
                                 "(empty: all)"), lambda v, m=m: self._set_activation(m, v))
        self.sync_settings()
        self.sync_clutch()
        self.show_results()
        self.show_run()

    def sync_settings(self) -> None:
        s = self.s.settings
        self.motion.value = s.motion
        self.clutch_state.value = "ON" if s.clutches_on else "OFF"
        self.pose.value = s.pose
        self.mode.value = s.mode
        self.show_body.value = s.show_body
        self.tool.value = s.tool
        self.radius.value = s.radius
        self.brush_mode.value = s.brush_mode
        self.budget.value = round(self.s.state.budget, 2)

    def sync_clutch(self) -> None:
        st, name = self.s.state, self.s.edit.selected
        self.clutch.options = [NONE] + st.clutch_names()
        self.clutch.value = name or NONE
        if name is not None:
            c = st.clutch(name)
            self.cname.value = c.name
            self.length.value = float(np.clip(c.length, *LENGTH_RANGE))
            self.width.value = float(np.clip(c.width, *WIDTH_RANGE))
            self.prestrain.value = float(np.clip(c.prestrain, 0.8, 1.0))
            self.clip.value = bool(c.clip)
        else:  # nothing selected (say, just deleted): no name left in the form; the sliders
            self.cname.value = ""  # keep their values as the next clutch's defaults
        self.refresh_status()

    def clutch_defaults(self) -> dict[str, float | bool]:
        """Length, width, prestrain, clip for a new clutch (the sliders' values)."""
        return {"length": float(self.length.value), "width": float(self.width.value),
                "prestrain": float(self.prestrain.value), "clip": bool(self.clip.value)}

    def refresh_status(self) -> None:
        st = self.s.state
        cov, budget = 100 * st.coverage(), 100 * st.budget
        over = " (over budget)" if round(cov, 1) > round(budget, 1) else ""  # as shown: 15.0% of 15% is not over
        self.coverage.content = f"**Reinforced: {cov:.1f}%** of the garment area; budget {budget:.0f}%{over}"
        saved = "unsaved changes" if st.dirty else "saved" if self.s.session_dir else "not saved yet"
        where = f" (Save writes {self.s.session_dir})" if self.s.session_dir is not None else ""
        self.status.content = (f"**kgarment studio**: {st.base_garment.name}, {st.n_faces} faces, "
                               f"{len(st.clutches)} clutches; reinforced {cov:.1f}% / {budget:.0f}%; {saved}{where}")
        for m, field in self.set_fields.items():  # the sets as the problem has them (after undo, renames)
            text = ", ".join(st.activation_set(m)) if st.problem.activation_of(m) is not None else ""
            if field.value != text:
                field.value = text

    def show_message(self, text: str, error: bool) -> None:
        self.message.content = ("**Error:** " if error else "") + text

    def show_legend(self, text: str) -> None:
        self.legend.content = text

    def show_progress(self, job: str, text: str) -> None:
        """Progress of the "simulation" or "optimisation" job."""
        (self.sim_status if job == "simulation" else self.opt_status).content = text

    def show_results(self) -> None:
        sims = self.s.sims
        self.results.content = sims.table()
        self.path_results.content = sims.path_table()
        if sims.path is not None and sims.path[2] is not self._path_drawn:
            self.path_plot.image = force_image(sims.path[2])
            self._path_drawn = sims.path[2]

    def show_run(self) -> None:
        o = self.s.optimiser
        run = o.run
        if run is None:
            self.iteration.disabled = True
            self.run_info.content = "No run open."
            return
        n = run.n_iterations
        self.iteration.max = max(n - 1, 1)
        self.iteration.disabled = n == 0
        self.iteration.value = min(o.k, max(n - 1, 0))
        self.run_info.content = f"{run.folder}: {n} iterations. " + (run.summary(o.k) if n else "")
        self.plot.image = progress_image(run.metrics)
        if o.running and run.metrics:
            row = run.metrics[-1]
            self.opt_status.content = f"iteration {row['iteration']}: area {100 * row['area']:.1f}%, " \
                                      f"objective {row['objective']:.4f}"
