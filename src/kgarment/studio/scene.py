"""The 3D scene of the page: what the garment looks like now, and drawing it in viser.

:func:`shown_state` and :func:`garment_colors` decide what is shown from plain inputs
(the edited state, the settings, design A's simulation, design B, the open run) and are
tested without a browser; :class:`Scene` keeps the viser scene's handles and draws body,
garment and clutches, and casts the page's clicks onto what it drew.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np

from kgarment.clutch import ClutchStrip
from kgarment.studio import brush, view
from kgarment.studio.results import SimResult
from kgarment.studio.runs import RunHistory
from kgarment.studio.session import DesignB
from kgarment.studio.settings import Settings
from kgarment.studio.state import StudioState

GARMENT_LIFT = 0.002  # metres: the garment is drawn this far off the skin
CLUTCH_LIFT = 0.004
BODY_FIRST = 0.01  # metres: a click meets the body first when the body is this much nearer
NO_SHADOW = {"cast_shadow": False, "receive_shadow": False}  # shadows cost much in software WebGL
STATES = ("on", "off", "none")


def shown_state(settings: Settings, a: SimResult | None) -> str:
    """The clutch state whose equilibrium is shown: ON or OFF as set, else (a passive
    simulation) the one simulated."""
    want = "on" if settings.clutches_on else "off"
    keys = a.states() if a is not None else set()
    return want if want in keys or not keys else next(s for s in STATES if s in keys)


def garment_target(state: StudioState, settings: Settings, a: SimResult | None) -> np.ndarray:
    """(n, 3) garment positions of the shown motion, m: design A's equilibrium when it was
    simulated in this motion and clutch state, else the skin-tight pose."""
    key = (settings.motion, shown_state(settings, a))
    if a is not None and key in a.garment_x:
        return a.garment_x[key]
    return state.base_garment.vertices(settings.motion)


def garment_colors(state: StudioState, settings: Settings, x: np.ndarray, *, a: SimResult | None,
                   design_b: DesignB | None, run: RunHistory | None, k: int) -> tuple[np.ndarray, str]:
    """((m, 3) uint8 face colours, markdown legend) of the colour mode ``settings.mode``.

    x : (n, 3) garment positions shown (for strain), m;  a : design A's simulation;
    design_b : design B;  run, k : the open run and the iteration shown.
    """
    st, s = state, settings
    plain = view.design_colors(st.design, st.attached)
    if s.mode == "attachments":
        return view.attachment_colors(st.attached), view.legend("attachments")
    if s.mode == "strain":
        g = st.base_garment
        c, lo, hi = view.scalar_colors(view.face_strain(g.rest_vertices, g.faces, x), vmin=0.0)
        return c, view.legend("strain", lo, hi)
    if s.mode == "energy density":
        key = (s.motion, shown_state(s, a))
        if a is not None and key in a.density:
            # one scale for ON and OFF of a motion (each with its own, they looked alike)
            hi = max(float(np.percentile(v, 99)) for (m, _), v in a.density.items() if m == key[0])
            c, lo, hi = view.scalar_colors(a.density[key], vmin=0.0, vmax=hi if hi > 0 else None)
            return c, view.legend("energy density", lo, hi, note=f"design A, {key[0]}, clutches {key[1]}; "
                                  "one scale for the motion's ON and OFF")
        note = "no simulation of design A for this motion and clutch state: simulate first (showing the design)"
        return plain, view.legend("design", note=note)
    if s.mode == "compare":
        if design_b is None:
            return plain, view.legend("design", note="no design B yet")
        return view.compare_colors(st.design, design_b.design), view.legend("compare", note=f"B: {design_b.label}")
    if s.mode == "run":
        if run is None or run.n_iterations == 0:
            return plain, view.legend("design", note="no run open")
        return view.design_colors(run.design(k)), view.legend("run", note=run.summary(k))
    return plain, view.legend("design")


class Scene:
    """The viser scene's body, garment and clutch meshes (``server``: a viser server).

    on_drag(event) is called for drags on the garment.  ``shown`` is the (n, 3) garment as
    drawn (lifted off the skin), m: clicks are cast onto it.
    """

    def __init__(self, server, on_drag: Callable):
        self.server = server
        self._on_drag = on_drag
        self._body = self._garment = self._marker = None
        self._clutches: list = []
        self.shown: np.ndarray | None = None

    def draw_body(self, x: np.ndarray, faces: np.ndarray, visible: bool) -> None:
        """The body at positions x (nb, 3), m."""
        if self._body is None:
            self._body = self.server.scene.add_mesh_simple("/body", x, faces, color=view.SKIN, visible=visible,
                                                           **NO_SHADOW)
        else:
            self._body.vertices = x.astype(np.float32)
            self._body.visible = visible

    def draw_garment(self, x: np.ndarray, faces: np.ndarray, colors: np.ndarray) -> None:
        """The garment at positions x (n, 3), m, lifted off the skin, with face colours (m, 3) uint8."""
        self.shown = view.offset_along_normals(x, faces, GARMENT_LIFT)
        glb = view.glb_bytes(self.shown, faces, colors)
        if self._garment is None:
            self._garment = self.server.scene.add_glb("/garment", glb, **NO_SHADOW)
            self._garment.on_drag(self._on_drag)
        else:
            self._garment.glb_data = glb

    def draw_clutches(self, x: np.ndarray, faces: np.ndarray, strips: Sequence[ClutchStrip],
                      colors: Sequence[tuple[int, int, int]]) -> None:
        """The clutch strips bound to the garment at positions x (n, 3), m, one colour each."""
        for h in self._clutches:
            h.remove()
        lifted = view.offset_along_normals(x, faces, CLUTCH_LIFT)
        self._clutches = [self.server.scene.add_mesh_simple(f"/clutches/c{k}", strip.bound_positions(lifted, faces),
                                                            strip.faces, color=color, side="double", **NO_SHADOW)
                          for k, (strip, color) in enumerate(zip(strips, colors))]

    def draw_marker(self, position: np.ndarray | None) -> None:
        """A small ball at ``position`` (3,), m (the start of a clutch being placed), or none."""
        if self._marker is not None:
            self._marker.remove()
            self._marker = None
        if position is not None:
            self._marker = self.server.scene.add_icosphere("/pending", radius=0.006, color=view.SELECTED,
                                                           position=tuple(position))

    def displayed(self, face: int, bary: np.ndarray, faces: np.ndarray) -> np.ndarray:
        """(3,) where the garment point (face, barycentric (3,)) is drawn, m."""
        return np.asarray(bary) @ self.shown[faces[face]]

    def pick(self, origin, direction, faces: np.ndarray,
             body: tuple[np.ndarray, np.ndarray] | None = None) -> brush.Hit | None:
        """The garment hit of a ray (origin (3,), direction (3,)) in the drawn scene, or None
        when the ray misses the garment or meets the ``body`` (vertices (nb, 3), faces; None:
        not shown) first."""
        hit = brush.ray_hit(origin, direction, self.shown, faces)
        if hit is None:
            return None
        if body is not None:
            b = brush.ray_hit(origin, direction, *body)
            if b is not None and b.distance < hit.distance - BODY_FIRST:
                return None
        return hit

    def set_initial_camera(self, rest: np.ndarray) -> None:
        """The camera a new page starts with, looking at the garment's rest vertices (n, 3)."""
        c = rest.mean(axis=0)
        size = float(np.linalg.norm(rest.max(axis=0) - rest.min(axis=0)))
        cam = self.server.initial_camera
        cam.position = tuple(c + np.array([0.3, -1.0, 0.35]) * max(size, 0.3) * 1.6)
        cam.look_at = tuple(c)
        cam.up = (0.0, 0.0, 1.0)

    def look_at_face(self, face: int, faces: np.ndarray, distance: float = 0.35) -> np.ndarray:
        """Point every open page's camera at drawn garment ``face`` from outside, along its
        normal, from ``distance`` m; returns the camera position (3,)."""
        tri = self.shown[faces[face]]
        c = tri.mean(axis=0)
        n = np.cross(tri[1] - tri[0], tri[2] - tri[0])
        n /= np.linalg.norm(n)
        for client in self.server.get_clients().values():
            with client.atomic():
                client.camera.up_direction = (0.0, 0.0, 1.0)
                client.camera.position = tuple(c + distance * n)
                client.camera.look_at = tuple(c)
        return c + distance * n
