"""The studio's web page on viser: the parts put together, messages, drawing, files.

:class:`Studio` owns a viser server, the edited :class:`~kgarment.studio.state.StudioState`
and the page's :class:`~kgarment.studio.settings.Settings`, and is made of parts split by
responsibility:

- ``edit`` (:class:`~kgarment.studio.edit.Editor`): the tools, clutch actions, undo;
- ``sims`` (:class:`~kgarment.studio.simulations.Simulations`): designs A and B simulated;
- ``optimiser`` (:class:`~kgarment.studio.optimise.Optimiser`): optimisations and runs;
- ``scene`` (:class:`~kgarment.studio.scene.Scene`): the 3D meshes and picking;
- ``panel`` (:class:`~kgarment.studio.panel.Panel`): the controls.

The parts reach the page only through the :class:`~kgarment.studio.page.Page` protocol,
which :class:`Studio` implements (messages, refreshes); files (save, open, export) are the
Studio's own. Every action that can fail on the user's input shows a message in the page
(and a notification) and changes nothing.
"""

from __future__ import annotations

import logging
import threading
import time
from collections.abc import Callable
from pathlib import Path
from typing import TypeVar

import numpy as np

from kgarment.body import Body
from kgarment.errors import KgarmentError
from kgarment.studio import brush, view
from kgarment.studio.edit import Editor
from kgarment.studio.folders import Folders
from kgarment.studio.gate import Gate, guarded_server
from kgarment.studio.optimise import Optimiser
from kgarment.studio.panel import Panel
from kgarment.studio.scene import Scene, garment_colors, garment_target
from kgarment.studio.session import (
    Opened,
    build_state,
    export_design,
    read_source,
    save_session,
    studio_path,
)
from kgarment.studio.settings import Settings
from kgarment.studio.simulations import Simulations
from kgarment.studio.state import StudioState

log = logging.getLogger(__name__)
MESSAGES_KEPT = 50
ERROR_SECONDS = 15.0  # an error pop-up closes after this long (the status line keeps the message)
T = TypeVar("T")


