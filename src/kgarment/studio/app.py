"""The studio's web page on viser: scene drawing, clicks, jobs and messages.

:class:`Studio` owns a viser server, the edited :class:`~kgarment.studio.state.StudioState`
and the page's settings; :mod:`kgarment.studio.panel` builds the controls and calls the
public methods here, which tests may call too. Every action that can fail on the user's
input shows a message in the page (and a notification) and changes nothing.
"""

from __future__ import annotations

import logging
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from kgarment.errors import KgarmentError
from kgarment.studio import brush, view
from kgarment.studio.actions import Actions
from kgarment.studio.session import Opened, build_state

log = logging.getLogger(__name__)
GARMENT_LIFT = 0.002  # metres: the garment is drawn this far off the skin
CLUTCH_LIFT = 0.004
NO_SHADOW = {"cast_shadow": False, "receive_shadow": False}  # shadows cost much in software WebGL
TOOLS = ("select", "place clutch", "move clutch", "aim clutch", "paint reinforcement", "erase reinforcement",
         "paint attachments", "erase attachments")
BRUSH_TOOLS = {"paint reinforcement": ("design", True), "erase reinforcement": ("design", False),
               "paint attachments": ("attached", True), "erase attachments": ("attached", False)}


@dataclass
class Settings:
    """The page's settings (saved with a session)."""

    motion: str = "rest"
    clutches_on: bool = True
    pose: float = 1.0
    mode: str = "design"
    show_body: bool = True
    tool: str = "select"
    radius: float = 0.02
    brush_mode: str = "surface"
    sim_motions: list = field(default_factory=list)

    def to_dict(self) -> dict:
        return dict(self.__dict__)

    @classmethod
    def from_dict(cls, d: dict) -> Settings:
        s = cls()
        for k, v in d.items():
            if hasattr(s, k) and isinstance(v, type(getattr(s, k))):
                setattr(s, k, v)
        return s


