"""Pictures of a body with its garment, attachments and clutches in one pose."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from kgarment.render.raster import STANDARD_VIEWS, Layer, render_png

SKIN = (0.82, 0.76, 0.70, 1.0)
CLOTH = (0.25, 0.47, 0.85, 1.0)
ATTACHED = (0.92, 0.35, 0.12, 1.0)
CLUTCH_ON = (0.95, 0.78, 0.10, 1.0)
CLUTCH_OFF = (0.55, 0.50, 0.35, 1.0)
DESIGN_LEGEND = {0.0: "plain cloth", 1.0: "reinforced"}  # ``categories`` of :func:`render_design`


def face_colors(values: np.ndarray, cmap: str = "viridis", vmin=None, vmax=None) -> tuple[np.ndarray, float, float]:
    """(m, 4) RGBA colours for per-face values (m,), with the range used."""
    import matplotlib

    values = np.asarray(values, dtype=float)
    vmin = float(np.nanmin(values)) if vmin is None else vmin
    vmax = float(np.nanmax(values)) if vmax is None else vmax
    t = (values - vmin) / max(vmax - vmin, 1e-300)
    return matplotlib.colormaps[cmap](np.clip(t, 0, 1)), vmin, vmax


def faces_near(body_vertices: np.ndarray, body_faces: np.ndarray, garment_vertices: np.ndarray,
               margin: float = 0.05) -> np.ndarray:
    """The body faces (k, 3) of ``body_faces`` (mb, 3) whose vertices (nb, 3) all lie within
    ``margin`` metres of the garment's bounding box (garment vertices (n, 3)): a picture
    framed on the garment (a sleeve is a small part of the whole body)."""
    bv = np.asarray(body_vertices)
    g = np.asarray(garment_vertices)
    lo, hi = g.min(0) - margin, g.max(0) + margin
    inside = np.all((bv >= lo) & (bv <= hi), axis=1)
    return np.asarray(body_faces)[inside[np.asarray(body_faces)].all(axis=1)]


def render_scene(path, body_vertices, body_faces, garment_vertices=None, garment_faces=None,
                 attached=None, face_values=None, clutches=(), clutch_activation=None,
                 views=STANDARD_VIEWS, title=None, cmap="viridis", value_label="",
                 vmin=None, vmax=None, height_px=600, categories=None) -> Path:
    """Render body (nb, 3)/(mb, 3), garment (n, 3)/(m, 3) and clutches to a PNG.

    attached : (m,) bool faces drawn in the attachment colour;
    face_values : (m,) per-face values drawn with ``cmap`` (e.g. energy density, J/m^2);
    clutches : sequence of (vertices (nc, 3), faces (mc, 3)) in the same pose;
    clutch_activation : (K,) activations in [0, 1] (ON colour at 1, OFF at 0);
    categories : {value: label} -- face_values take only these values: a legend of their
    colours (and the clutches') replaces the colour bar (designs: plain / reinforced).
    """
    layers = [Layer(np.asarray(body_vertices), np.asarray(body_faces), SKIN, cull=True)]
    colorbar = None
    if garment_vertices is not None:
        m = len(garment_faces)
        if face_values is not None:
            col, lo, hi = face_colors(face_values, cmap, vmin, vmax)
            colorbar = (cmap, lo, hi, value_label)
        else:
            col = np.tile(CLOTH, (m, 1))
        if attached is not None and face_values is None:
            col[np.asarray(attached, bool)] = ATTACHED
        layers.append(Layer(np.asarray(garment_vertices), np.asarray(garment_faces), col,
                            depth_bias=0.004, offset=0.003))
    legend = None
    if categories and colorbar is not None:
        vals = np.array(list(categories), dtype=float)
        cols, _, _ = face_colors(vals, cmap, colorbar[1], colorbar[2])
        legend = [(label, tuple(c)) for label, c in zip(categories.values(), cols)]
        if len(clutches):
            legend.append(("clutch", tuple(CLUTCH_ON) if clutch_activation is None else tuple(CLUTCH_OFF)))
        colorbar = None
    for k, (cv, cf) in enumerate(clutches):
        g = 1.0 if clutch_activation is None else float(clutch_activation[k])
        c = g * np.array(CLUTCH_ON) + (1 - g) * np.array(CLUTCH_OFF)
        layers.append(Layer(np.asarray(cv), np.asarray(cf), c, depth_bias=0.008, offset=0.005))
    return render_png(layers, path, views=views, title=title, colorbar=colorbar, height_px=height_px, legend=legend)


def render_design(path, body_vertices, body_faces, garment_vertices, garment_faces, design,
                  clutches=(), title=None, height_px=600) -> Path:
    """Render a design: faces of ``design`` (m,) above 0.5 reinforced, with a plain /
    reinforced / clutch legend; other arguments as :func:`render_scene`."""
    return render_scene(path, body_vertices, body_faces, garment_vertices, garment_faces,
                        face_values=(np.asarray(design) > 0.5).astype(float), clutches=clutches, cmap="Blues",
                        vmin=-0.3, vmax=1.2, value_label="reinforced", categories=DESIGN_LEGEND, title=title,
                        height_px=height_px)


def render_poses(out, body, garment, strips, motions, views=STANDARD_VIEWS) -> list[Path]:
    """One PNG per pose (rest and each of ``motions``) of the skin-tight garment on the
    posed body with its attachments and clutches: ``out/<garment>_<pose>.png``.

    body : kgarment.body.Body;  garment : kgarment.garment.Garment;  strips : ClutchStrip list.
    """
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    paths = []
    for motion in ("rest",) + tuple(motions):
        gv = garment.vertices(motion)
        cl = [(c.bound_positions(gv, garment.faces), c.faces) for c in strips]
        paths.append(render_scene(out / f"{garment.name}_{motion}.png", body.vertices(motion), body.faces, gv,
                                  garment.faces, attached=garment.attached, views=views, clutches=cl,
                                  title=f"{garment.name} (subdivision {garment.subdivision}) - {motion}"))
    return paths
