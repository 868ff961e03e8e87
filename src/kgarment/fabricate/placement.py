"""The placement sheet: where every piece and clutch goes on the base garment.

Each base garment panel (:mod:`kgarment.fabricate.panels`) is drawn flat at 1:1 in
millimetres, turned "up" like the pieces, with every reinforcement piece filled in place
and named as on the cut sheet (P1, ...), and every clutch drawn along its centre line with
its button circles and its tag (C1, ...). Written as ``placement.svg`` (1:1) and a small
``placement.png``; :func:`render_placement_3d` draws the same labels on the 3D garment.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from kgarment.fabricate.annotate import BUTTON_MM, leader
from kgarment.fabricate.labels import Label, LabelPlacer
from kgarment.fabricate.layout import MM, allowance_outlines, shelf_pack, up_direction, up_rotation
from kgarment.fabricate.outline import smooth_outline

PANEL_TEXT_MM = 12.0
PIECE_TEXT_MM = 8.0
CLUTCH_TEXT_MM = 7.0
PREVIEW_PX = 1000  # the longer side of placement.png


def piece_color(k: int) -> tuple:
    import matplotlib

    return tuple(matplotlib.colormaps["tab10"](k % 10))


@dataclass(frozen=True)
class PanelDrawing:
    """One panel on the placement sheet (mm): name; outlines, closed (k, 2), the outer one
    first; cut : the cut line with the seam allowance (or the outlines); pieces : (piece
    index, label, [(k, 2) polygons]); clutches : (tag, [(k, 2) centre line runs], (b, 2)
    buttons); area_3d (m^2) and max_length_distortion of its flattening."""

    name: str
    outlines: tuple
    cut: tuple
    pieces: tuple
    clutches: tuple
    area_3d: float
    max_length_distortion: float


@dataclass(frozen=True)
class PlacementSheet:
    """All panels packed: width, height mm, panels, labels (placed without overlap)."""

    width: float
    height: float
    panels: tuple[PanelDrawing, ...]
    labels: tuple[Label, ...]


def _draw_panel(panel, patterns, strips, notes, allowance: float) -> PanelDrawing:
    from shapely import Polygon, unary_union

    patch = panel.patch
    V, F, uv = patch.mesh.vertices, patch.mesh.faces, patch.flat.uv
    R = up_rotation(up_direction(V, F, uv))
    pts = (MM * uv) @ R.T
    outl = tuple(smooth_outline(pts[lp], 10, rounds=2) for lp in patch.mesh.loops())
    gface = patch.mesh.garment_face
    pieces = []
    for k, rp in enumerate(patterns.patches):
        local = np.flatnonzero(np.isin(gface, rp.mesh.garment_face))
        if not len(local):
            continue
        shape = unary_union([Polygon(t) for t in pts[F[local]]]).buffer(0.01).buffer(-0.01)
        polys = [np.asarray(g.exterior.coords) for g in getattr(shape, "geoms", [shape]) if g.area > 1.0]
        pieces.append((k, rp.label, polys))
    clutches = []
    for c, n in zip(strips, notes):
        runs, run = [], []
        for v in list(np.asarray(c.centerline)) + [None]:
            q = None if v is None else patch.map_bary(int(c.bind_face[v]), c.bind_bary[v])
            if q is not None:
                run.append(MM * q @ R.T)
            elif run:
                runs.append(np.array(run))
                run = []
        found = [patch.map_bary(int(c.bind_face[a]), c.bind_bary[a]) for a in np.asarray(c.anchors)]
        buttons = np.array([MM * q @ R.T for q in found if q is not None]).reshape(-1, 2)
        if runs or len(buttons):
            clutches.append((n.tag, [r for r in runs if len(r) > 1], buttons))
    return PanelDrawing(panel.name, outl, allowance_outlines(outl, allowance) or outl, tuple(pieces),
                        tuple(clutches), patch.flat.area_3d, patch.flat.max_length_distortion)


def _shift(d: PanelDrawing, s: np.ndarray) -> PanelDrawing:
    return PanelDrawing(d.name, tuple(o + s for o in d.outlines), tuple(o + s for o in d.cut),
                        tuple((k, lab, [p + s for p in polys]) for k, lab, polys in d.pieces),
                        tuple((t, [r + s for r in runs], b + s) for t, runs, b in d.clutches),
                        d.area_3d, d.max_length_distortion)


def placement_sheet(panels, patterns, strips, notes, allowance: float = 0.0, width: float = 1500.0,
                    gap: float = 20.0) -> PlacementSheet:
    """Lay the panels out (mm, 1:1) with the pieces (``patterns``) and clutches (``strips``,
    their ``notes`` from :func:`kgarment.fabricate.annotate.clutch_notes`) drawn in place."""
    from shapely import Polygon

    drawings = [_draw_panel(p, patterns, strips, notes, allowance) for p in panels]
    lo = [np.concatenate(d.cut).min(axis=0) for d in drawings]
    sizes = [np.concatenate(d.cut).max(axis=0) - a for d, a in zip(drawings, lo)]
    corners, w, h = shelf_pack(sizes, width, gap)
    drawings = [_shift(d, c - a) for d, c, a in zip(drawings, corners, lo)]
    r = 0.5 * BUTTON_MM + 0.3
    hard = [np.r_[b - r, b + r] for d in drawings for _, _, bs in d.clutches for b in bs]
    lines = [np.vstack([o, o[:1]]) for d in drawings for o in d.cut]
    lines += [run for d in drawings for _, runs, _ in d.clutches for run in runs]
    placer = LabelPlacer(hard, lines)
    for d in drawings:
        region = Polygon(d.outlines[0]).buffer(0)
        placer.place(d.name, np.asarray(region.representative_point().coords[0]), PANEL_TEXT_MM, "panel", region,
                     bold=True)
        for _, lab, polys in d.pieces:
            big = max(polys, key=lambda p: abs(Polygon(p).area))
            spot = Polygon(big).buffer(0).representative_point().coords[0]
            placer.place(lab, spot, PIECE_TEXT_MM, "piece", Polygon(big).buffer(0), bold=True, avoid_lines=False)
        for tag, runs, buttons in d.clutches:
            longest = max(runs, key=len) if runs else buttons
            placer.place(tag, longest[len(longest) // 2], CLUTCH_TEXT_MM, "clutch", region, avoid_lines=False)
    return PlacementSheet(w, h, tuple(drawings), tuple(placer.labels))


def _draw(ax, sheet: PlacementSheet, scale: float) -> None:
    from matplotlib.patches import Circle
    from matplotlib.patches import Polygon as MPolygon

    pt = 72.0 / 25.4 * scale
    for d in sheet.panels:
        for o in d.cut:
            ax.add_patch(MPolygon(o, closed=True, fill=False, ec="0.2", lw=max(0.5 * pt, 0.3)))
        if d.cut is not d.outlines:
            for o in d.outlines:
                ax.add_patch(MPolygon(o, closed=True, fill=False, ec="0.4", lw=max(0.3 * pt, 0.2), ls="--"))
        for k, _, polys in d.pieces:
            for p in polys:
                ax.add_patch(MPolygon(p, closed=True, fc=piece_color(k), ec="0.3", lw=max(0.3 * pt, 0.2), alpha=0.45))
        for _, runs, buttons in d.clutches:
            for run in runs:
                ax.plot(run[:, 0], run[:, 1], color="#d4a000", lw=max(8.0 * pt, 1.0), solid_capstyle="butt")
            for b in buttons:
                ax.add_patch(Circle(b, 0.5 * BUTTON_MM, fill=False, ec="#0000ff", lw=max(0.4 * pt, 0.3)))
    for lab in sheet.labels:
        line = leader(lab)
        if line is not None:
            ax.plot(line[:, 0], line[:, 1], color="0.3", lw=max(0.3 * pt, 0.3))
        ax.text(lab.at[0], lab.at[1], lab.text, ha="center", va="center", fontsize=lab.size * pt,
                weight="bold" if lab.bold else "normal")


def write_placement(sheet: PlacementSheet, out, title: str = "") -> list[Path]:
    """placement.svg (1:1, mm) and placement.png (a preview) in the folder ``out``."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    out = Path(out)
    files = []
    head = 30.0  # mm of title above the panels
    for name, scale in (("placement.svg", 1.0), ("placement.png", None)):
        if scale is None:  # the preview: PREVIEW_PX on the longer side at 100 dpi
            scale = PREVIEW_PX / 100 * 25.4 / max(sheet.width, sheet.height + head)
        fig = plt.figure(figsize=(sheet.width * scale / 25.4, (sheet.height + head) * scale / 25.4))
        ax = fig.add_axes((0, 0, 1, sheet.height / (sheet.height + head)))
        _draw(ax, sheet, scale)
        ax.set_xlim(0, sheet.width)
        ax.set_ylim(0, sheet.height)
        ax.set_aspect("equal")
        ax.axis("off")
        fig.text(0.01, 1 - 0.5 * head / (sheet.height + head), (title + ": " if title else "") +
                 "placement on the base garment's panels (P: reinforcement pieces, C: clutches, circles: snap "
                 "buttons); 1:1 in the SVG", fontsize=6.0 * 72 / 25.4 * scale, va="center")
        fig.savefig(out / name, dpi=100, facecolor="white")
        plt.close(fig)
        files.append(out / name)
    return files


