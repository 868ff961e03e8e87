"""Everything written on the cutting sheet: the legend, the clutch notes and every label.

Clutches are numbered C1, C2, ... in the problem's order. Each clutch end that lies on a
piece is labelled beside its three button circles ("C1 elbow.R start"); a clutch that
carries no load in the design's evaluation (:mod:`kgarment.evaluate.loads`: its share of the
ON - OFF energy below :data:`kgarment.constants.LOADED_SHARE` in every motion) is labelled
"no load" there and in the legend; without an evaluation the legend says "not evaluated".
The legend lists every clutch, also those whose ends sit on the base garment (no piece).
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np

from kgarment.fabricate.labels import Label, LabelPlacer, text_extent

SQUARE_MM = 100.0  # the reference square's side
BUTTON_MM = 5.0  # diameter of the snap-button mark
PIECE_TEXT_MM = 5.0
CLUTCH_TEXT_MM = 3.5
MARK_TEXT_MM = 3.0
LEGEND_TEXT_MM = 3.5
LEGEND_LINE_MM = 6.0
SAMPLE_MM = 12.0  # length of a legend's sample line


@dataclass(frozen=True)
class ClutchNote:
    """One clutch on the sheet: tag "C1", ...; length, width in mm; ends : where its start and
    end anchors lie ("P2" or "base garment"); loaded : True, False (no load in any evaluated
    motion) or None (not evaluated); status : the load in words."""

    tag: str
    name: str
    length_mm: float
    width_mm: float
    ends: tuple[str, str]
    loaded: bool | None
    status: str


def load_status(name: str, loads) -> tuple[bool | None, str]:
    """(loaded, words) for the clutch ``name`` from a LoadReport (or None: not evaluated)."""
    if loads is None or name not in loads.clutch_names:
        return None, "load not evaluated"
    rows = [c for c in loads.clutches if c.clutch == name]
    on = [c for c in rows if c.loaded]
    if on:
        best = max(on, key=lambda c: c.effect)
        return True, (f"loaded in {', '.join(c.motion for c in on)} (share {best.share:.2f}, needed "
                      f"{best.needed:.2f}, {best.tension_N:.0f} N)")
    shares = [c.effect for c in rows if math.isfinite(c.effect)]
    if not shares:
        return False, "NO LOAD: switching the clutches on changes nothing in the evaluated motions"
    return False, f"NO LOAD in the evaluated motions (share and needed at most {max(shares):.2f})"


def clutch_notes(strips, pieces, loads=None) -> list[ClutchNote]:
    """A :class:`ClutchNote` per clutch strip; ``pieces`` the sheet's pieces (their buttons
    say which piece each end lies on); ``loads`` a LoadReport or None."""
    notes = []
    for k, c in enumerate(strips):
        ends = []
        for end in ("start", "end"):
            on = [p.label for p in pieces if any(n.startswith(f"{c.name}:{end}") for n in p.button_names)]
            ends.append("/".join(dict.fromkeys(on)) or "base garment")
        loaded, status = load_status(c.name, loads)
        notes.append(ClutchNote(f"C{k + 1}", c.name, 1e3 * c.length, 1e3 * c.width, (ends[0], ends[1]), loaded,
                                status))
    return notes


def legend_block(title: str, allowance: float, notes) -> tuple[list[tuple[str | None, str, float]], np.ndarray]:
    """The legend's lines as (sample kind or None, text, font size mm) and its size (2,) mm.
    Sample kinds: "CUT", "SEW", "MARK", "BUTTON", "REFERENCE" (the writers' layers)."""
    cut = "cut line" + (f", {allowance:g} mm seam allowance included" if allowance > 0 else "")
    lines = [(None, title or "kgarment cut patterns", 4.5),
             (None, "1:1 in millimetres: print or cut at actual size, then measure the 100 mm square", LEGEND_TEXT_MM),
             ("CUT", cut, LEGEND_TEXT_MM)]
    if allowance > 0:
        lines.append(("SEW", "sew line: where the piece's edge lies on the garment", LEGEND_TEXT_MM))
    lines += [("MARK", "marks: clutch centre line, notches (hem, cuffs, seams), UP arrow", LEGEND_TEXT_MM),
              ("BUTTON", "snap button at a clutch anchor (3 per clutch end)", LEGEND_TEXT_MM),
              ("REFERENCE", "reference: the square measures 100 mm x 100 mm", LEGEND_TEXT_MM),
              (None, "clutches (C1, ... beside their buttons; ends on pieces P1, ... or on the base garment):",
               LEGEND_TEXT_MM)]
    for n in notes:
        lines.append((None, (f"{n.tag} {n.name}: {n.length_mm:.0f} x {n.width_mm:.0f} mm, start on {n.ends[0]}, "
                            f"end on {n.ends[1]}; {n.status}"), LEGEND_TEXT_MM))
    width = max(SAMPLE_MM + 4.0 + text_extent(t, s)[0] for _, t, s in lines)
    return lines, np.array([width, LEGEND_LINE_MM * len(lines)])


def _legend(placer: LabelPlacer, lines, top_left: np.ndarray) -> list[tuple[str, np.ndarray]]:
    samples = []
    x0, y = float(top_left[0]), float(top_left[1])
    for i, (kind, text, size) in enumerate(lines):
        yc = y - (i + 0.5) * LEGEND_LINE_MM
        x_text = x0 + (SAMPLE_MM + 4.0 if kind else 0.0)
        placer.fixed(text, [x_text + text_extent(text, size)[0] / 2, yc], size, "legend", bold=i == 0)
        if kind == "BUTTON":
            samples.append((kind, np.array([[x0 + SAMPLE_MM / 2, yc]])))
        elif kind:
            samples.append((kind, np.array([[x0, yc], [x0 + SAMPLE_MM, yc]])))
    return samples


def _clutch_ends(piece, notes) -> list[tuple[str, np.ndarray, bool | None]]:
    """(text, (2,) mm centre of its anchors, loaded) per clutch end on the piece."""
    out = []
    for n in notes:
        for end in ("start", "end"):
            idx = [i for i, b in enumerate(piece.button_names) if b.startswith(f"{n.name}:{end}")]
            if idx:
                flag = " (no load)" if n.loaded is False else ""
                out.append((f"{n.tag} {n.name} {end}{flag}", piece.buttons[idx].mean(axis=0), n.loaded))
    return out


def label_sheet(sheet, legend_lines, legend_top_left):
    """The Sheet ``sheet`` with its legend drawn at ``legend_top_left`` (2,) mm and every text placed
    clear of the others and of the button circles (see :class:`LabelPlacer`)."""
    from shapely import Polygon

    r = 0.5 * BUTTON_MM + 0.3
    sq = sheet.square
    hard = [np.r_[b - r, b + r] for p in sheet.pieces for b in p.buttons]
    hard.append(np.r_[sq.min(axis=0), sq.max(axis=0)])
    lines = [np.vstack([o, o[:1]]) for p in sheet.pieces for o in list(p.cut_lines) + list(p.allowance and p.outlines)]
    lines += [m.points for p in sheet.pieces for m in p.marks]
    placer = LabelPlacer(hard, lines)
    legend = _legend(placer, legend_lines, np.asarray(legend_top_left, float))
    placer.fixed("100 mm x 100 mm", sq[0] + [SQUARE_MM / 2, -4.0], 4.0, "reference")
    placer.fixed("1:1, mm", sq[0] + [SQUARE_MM / 2, SQUARE_MM / 2], 4.0, "reference")
    regions = {}
    for p in sheet.pieces:
        regions[p.label] = Polygon(p.outlines[0], [o for o in p.outlines[1:] if len(o) > 2]).buffer(0)
        placer.place(p.text, p.text_at - [0.0, 4.0], PIECE_TEXT_MM, "piece", regions[p.label], bold=True)
    for p in sheet.pieces:
        for text, at, _ in _clutch_ends(p, sheet.clutches):
            placer.place(text, at, CLUTCH_TEXT_MM, "clutch", regions[p.label])
    for p in sheet.pieces:
        for m in p.marks:
            if m.text and m.at is not None:
                placer.place(m.text, m.at, MARK_TEXT_MM, m.kind, regions[p.label])
    return dataclasses.replace(sheet, legend=tuple(legend), labels=tuple(placer.labels))


def leader(label: Label) -> np.ndarray | None:
    """(2, 2) mm: a line from the label's box edge to what it names, or None when it sits
    on it."""
    if not label.moved:
        return None
    b = label.box(0.3)
    a = np.asarray(label.anchor, float)
    start = np.clip(a, b[:2], b[2:])
    return np.stack([start, a])
