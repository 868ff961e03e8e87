"""Text labels placed on a sheet without overlapping each other or the marks they name.

A label is an axis-aligned text box centred on its position (the writers draw text with
``text-anchor: middle`` and a middle baseline). Its size comes from the glyphs of the
sans-serif font matplotlib ships (DejaVu Sans, wider than most sans-serif faces, so the boxes
are on the safe side when a viewer substitutes another font).

:class:`LabelPlacer` places labels one at a time: each tries spots on rings around its
anchor, nearest first, and takes the first whose box (with a margin) touches no label placed
before and no hard obstacle (button circles); spots that also cross no drawn line (cut
outlines, clutch lines) and, where a region is given, lie inside it are preferred. Every
label gets a spot: the rings grow until one is free.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np

PAD_MM = 0.6  # clear margin around every label box


@lru_cache(maxsize=4096)
def text_extent(text: str, size: float) -> tuple[float, float]:
    """(width, height) in mm of ``text`` set at font size ``size`` mm in the sans-serif font;
    the height is the font's full line (ascender to descender), whatever the letters."""
    from matplotlib.font_manager import FontProperties
    from matplotlib.textpath import TextPath

    if not text:
        return 0.0, 0.0
    ext = TextPath((0, 0), text, size=size, prop=FontProperties(family=["sans-serif"])).get_extents()
    return float(max(ext.x1, 0.0) - min(ext.x0, 0.0)), 1.2 * size


@dataclass(frozen=True)
class Label:
    """One text on the sheet: ``at`` (2,) mm, the centre of its box; ``size`` font size, mm;
    ``kind`` what it names ("piece", "clutch", "arrow", "loop", "seam", "reference",
    "legend", "panel"); ``anchor`` (2,) mm, the point it names (a leader line is drawn from
    the box to it when the label had to move away)."""

    text: str
    at: np.ndarray
    size: float
    kind: str
    anchor: np.ndarray | None = None
    bold: bool = False

    def box(self, pad: float = 0.0) -> np.ndarray:
        """(4,) mm: xmin, ymin, xmax, ymax of the text, grown by ``pad``."""
        w, h = text_extent(self.text, self.size)
        return np.array([self.at[0] - w / 2 - pad, self.at[1] - h / 2 - pad,
                         self.at[0] + w / 2 + pad, self.at[1] + h / 2 + pad])

    @property
    def moved(self) -> bool:
        """Whether the label sits away from what it names (worth a leader line)."""
        if self.anchor is None:
            return False
        b = self.box()
        return not (b[0] <= self.anchor[0] <= b[2] and b[1] <= self.anchor[1] <= b[3]) and \
            float(np.linalg.norm(self.at - self.anchor)) > 2.5 * self.size


def boxes_overlap(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Whether box a (4,) overlaps each of boxes b (k, 4) (xmin, ymin, xmax, ymax)."""
    b = np.asarray(b, float).reshape(-1, 4)
    return (a[0] < b[:, 2]) & (b[:, 0] < a[2]) & (a[1] < b[:, 3]) & (b[:, 1] < a[3])


def _rings(size: float) -> np.ndarray:
    """(k, 2) mm offsets around an anchor, nearest first: the anchor, then 16 directions on
    rings of growing radius."""
    ang = np.radians(np.arange(0, 360, 22.5))
    dirs = np.stack([np.cos(ang), np.sin(ang)], 1)
    radii = size * np.array([0.8, 1.3, 2.0, 3.0, 4.2, 5.6, 7.5, 10.0, 13.0, 17.0, 22.0, 30.0])
    return np.concatenate([np.zeros((1, 2))] + [r * dirs for r in radii])


class LabelPlacer:
    """Places labels one by one, each clear of the ones before it.

    hard : (k, 4) boxes (mm) no label may touch (button circles, the reference square);
    lines : (k, 2) polylines (mm) a label should rather not cross (outlines, clutch lines).
    """

    def __init__(self, hard=(), lines=()):
        from shapely import LineString, STRtree

        self.boxes = [np.asarray(b, float) for b in hard]
        self._n_hard = len(self.boxes)
        geoms = [LineString(np.asarray(p, float)) for p in lines if len(p) > 1]
        self._lines = STRtree(geoms) if geoms else None
        self.labels: list[Label] = []

    def _clear(self, box: np.ndarray) -> bool:
        return not self.boxes or not boxes_overlap(box, np.array(self.boxes)).any()

    def _crosses(self, box: np.ndarray) -> bool:
        if self._lines is None:
            return False
        from shapely import box as sbox

        return len(self._lines.query(sbox(*box), predicate="intersects")) > 0

    def place(self, text: str, anchor, size: float, kind: str, region=None, bold: bool = False,
              avoid_lines: bool = True) -> Label:
        """Place ``text`` near ``anchor`` (2,) mm; ``region`` : a shapely polygon the label
        should stay inside (a piece), or None. Returns the placed label."""
        from shapely import box as sbox

        anchor = np.asarray(anchor, float)
        spots = anchor + _rings(size)
        best = None
        # pass 0: clear, crossing no line, inside the region; 1: clear and crossing no line; 2: clear
        for rank in (0, 1, 2) if avoid_lines else (0, 2):
            for p in spots:
                lab = Label(text, p, size, kind, anchor, bold)
                b = lab.box(PAD_MM)
                if not self._clear(b):
                    continue
                if avoid_lines and rank < 2 and self._crosses(b):
                    continue
                if rank == 0 and region is not None and not region.contains(sbox(*b)):
                    continue
                best = lab
                break
            if best is not None:
                break
        r = 40.0 * size
        while best is None:  # everything near is taken: further out until a spot is free
            for a in np.radians(np.arange(0, 360, 15)):
                lab = Label(text, anchor + r * np.array([np.cos(a), np.sin(a)]), size, kind, anchor, bold)
                if self._clear(lab.box(PAD_MM)):
                    best = lab
                    break
            r *= 1.3
        self.boxes.append(best.box())
        self.labels.append(best)
        return best

    def fixed(self, text: str, at, size: float, kind: str, bold: bool = False) -> Label:
        """A label at exactly ``at`` (legend lines, the reference square's text): kept as is
        and avoided by every later label."""
        lab = Label(text, np.asarray(at, float), size, kind, None, bold)
        self.boxes.append(lab.box())
        self.labels.append(lab)
        return lab