def render_placement_3d(path, garment, patterns, strips, notes, body=None, views=("front", "back"),
                        height_px: int = 640) -> Path:
    """A PNG of the rest garment (on the body when given) from ``views``, every piece in its
    placement colour and tagged P1, ..., every clutch in yellow and tagged C1, ...; a tag is
    drawn in the views that see its spot. garment : Garment; patterns : PatternSet; strips,
    notes : the clutches and their notes."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.collections import PolyCollection

    from kgarment.render import VIEWS, Layer
    from kgarment.render.raster import project

    V, F = garment.rest_vertices, garment.faces
    col = np.tile((0.78, 0.80, 0.84, 1.0), (garment.n_faces, 1))
    spots = []  # (text, (3,) point, (3,) normal, colour)
    normals = np.cross(V[F[:, 1]] - V[F[:, 0]], V[F[:, 2]] - V[F[:, 0]])
    for k, p in enumerate(patterns.patches):
        fs = p.mesh.garment_face
        col[fs] = piece_color(k)
        cen = V[F[fs]].mean(axis=1)
        mid = cen[np.argmin(np.linalg.norm(cen - cen.mean(axis=0), axis=1))]
        spots.append((p.label, mid, normals[fs].sum(axis=0), "k"))
    layers = [Layer(V, F, col, depth_bias=0.004, offset=0.003)]
    if body is not None:
        layers.insert(0, Layer(body.rest_vertices, body.faces, (0.82, 0.76, 0.70, 1.0), cull=True))
    for c, n in zip(strips, notes):
        layers.append(Layer(c.vertices, c.faces, (0.95, 0.78, 0.10, 1.0), depth_bias=0.008, offset=0.005))
        mid = c.vertices[np.asarray(c.centerline)[len(c.centerline) // 2]]
        f = int(c.bind_face[np.asarray(c.centerline)[len(c.centerline) // 2]])
        spots.append((n.tag + (" (no load)" if n.loaded is False else ""), mid, normals[f], "#7a5a00"))
    fig, axes = plt.subplots(1, len(views), figsize=(0.55 * height_px / 100 * len(views), height_px / 100), dpi=100)
    for ax, view in zip(np.atleast_1d(axes), views):
        polys, cols = project(layers, view)
        ax.add_collection(PolyCollection(polys, facecolors=cols, edgecolors="none", antialiased=False))
        to_cam, up = (np.asarray(a, float) for a in VIEWS[view])
        right = np.cross(up, to_cam)
        right /= np.linalg.norm(right)
        up = np.cross(to_cam / np.linalg.norm(to_cam), right)
        lo, hi = polys.reshape(-1, 2).min(0), polys.reshape(-1, 2).max(0)
        placer = LabelPlacer()
        for text, p3, nrm, color in spots:
            if nrm @ to_cam <= 0:  # faces away from this view
                continue
            at = np.array([p3 @ right, p3 @ up]) * MM  # mm on the screen plane
            lab = placer.place(text, at, 30.0, "piece", avoid_lines=False)
            ax.annotate(text, xy=at / MM, xytext=lab.at / MM, ha="center", va="center", fontsize=8, color=color,
                        weight="bold", bbox={"boxstyle": "round,pad=0.15", "fc": "white", "ec": "0.5", "lw": 0.4, "alpha": 0.85},
                        arrowprops={"arrowstyle": "-", "lw": 0.5, "color": "0.3"} if lab.moved else None)
        pad = 0.05 * (hi - lo).max()
        ax.set_xlim(lo[0] - pad, hi[0] + pad)
        ax.set_ylim(lo[1] - pad, hi[1] + pad)
        ax.set_aspect("equal")
        ax.axis("off")
        ax.set_title(view, fontsize=9)
    fig.subplots_adjust(left=0, right=1, bottom=0, top=0.95, wspace=0)
    path = Path(path)
    fig.savefig(path, dpi=100, facecolor="white")
    plt.close(fig)
    return path