class Studio:
    """The web app (see the module docstring). ``opened`` from
    :func:`kgarment.studio.session.read_source`; ``session`` : folder Save writes to
    (default: the opened session's); ``runs`` : where optimisations go when no folder is
    named; ``body`` reuses a posed body (tests).  Only the page opened at :attr:`url` (it
    holds the session token) can connect (:mod:`kgarment.studio.gate`), and it reads only
    under :attr:`folders` (:mod:`kgarment.studio.folders`)."""

    def __init__(self, opened: Opened, *, host: str = "127.0.0.1", port: int = 8080,
                 session: str | Path | None = None, runs: str | Path = "runs/studio", device: str = "cpu",
                 body: Body | None = None):
        self.lock = threading.RLock()
        self.device = device
        self.session_dir: Path | None = Path(session) if session else opened.session
        self.state: StudioState = build_state(opened, body)
        self.settings = Settings.from_dict(opened.settings)
        self.settings.fit(self.state.base_garment.motion_names, self.state.problem.motions)
        self.messages: list[tuple[str, bool]] = []
        self._confirm_open: str | None = None
        self._confirm_write: Path | None = None
        self._popups: dict = {}  # client id -> its last notification handle
        self.files_root = Path(runs)
        self.folders = Folders.of(opened, runs, session)
        self.gate = Gate(host)
        self.edit = Editor(self)
        self.sims = Simulations(self, opened.compare)
        self.optimiser = Optimiser(self, self.sims, Path(runs))
        self.server = guarded_server(self.gate, host=host, port=port, verbose=False)
        self.server.scene.set_up_direction("+z")
        self.scene = Scene(self.server, self._on_drag)
        self.panel = Panel(self)
        self.server.scene.on_click()(self._on_scene_click)
        self.scene.set_initial_camera(self.state.base_garment.rest_vertices)
        self.redraw()
        if opened.run is not None:
            self.optimiser.open(opened.run)

    # ----- life cycle -------------------------------------------------------------------
    @property
    def url(self) -> str:
        """The page's address with the session token (the page is let in with it only)."""
        return self.gate.url(self.server.get_host(), self.server.get_port())

    def stop(self) -> None:
        for job in (self.sims.job, self.optimiser.job):
            if job is not None and job.running:
                job.cancel()
        self.server.stop()

    # ----- the Page protocol: messages and refreshes -------------------------------------
    def say(self, text: str, error: bool = False, notify: bool = False) -> None:
        """Show ``text`` in the page's status line; errors (and ``notify``) also pop up as
        a notification, one at a time (a new one replaces the last; errors close after
        ``ERROR_SECONDS``, the status line keeps the text)."""
        (log.warning if error else log.info)("studio: %s", text)
        self.messages.append((text, error))
        del self.messages[:-MESSAGES_KEPT]
        self.panel.show_message(text, error)
        if not (error or notify):
            return
        for cid, client in self.server.get_clients().items():
            try:
                old = self._popups.pop(cid, None)
                if old is not None:  # one pop-up at a time: a new message replaces the last
                    old.remove()
                self._popups[cid] = client.add_notification(
                    "Error" if error else "kgarment", text, color="red" if error else None,
                    auto_close_seconds=ERROR_SECONDS if error else 4.0)
            except Exception:
                log.debug("notification not delivered", exc_info=True)

    def refresh(self, *, scene: bool = False, body: bool = False, results: bool = False, run: bool = False,
                settings: bool = False, clutch: bool = False) -> None:
        """Bring parts of the page up to date (see :meth:`kgarment.studio.page.Page.refresh`)."""
        if settings:
            self.panel.sync_settings()
        if clutch:
            self.panel.sync_clutch()
        if run:
            self.panel.show_run()
        if results:
            self.panel.show_results()
        if scene or body:
            self.redraw(body=body)

    def show_progress(self, job: str, text: str) -> None:
        self.panel.show_progress(job, text)

    def clutch_defaults(self) -> dict[str, float | bool]:
        return self.panel.clutch_defaults()

    def guarded(self, fn: Callable[..., T], *args, **kwargs) -> T | None:
        """Run ``fn``; user errors and crashes become a message in the page (returns None)."""
        try:
            return fn(*args, **kwargs)
        except KgarmentError as exc:
            self.say(str(exc), error=True)
        except Exception as exc:
            log.exception("studio action failed")
            self.say(f"{type(exc).__name__}: {exc}", error=True)
        return None

    # ----- what is shown ----------------------------------------------------------------
    def garment_positions(self) -> np.ndarray:
        """(n, 3) displayed garment, m: rest blended towards the equilibrium of design A (if
        simulated for this motion and clutch state) or the skin-tight target pose."""
        g, s = self.state.base_garment, self.settings
        if s.motion == "rest":
            return g.rest_vertices
        return view.interpolate(g.rest_vertices, garment_target(self.state, s, self.sims.a), s.pose)

    def body_positions(self) -> np.ndarray:
        """(nb, 3) displayed body, m."""
        b, s = self.state.body, self.settings
        return b.rest_vertices if s.motion == "rest" else view.interpolate(b.rest_vertices, b.vertices(s.motion), s.pose)

    def garment_colors(self) -> tuple[np.ndarray, str]:
        """((m, 3) uint8 colours, markdown legend) for the current colour mode."""
        x = self.garment_positions() if self.settings.mode == "strain" else self.state.base_garment.rest_vertices
        return garment_colors(self.state, self.settings, x, a=self.sims.a, design_b=self.sims.design_b,
                              run=self.optimiser.run, k=self.optimiser.k)

    def redraw(self, body: bool = True) -> None:
        """Send the body, garment and clutches as they should look now."""
        with self.lock:
            st, s, scene = self.state, self.settings, self.scene
            faces = st.base_garment.faces
            if body:
                scene.draw_body(self.body_positions(), st.body.faces, s.show_body)
            gx = self.garment_positions()
            colors, legend = self.garment_colors()
            scene.draw_garment(gx, faces, colors)
            strips = st.strips()
            on = view.CLUTCH_ON if s.clutches_on else view.CLUTCH_OFF
            scene.draw_clutches(gx, faces, strips, [view.SELECTED if c.name == self.edit.selected else on
                                                    for c in strips])
            pending = self.edit.pending_start
            if pending is None:
                scene.draw_marker(None)
            else:
                hit = st.topology.closest_point(np.asarray(pending))
                scene.draw_marker(scene.displayed(hit.face, hit.bary, faces))
            self.panel.show_legend(legend)
            self.panel.refresh_status()
            self.panel.show_results()

    def look_at_face(self, face: int, distance: float = 0.35) -> np.ndarray:
        """Point every open page's camera at garment ``face`` from outside, along its normal;
        returns the camera position (3,)."""
        return self.scene.look_at_face(face, self.state.base_garment.faces, distance)

    def play(self, seconds: float = 2.0, steps: int = 24) -> None:
        """Animate the pose slider from rest to the target pose (in a thread)."""
        def run():
            for k in range(steps + 1):
                self.settings.pose = k / steps
                self.panel.pose.value = round(k / steps, 3)
                self.redraw()
                time.sleep(seconds / steps)

        threading.Thread(target=run, daemon=True).start()

    # ----- clicks -----------------------------------------------------------------------
    def pick(self, origin, direction) -> brush.Hit | None:
        """The garment hit of a ray in the displayed scene, or None when the ray misses the
        garment or meets the body first."""
        st = self.state
        body = (self.body_positions(), st.body.faces) if self.settings.show_body else None
        return self.scene.pick(origin, direction, st.base_garment.faces, body)

    def click_ray(self, origin, direction) -> None:
        """A click in the scene (ray origin (3,), direction (3,)): the tool acts on the
        garment point hit."""
        hit = self.pick(origin, direction)
        if hit is None:
            if self.settings.tool != "select":
                raise KgarmentError("that click is not on the garment; click on the garment (blue cloth)")
            return
        self.edit.click_face(hit.face, hit.bary)

    def _on_scene_click(self, event) -> None:
        self.guarded(self.click_ray, event.ray_origin, event.ray_direction)

    def _on_drag(self, event) -> None:
        cam = event.client.camera.position
        point = event.start_position if event.phase == "start" else event.end_position
        hit = self.pick(*brush.camera_ray(cam, point))
        if hit is not None:
            self.edit.dab(hit.face, hit.bary, start=event.phase == "start")

    # ----- files ------------------------------------------------------------------------
    def confirm_write(self, path: Path) -> bool:
        """Whether the page may write ``path``: a new one, yes; an existing one only when the
        same write is asked for twice in a row (the first time the page warns)."""
        if path.exists() and self._confirm_write != path:
            self._confirm_write = path
            self.say(f"{path} exists: press the button again to replace it", notify=True)
            return False
        self._confirm_write = None
        return True

    def save(self, folder: str | None = None) -> list[Path] | None:
        """Save the session (problem, clutches, designs, attachments, settings, results)
        into its folder (``--session``, or the session opened), or a session named
        ``folder`` under ``RUNS/sessions``; None when an existing one awaits confirmation."""
        if folder and folder.strip():
            target = studio_path(self.files_root / "sessions", folder, "session name")
            if not self.confirm_write(target):
                return None
        else:
            target = self.session_dir
        if target is None:
            raise KgarmentError("give a session name to save into")
        run = self.optimiser.run
        paths = save_session(self.state, target, settings=self.settings.to_dict(), compare=self.sims.design_b,
                             results=self.sims.to_json(), run=run.folder if run is not None else None)
        self.session_dir = target
        self.say(f"session saved to {target} ({len(paths)} files)", notify=True)
        self.panel.refresh_status()
        return paths

    def open(self, path: str, force: bool = False) -> None:
        """Replace the studio's contents by a problem file, run folder or session. With
        unsaved changes the first call only warns; a second call with the same path opens."""
        text = path.strip()
        if not text:
            raise KgarmentError("give a problem file, a run folder or a session folder to open")
        if self.sims.running or self.optimiser.running:
            raise KgarmentError("a simulation or optimisation is running; stop it before opening something else")
        self.folders.inside(text, "open")
        if self.state.dirty and not force and self._confirm_open != text:
            self._confirm_open = text
            raise KgarmentError("there are unsaved changes: save them, or press Open again to discard them")
        opened = read_source(text)
        body = self.state.body if opened.problem.body == self.state.problem.body else None
        new = build_state(opened, body)
        with self.lock:
            self.state, self._confirm_open = new, None
            self.session_dir = opened.session or self.session_dir
            self.sims.reset(opened.compare)
            self.edit.reset()
            self.optimiser.close()
            self.settings = Settings.from_dict(opened.settings)
            self.settings.fit(new.base_garment.motion_names, new.problem.motions)
        self.panel.rebuild_for_state()
        self.scene.set_initial_camera(new.base_garment.rest_vertices)
        self.redraw()
        self.say(f"opened {text} ({opened.kind}): {new.base_garment.name}, {new.n_faces} faces, "
                 f"{len(new.clutches)} clutches", notify=True)
        if opened.run is not None:
            self.guarded(self.optimiser.open, opened.run)

    def export_a(self, name: str) -> Path | None:
        """Write design A as a design NPZ (``kgarment simulate --design`` reads it) named
        ``name`` under ``RUNS/exports``; None when an existing file awaits confirmation."""
        out = studio_path(self.files_root / "exports", name, "export name", ".npz")
        if not self.confirm_write(out):
            return None
        out = export_design(out, self.state.design, self.state.base_garment)
        self.say(f"design A written to {out}", notify=True)
        return out

    def export_shown(self, name: str) -> Path | None:
        """Write the design the view shows (the File tab's export): the run's iteration in
        the "run" colour mode with a run open, design A otherwise; the message says which."""
        run = self.optimiser.run
        if self.settings.mode == "run" and run is not None and run.n_iterations:
            out = self.optimiser.export_iteration(name)
            if out is not None:
                self.say(f"the design shown, iteration {self.optimiser.k} of run {run.folder.name}, written to {out} "
                         "(not design A: Load iteration into design A to edit it)", notify=True)
            return out
        return self.export_a(name)
