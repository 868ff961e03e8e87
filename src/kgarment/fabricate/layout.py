"""The cutting sheet: patches placed at 1:1 scale with their marks, in millimetres.

Each patch is turned so that the garment's "up" (+Z of the rest body, carried into the patch
through its flattening) points up the sheet, then shelf-packed left to right, top to
bottom, after a 100 mm reference square. Sheet coordinates are millimetres with y up.

Marks on a patch: its label and area; an "UP" arrow; a snap-button mark at every clutch
anchor that lies on it (drawn by the writers as a circle with a cross); the clutch centre line; notches where its
edge runs along a garment boundary loop (hem, cuff, ...), labelled with the loop's name;
and a notch labelled with the seam name at the middle of every seam cut through it, on both
sides, to line the pieces up when sewing. With a seam allowance the outline becomes the sew
line and the cut line runs the allowance outside it (holes shrink by as much).

The sheet also holds the 100 mm reference square and a legend (line kinds, the clutches and
whether each carries load); every text is placed by :mod:`kgarment.fabricate.annotate` so
that no two overlap.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from kgarment.fabricate.annotate import (
    BUTTON_MM,
    SQUARE_MM,
    clutch_notes,
    label_sheet,
    legend_block,
)
from kgarment.fabricate.flatten import face_jacobians, triangle_frames
from kgarment.fabricate.outline import point_segment_distance, smooth_outline
from kgarment.fabricate.patterns import PatternSet
from kgarment.garment.topology import triangle_areas

MM = 1000.0
NOTCH_MM = 5.0


@dataclass(frozen=True)
class Mark:
    """A drawn mark: polyline (k, 2) mm (closed if ``closed``), optional text at ``at`` (2,)."""

    kind: str  # "arrow", "clutch", "loop", "seam"
    points: np.ndarray
    closed: bool = False
    text: str = ""
    at: np.ndarray | None = None


@dataclass(frozen=True)
class Piece:
    """One patch on the sheet.

    label : "P1", ...; outlines : closed polylines (k, 2) mm, the outer one first (smoothed);
    raw_outlines : the same loops through the flattened mesh boundary, unsmoothed;
    rotation : (2, 2), offset : (2,), with sheet_mm = rotation @ (1000 uv) + offset;
    buttons : (b, 2) mm centres of the snap-button marks; button_names : b names;
    marks : drawn marks; text, text_at : the label text and the spot it names (2,) mm;
    allowance : closed polylines (k, 2) mm, the cut line a seam allowance outside the
    outlines (the outer one first), empty without an allowance.
    """

    label: str
    outlines: tuple[np.ndarray, ...]
    raw_outlines: tuple[np.ndarray, ...]
    rotation: np.ndarray
    offset: np.ndarray
    buttons: np.ndarray
    button_names: tuple[str, ...]
    marks: tuple[Mark, ...]
    text: str
    text_at: np.ndarray
    allowance: tuple[np.ndarray, ...] = ()

    @property
    def cut_lines(self) -> tuple[np.ndarray, ...]:
        """The closed polylines (k, 2) mm to cut along: the allowance, or the outlines."""
        return self.allowance or self.outlines

    def to_sheet(self, uv: np.ndarray) -> np.ndarray:
        """(k, 2) sheet millimetres of flat patch points uv (k, 2) in metres."""
        return (MM * np.asarray(uv, float)) @ self.rotation.T + self.offset


@dataclass(frozen=True)
class Sheet:
    """The whole cutting layout: width, height in mm, pieces, the reference square
    (5, 2) mm closed, and a title; allowance : the seam allowance, mm; legend : the legend's
    sample lines as (layer, (k, 2) mm polyline); labels : every text on the sheet, placed;
    clutches : one note per clutch (number, name, load)."""

    width: float
    height: float
    pieces: tuple[Piece, ...]
    square: np.ndarray
    title: str
    allowance: float = 0.0
    legend: tuple = ()
    labels: tuple = ()
    clutches: tuple = ()


def up_direction(V: np.ndarray, F: np.ndarray, uv: np.ndarray, up=(0.0, 0.0, 1.0)) -> np.ndarray | None:
    """(2,) unit image of the 3D direction ``up`` in a flattening (area-weighted mean of its
    per-triangle images), or None where the patch is nearly level (``up`` is its normal).
    V (n, 3), F (f, 3), uv (n, 2)."""
    x, y = triangle_frames(V, F)
    u = np.asarray(up, float)
    local = np.stack([x @ u, y @ u], axis=1)  # (f, 2) up projected on each triangle
    w = triangle_areas(V, F)
    img = np.einsum("fij,fj->fi", face_jacobians(V, F, uv), local)
    s = (w[:, None] * img).sum(0)
    n = float(np.linalg.norm(s))
    return None if n < 0.2 * w.sum() else s / n


def up_rotation(d: np.ndarray | None) -> np.ndarray:
    """(2, 2) rotation taking the direction d (2,) to +y (identity for None)."""
    if d is None:
        return np.eye(2)
    c, s = d[1], d[0]  # the rotation taking d to +y
    return np.array([[c, -s], [s, c]])


def _notch(a: np.ndarray, b: np.ndarray, kind: str, text: str) -> Mark:
    """A notch at the middle of boundary edge a -> b (mm, interior on the left)."""
    m = 0.5 * (a + b)
    t = (b - a) / max(np.linalg.norm(b - a), 1e-12)
    inward = np.array([-t[1], t[0]])
    return Mark(kind, np.stack([m, m + NOTCH_MM * inward]), text=text, at=m + 2.2 * NOTCH_MM * inward)


def _loop_marks(patch, sheet_uv, garment) -> list[Mark]:
    """Notches where the patch edge runs along a garment boundary loop: one in the middle of
    every run of edges on the loop, the loop's name written at the longest run."""
    marks = []
    gv = patch.mesh.garment_vertex
    for name, loop in garment.loops.items():
        loop = np.asarray(loop)
        on_loop = set(zip(loop.tolist(), np.roll(loop, -1).tolist()))
        on_loop |= {(j, i) for i, j in on_loop}
        runs = []  # (length in mm, a, b) of the middle edge of each run
        for lp in patch.mesh.loops():
            nx = np.roll(lp, -1)
            on = np.array([(int(i), int(j)) in on_loop for i, j in zip(gv[lp], gv[nx], strict=True)])
            if not on.any():
                continue
            k0 = int(np.argmin(on)) if not on.all() else 0  # start the scan off the loop
            r, idx = np.roll(on, -k0), np.roll(np.arange(len(on)), -k0)
            length = np.linalg.norm(sheet_uv[nx] - sheet_uv[lp], axis=1)
            start = None
            for i in range(len(r) + 1):
                if i < len(r) and r[i] and start is None:
                    start = i
                elif (i == len(r) or not r[i]) and start is not None:
                    e = idx[(start + i - 1) // 2]
                    runs.append((float(length[idx[start:i]].sum()), sheet_uv[lp[e]], sheet_uv[nx[e]]))
                    start = None
        if runs:
            best = max(range(len(runs)), key=lambda k: runs[k][0])
            marks += [_notch(a, b, "loop", name if k == best else "") for k, (_, a, b) in enumerate(runs)]
    return marks


def _seam_marks(patch, sheet_uv, seams) -> list[Mark]:
    marks = []
    gv = patch.mesh.garment_vertex
    for lp in patch.mesh.loops():
        a, b = gv[lp], gv[np.roll(lp, -1)]
        for s in seams:
            path = s.garment_vertices
            j = (len(path) - 2) // 2
            pair = {int(path[j]), int(path[j + 1])}
            for e in np.flatnonzero([{int(x), int(y)} == pair for x, y in zip(a, b)]):
                marks.append(_notch(sheet_uv[lp[e]], sheet_uv[np.roll(lp, -1)[e]], "seam", s.label))
    return marks


def _clutch_marks(patch, strips, uv_to_sheet):
    buttons, names, marks = [], [], []
    for c in strips:
        for k, a in enumerate(np.asarray(c.anchors)):
            q = patch.map_bary(int(c.bind_face[a]), c.bind_bary[a])
            if q is not None:
                buttons.append(uv_to_sheet(q[None])[0])
                names.append(f"{c.name}:{'start' if k < 3 else 'end'}{k % 3 + 1}")
        line = [patch.map_bary(int(c.bind_face[v]), c.bind_bary[v]) for v in np.asarray(c.centerline)]
        run: list = []
        for q in line + [None]:
            if q is not None:
                run.append(q)
            elif run:
                if len(run) > 1:
                    pts = uv_to_sheet(np.array(run))
                    marks.append(Mark("clutch", pts))
                run = []
    return np.array(buttons).reshape(-1, 2), tuple(names), marks


def _label_spot(outlines: list[np.ndarray], centres: np.ndarray) -> np.ndarray:
    """The triangle centre (k, 2) farthest from the outlines: where the label goes."""
    d = np.min([point_segment_distance(centres, o) for o in outlines], axis=0)
    return centres[int(np.argmax(d))]


def allowance_outlines(outlines, allowance: float) -> tuple[np.ndarray, ...]:
    """The cut line ``allowance`` mm outside the closed polylines ``outlines`` (k, 2) mm (the
    outer one first, then holes), with round corners so that every point of it lies exactly
    ``allowance`` from the outline; () for no allowance."""
    if allowance <= 0:
        return ()
    from shapely import Polygon

    shape = Polygon(outlines[0], [o for o in outlines[1:] if len(o) > 2]).buffer(0)  # untangled
    grown = shape.buffer(allowance, join_style="round", quad_segs=16)
    polys = sorted(getattr(grown, "geoms", [grown]), key=lambda g: -g.area)
    rings = [polys[0].exterior] + [r for g in polys for r in g.interiors] + [g.exterior for g in polys[1:]]
    return tuple(np.asarray(r.coords)[:-1] for r in rings)


def place_piece(patch, garment, strips, seams, smooth_iterations: int = 10, allowance: float = 0.0) -> Piece:
    """A patch turned "up" and drawn with its marks, before packing (offset 0); ``allowance``
    mm of seam allowance around it."""
    V, F, uv = patch.mesh.vertices, patch.mesh.faces, patch.flat.uv
    up = up_direction(V, F, uv)
    R = up_rotation(up)
    pts = (MM * uv) @ R.T
    loops = patch.mesh.loops()
    raw = [pts[lp] for lp in loops]
    outl = [smooth_outline(o, smooth_iterations, rounds=2 if smooth_iterations > 0 else 0) for o in raw]
    to_sheet = lambda q: (MM * np.asarray(q)) @ R.T
    buttons, names, marks = _clutch_marks(patch, strips, to_sheet)
    marks += _loop_marks(patch, pts, garment) + _seam_marks(patch, pts, seams)
    at = _label_spot(raw, pts[F].mean(axis=1))
    if up is not None:
        size = float(np.ptp(pts, axis=0).min())
        length = float(np.clip(0.3 * size, 8.0, 40.0))
        tip = at + [0.0, length]
        arrow = np.array([at, tip, tip + [-0.15 * length, -0.25 * length], tip, tip + [0.15 * length, -0.25 * length]])
        marks.append(Mark("arrow", arrow, text="UP", at=tip + [0.0, 3.0]))
    text = f"{patch.label} {1e4 * patch.flat.area_3d:.0f} cm2"
    return Piece(patch.label, tuple(outl), tuple(raw), R, np.zeros(2), buttons, names, tuple(marks), text, at,
                 allowance_outlines(outl, allowance))


def _moved(p: Piece, shift: np.ndarray) -> Piece:
    mv = lambda a: a + shift
    marks = tuple(Mark(m.kind, mv(m.points), m.closed, m.text, None if m.at is None else mv(m.at)) for m in p.marks)
    return Piece(p.label, tuple(map(mv, p.outlines)), tuple(map(mv, p.raw_outlines)), p.rotation,
                 p.offset + shift, mv(p.buttons), p.button_names, marks, p.text, mv(p.text_at),
                 tuple(map(mv, p.allowance)))


def _bounds(p: Piece) -> tuple[np.ndarray, np.ndarray]:
    allp = np.concatenate(list(p.outlines) + list(p.raw_outlines) + list(p.allowance) + [m.points for m in p.marks]
                          + [p.buttons + d for d in ((BUTTON_MM, BUTTON_MM), (-BUTTON_MM, -BUTTON_MM))])
    return allp.min(axis=0), allp.max(axis=0)


def shelf_pack(sizes, width: float, gap: float = 10.0) -> tuple[np.ndarray, float, float]:
    """Shelf packing, in the given order, left to right and top down, on a sheet at most
    ``width`` mm wide (wider only where one item is). sizes : (k, 2) mm.
    Returns (lower-left corners (k, 2) mm with y up, used width, height)."""
    sizes = np.asarray(sizes, float).reshape(-1, 2)
    width = max([width] + [s[0] + 2 * gap for s in sizes])
    x, y, shelf, spots = gap, gap, 0.0, []
    for s in sizes:  # y grows downwards while packing; flipped at the end
        if x + s[0] + gap > width and x > gap:
            x, y, shelf = gap, y + shelf + gap, 0.0
        spots.append((x, y))
        x += s[0] + gap
        shelf = max(shelf, s[1])
    height = y + shelf + gap
    used = max([x0 + s[0] + gap for (x0, _), s in zip(spots, sizes)] + [2 * gap])
    corners = np.array([[x0, height - y0 - s[1]] for (x0, y0), s in zip(spots, sizes)]).reshape(-1, 2)
    return corners, float(used), float(height)


def layout_sheet(patterns: PatternSet, garment, strips, sheet_width: float = 600.0, gap: float = 10.0,
                 smooth_iterations: int = 10, title: str = "", allowance: float = 0.0, loads=None) -> Sheet:
    """Pack every patch onto a sheet at most ``sheet_width`` mm wide (wider only where one patch
    is), shelf by shelf, tallest first, after the reference square and the legend; the sheet
    is cropped to what it holds. allowance : seam allowance, mm; loads : the design's
    ``kgarment.evaluate.loads.LoadReport`` (clutches that carry no load are flagged), or None
    (not evaluated)."""
    pieces = [place_piece(p, garment, strips, patterns.seams, smooth_iterations, allowance) for p in patterns.patches]
    notes = clutch_notes(strips, pieces, loads)
    legend_lines, legend_size = legend_block(title, allowance, notes)
    boxes = [_bounds(p) for p in pieces]
    sizes = [hi - lo for lo, hi in boxes]
    order = sorted(range(len(pieces)), key=lambda i: -sizes[i][1])
    fixed = [np.array([SQUARE_MM, SQUARE_MM + 8.0]), legend_size]
    corners, width, height = shelf_pack(fixed + [sizes[i] for i in order], sheet_width, gap)
    placed = [None] * len(pieces)
    for k, i in enumerate(order):
        placed[i] = _moved(pieces[i], corners[2 + k] - boxes[i][0])
    x, y0 = corners[0] + [0.0, 8.0]
    square = np.array([[x, y0], [x + SQUARE_MM, y0], [x + SQUARE_MM, y0 + SQUARE_MM], [x, y0 + SQUARE_MM], [x, y0]])
    sheet = Sheet(float(width), float(height), tuple(placed), square, title, float(allowance), (), (), tuple(notes))
    return label_sheet(sheet, legend_lines, corners[1] + [0.0, legend_size[1]])