class Studio(Actions):
    """The web app (see the module docstring). ``opened`` from
    :func:`kgarment.studio.session.read_source`; ``body`` reuses a posed body (tests)."""

    def __init__(self, opened: Opened, *, host: str = "127.0.0.1", port: int = 8080, session=None,
                 runs="runs/studio", device: str = "cpu", body=None):
        import viser

        self.lock = threading.RLock()
        self.device = device
        self.runs_root = Path(runs)
        self.session_dir = Path(session) if session else opened.session
        self.state = build_state(opened, body)
        self.settings = Settings.from_dict(opened.settings)
        self._fix_settings()
        self.selected: str | None = None
        self.pending_start: np.ndarray | None = None
        self.eval_a = self.eval_b = None
        self.compare = opened.compare
        self.full_cache: dict = {}
        self.run = None
        self.run_k = 0
        self.sim_job = self.opt_job = None
        self.messages: list[tuple[str, bool]] = []
        self._confirm_open: str | None = None
        self._stroke = False
        self.server = viser.ViserServer(host=host, port=port, verbose=False)
        self.server.scene.set_up_direction("+z")
        self._handles: dict = {}
        from kgarment.studio.panel import Panel

        self.panel = Panel(self)
        self.server.scene.on_click()(self._on_scene_click)
        self._set_initial_camera()
        self.redraw()
        if opened.run is not None:
            self.open_run(opened.run)

    # ----- life cycle -------------------------------------------------------------------
    @property
    def url(self) -> str:
        return f"http://{self.server.get_host()}:{self.server.get_port()}"

    def stop(self) -> None:
        for job in (self.sim_job, self.opt_job):
            if job is not None and job.running:
                job.cancel()
        self.server.stop()

    def _fix_settings(self) -> None:
        s, names = self.settings, self.state.base_garment.motion_names
        if s.motion != "rest" and s.motion not in names:
            s.motion = "rest"
        s.sim_motions = [m for m in s.sim_motions if m in self.state.problem.motions] or list(self.state.problem.motions)

    # ----- messages ---------------------------------------------------------------------
    def say(self, text: str, error: bool = False, notify: bool = False) -> None:
        """Show ``text`` in the page's status line; errors (and ``notify``) also pop up
        as a notification (errors stay until closed)."""
        (log.warning if error else log.info)("studio: %s", text)
        self.messages.append((text, error))
        del self.messages[:-50]
        self.panel.show_message(text, error)
        if not (error or notify):
            return
        for client in self.server.get_clients().values():
            try:
                client.add_notification("Error" if error else "kgarment", text, color="red" if error else None,
                                        auto_close_seconds=None if error else 4.0)
            except Exception:
                log.debug("notification not delivered", exc_info=True)

    def guarded(self, fn, *args, **kwargs):
        """Run ``fn``; user errors and crashes become a message in the page (returns None)."""
        try:
            return fn(*args, **kwargs)
        except KgarmentError as exc:
            self.say(str(exc), error=True)
        except Exception as exc:
            log.exception("studio action failed")
            self.say(f"{type(exc).__name__}: {exc}", error=True)
        return None

    # ----- geometry shown ---------------------------------------------------------------
    def _state_key(self) -> str:
        states = ("on", "off", "none")
        want = "on" if self.settings.clutches_on else "off"
        keys = {k[1] for e in (self.eval_a,) if e is not None for k in e.garment_x}
        return want if want in keys or not keys else next(s for s in states if s in keys)

    def garment_positions(self) -> np.ndarray:
        """(n, 3) displayed garment: rest blended towards the equilibrium of design A (if
        simulated for this motion and clutch state) or the skin-tight target pose."""
        g, s = self.state.base_garment, self.settings
        if s.motion == "rest":
            return g.rest_vertices
        key = (s.motion, self._state_key())
        target = self.eval_a.garment_x[key] if self.eval_a is not None and key in self.eval_a.garment_x else g.vertices(s.motion)
        return view.interpolate(g.rest_vertices, target, s.pose)

    def body_positions(self) -> np.ndarray:
        b, s = self.state.body, self.settings
        return b.rest_vertices if s.motion == "rest" else view.interpolate(b.rest_vertices, b.vertices(s.motion), s.pose)

    def garment_colors(self) -> tuple[np.ndarray, str]:
        """((m, 3) uint8 colours, markdown legend) for the current colour mode."""
        st, s = self.state, self.settings
        if s.mode == "attachments":
            return view.attachment_colors(st.attached), view.legend("attachments")
        if s.mode == "strain":
            x = self.garment_positions()
            c, lo, hi = view.scalar_colors(view.face_strain(st.base_garment.rest_vertices, st.base_garment.faces, x),
                                           vmin=0.0)
            return c, view.legend("strain", lo, hi)
        if s.mode == "energy density":
            key = (s.motion, self._state_key())
            if self.eval_a is not None and key in self.eval_a.density:
                c, lo, hi = view.scalar_colors(self.eval_a.density[key], vmin=0.0)
                return c, view.legend("energy density", lo, hi, note=f"design A, {key[0]}, clutches {key[1]}")
            note = "no simulation of design A for this motion and clutch state: simulate first (showing the design)"
            return view.design_colors(st.design, st.attached), view.legend("design", note=note)
        if s.mode == "compare":
            if self.compare is None:
                return view.design_colors(st.design, st.attached), view.legend("design", note="no design B yet")
            return view.compare_colors(st.design, self.compare[1]), view.legend("compare", note=f"B: {self.compare[0]}")
        if s.mode == "run":
            if self.run is None or self.run.n_iterations == 0:
                return view.design_colors(st.design, st.attached), view.legend("design", note="no run open")
            return view.design_colors(self.run.design(self.run_k)), view.legend("run", note=self.run.summary(self.run_k))
        return view.design_colors(st.design, st.attached), view.legend("design")

    # ----- drawing ----------------------------------------------------------------------
    def redraw(self, body: bool = True) -> None:
        """Send the body, garment and clutches as they should look now."""
        with self.lock:
            scene, st = self.server.scene, self.state
            if body:
                bv = self.body_positions()
                h = self._handles.get("body")
                if h is None:
                    self._handles["body"] = scene.add_mesh_simple("/body", bv, st.body.faces, color=view.SKIN,
                                                                  visible=self.settings.show_body, **NO_SHADOW)
                else:
                    h.vertices = bv.astype(np.float32)
                    h.visible = self.settings.show_body
            gx = self.garment_positions()
            shown = view.offset_along_normals(gx, st.base_garment.faces, GARMENT_LIFT)
            self._shown = shown
            colors, legend = self.garment_colors()
            glb = view.glb_bytes(shown, st.base_garment.faces, colors)
            h = self._handles.get("garment")
            if h is None:
                self._handles["garment"] = scene.add_glb("/garment", glb, **NO_SHADOW)
                self._handles["garment"].on_drag(self._on_drag)
            else:
                h.glb_data = glb
            self._draw_clutches(gx)
            self.panel.show_legend(legend)
            self.panel.refresh_status()
            self.panel.show_results()

    def _draw_clutches(self, gx: np.ndarray) -> None:
        scene, st = self.server.scene, self.state
        for h in self._handles.pop("clutches", []):
            h.remove()
        lifted = view.offset_along_normals(gx, st.base_garment.faces, CLUTCH_LIFT)
        hs = []
        for k, strip in enumerate(st.strips()):
            color = view.SELECTED if strip.name == self.selected else (
                view.CLUTCH_ON if self.settings.clutches_on else view.CLUTCH_OFF)
            x = strip.bound_positions(lifted, st.base_garment.faces)
            hs.append(scene.add_mesh_simple(f"/clutches/c{k}", x, strip.faces, color=color, side="double",
                                             **NO_SHADOW))
        self._handles["clutches"] = hs
        old = self._handles.pop("pending", None)
        if old is not None:
            old.remove()
        if self.pending_start is not None:
            self._handles["pending"] = scene.add_icosphere("/pending", radius=0.006, color=view.SELECTED,
                                                           position=tuple(self._displayed(self.pending_start)))

    def _displayed(self, rest_point: np.ndarray) -> np.ndarray:
        hit = self.state.topology.closest_point(np.asarray(rest_point))
        return hit.bary @ self._shown[self.state.base_garment.faces[hit.face]]

    def _set_initial_camera(self) -> None:
        g = self.state.base_garment.rest_vertices
        c = g.mean(axis=0)
        size = float(np.linalg.norm(g.max(axis=0) - g.min(axis=0)))
        cam = self.server.initial_camera
        cam.position = tuple(c + np.array([0.3, -1.0, 0.35]) * max(size, 0.3) * 1.6)
        cam.look_at = tuple(c)
        cam.up = (0.0, 0.0, 1.0)

    def look_at_face(self, face: int, distance: float = 0.35) -> np.ndarray:
        """Point every open page's camera at garment ``face`` from outside, along its normal;
        returns the camera position (3,)."""
        x = self._shown
        tri = x[self.state.base_garment.faces[face]]
        c = tri.mean(axis=0)
        n = np.cross(tri[1] - tri[0], tri[2] - tri[0])
        n /= np.linalg.norm(n)
        for client in self.server.get_clients().values():
            with client.atomic():
                client.camera.up_direction = (0.0, 0.0, 1.0)
                client.camera.position = tuple(c + distance * n)
                client.camera.look_at = tuple(c)
        return c + distance * n

    # ----- picking ----------------------------------------------------------------------
    def pick(self, origin, direction) -> brush.Hit | None:
        """The garment hit of a ray in the displayed scene, or None when the ray misses the
        garment or meets the body first."""
        st = self.state
        hit = brush.ray_hit(origin, direction, self._shown, st.base_garment.faces)
        if hit is None:
            return None
        if self.settings.show_body:
            b = brush.ray_hit(origin, direction, self.body_positions(), st.body.faces)
            if b is not None and b.distance < hit.distance - 0.01:
                return None
        return hit

    def _on_scene_click(self, event) -> None:
        self.guarded(self.click_ray, event.ray_origin, event.ray_direction)

    def click_ray(self, origin, direction) -> None:
        """A click in the scene: what happens depends on the tool."""
        hit = self.pick(origin, direction)
        if hit is None:
            if self.settings.tool != "select":
                raise KgarmentError("that click is not on the garment; click on the garment (blue cloth)")
            return
        self.click_face(hit.face, hit.bary)

    def click_face(self, face: int, bary=(1 / 3, 1 / 3, 1 / 3)) -> None:
        """A click on the garment at (face, barycentric (3,)), by the current tool."""
        tool = self.settings.tool
        with self.lock:
            p = self.state.rest_point(int(face), bary)
            if tool in BRUSH_TOOLS:
                layer, value = BRUSH_TOOLS[tool]
                n = self.state.paint(int(face), p, self.settings.radius, value, layer, self.settings.brush_mode)
                self.say(f"{tool}: {n} faces changed at face {face}")
            elif tool == "place clutch":
                self._place_click(p)
            elif tool in ("move clutch", "aim clutch"):
                if self.selected is None:
                    raise KgarmentError(f"{tool}: select a clutch first (Edit tab, or click it with 'select')")
                if tool == "move clutch":
                    self.state.move_clutch(self.selected, p)
                else:
                    self.state.aim_clutch(self.selected, p)
                self.say(f"clutch {self.selected}: {tool.split()[0]}d")
            else:
                from kgarment.studio.placement import nearest_clutch

                name = nearest_clutch(self.state.strips(), p)
                if name is not None:
                    self.select_clutch(name)
                self.say(f"face {face} at {np.round(p, 3).tolist()} m" + (f"; clutch {name} selected" if name else ""))
            self.redraw(body=False)
            self.panel.sync_clutch()

    def _place_click(self, p: np.ndarray) -> None:
        if self.pending_start is None:
            self.pending_start = p
            self.say("clutch start set: now click where the clutch should head")
            return
        from kgarment.studio.placement import clutch_from_points

        start, self.pending_start = self.pending_start, None
        d = self.panel.clutch_defaults()
        spec = clutch_from_points(self.state.new_clutch_name(), start, p, **d)
        self.state.add_clutch(spec)
        self.selected = spec.name
        self.say(f"clutch {spec.name} placed ({100 * spec.length:.1f} cm x {100 * spec.width:.1f} cm)")

    def _on_drag(self, event) -> None:
        tool = self.settings.tool
        if tool not in BRUSH_TOOLS:
            return
        cam = event.client.camera.position
        point = event.start_position if event.phase == "start" else event.end_position
        o, d = brush.camera_ray(cam, point)
        hit = self.pick(o, d)
        if hit is None:
            return
        layer, value = BRUSH_TOOLS[tool]
        with self.lock:
            p = self.state.rest_point(hit.face, hit.bary)
            self.state.paint(hit.face, p, self.settings.radius, value, layer, self.settings.brush_mode,
                             record=event.phase == "start")
            self.redraw(body=False)

    # ----- clutch actions ---------------------------------------------------------------
    def select_clutch(self, name: str | None) -> None:
        if name is not None:
            self.state.clutch(name)
        self.selected = name
        self.panel.sync_clutch()
        self.redraw(body=False)

    def add_clutch_at_landmarks(self, start: str, towards: str) -> None:
        from kgarment.studio.placement import clutch_from_landmarks

        base = start.replace(".", "_")
        spec = clutch_from_landmarks(self.state.new_clutch_name(base), start, towards, **self.panel.clutch_defaults())
        self.state.add_clutch(spec)
        self.selected = spec.name
        self.say(f"clutch {spec.name} placed at {start}, heading to {towards}")
        self.panel.sync_clutch()
        self.redraw(body=False)

    def edit_selected(self, **changes) -> None:
        """Change the selected clutch (length, width, ...); on error the controls go back."""
        if self.selected is None:
            return
        try:
            strip = self.state.edit_clutch(self.selected, **changes)
        except KgarmentError:
            self.panel.sync_clutch()
            raise
        self.selected = strip.name
        self.panel.sync_clutch()
        self.redraw(body=False)

    def delete_selected(self) -> None:
        if self.selected is None:
            raise KgarmentError("no clutch selected")
        name = self.selected
        self.state.delete_clutch(name)
        self.selected = None
        self.say(f"clutch {name} deleted")
        self.panel.sync_clutch()
        self.redraw(body=False)

    def undo(self) -> None:
        self.say("undone" if self.state.undo() else "nothing to undo")
        if self.selected not in self.state.clutch_names():
            self.selected = None
        self.panel.sync_clutch()
        self.redraw(body=False)

    def play(self, seconds: float = 2.0, steps: int = 24) -> None:
        """Animate the pose slider from rest to the target pose (in a thread)."""
        def run():
            for k in range(steps + 1):
                self.settings.pose = k / steps
                self.panel.pose.value = round(k / steps, 3)
                self.redraw()
                time.sleep(seconds / steps)

        threading.Thread(target=run, daemon=True).start()

