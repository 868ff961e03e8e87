"""A printable PDF of the cutting sheet at true scale, tiled over A4 or Letter pages.

Page 1 is an overview (not to scale) that numbers the tiles; every following page is one
tile at 1:1 with a 10 mm overlap to its neighbours, crop marks, its tile name and a 50 mm
scale bar. The sheet's 100 mm reference square is on the first tile: print at "actual
size" (no fit-to-page) and measure it.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from kgarment.errors import KgarmentError
from kgarment.fabricate.cutfiles import COLORS
from kgarment.fabricate.layout import BUTTON_MM, Sheet

PAPERS = {"a4": (210.0, 297.0), "letter": (215.9, 279.4)}
MARGIN_MM = 10.0
FOOTER_MM = 12.0
OVERLAP_MM = 10.0
INCH = 25.4


@dataclass(frozen=True)
class Tile:
    """One page's window on the sheet: lower-left corner (x, y) and size (w, h) in mm, name."""

    x: float
    y: float
    w: float
    h: float
    name: str


def _grid(sheet: Sheet, pw: float, ph: float) -> list[Tile]:
    w, h = pw - 2 * MARGIN_MM, ph - 2 * MARGIN_MM - FOOTER_MM
    nx = max(1, int(np.ceil((sheet.width - OVERLAP_MM) / (w - OVERLAP_MM))))
    ny = max(1, int(np.ceil((sheet.height - OVERLAP_MM) / (h - OVERLAP_MM))))
    out = []
    for r in range(ny):
        for c in range(nx):
            t = Tile(c * (w - OVERLAP_MM), sheet.height - h - r * (h - OVERLAP_MM), w, h, f"{chr(65 + r % 26)}{c + 1}")
            if _occupied(sheet, t):
                out.append(t)
    return out


def _occupied(sheet: Sheet, t: Tile) -> bool:
    """Whether anything of the sheet lies in the tile."""
    pts = [sheet.square] + [o for p in sheet.pieces for o in p.outlines]
    for q in pts:
        lo, hi = q.min(axis=0), q.max(axis=0)
        if lo[0] < t.x + t.w and hi[0] > t.x and lo[1] < t.y + t.h and hi[1] > t.y:
            return True
    return False


def page_size(sheet: Sheet, paper: str = "a4") -> tuple[float, float]:
    """(width, height) mm of the page, portrait or landscape, whichever needs fewer pages."""
    if paper not in PAPERS:
        raise KgarmentError(f"paper {paper!r}; allowed: {', '.join(PAPERS)}")
    pw, ph = PAPERS[paper]
    return min([(pw, ph), (ph, pw)], key=lambda s: len(_grid(sheet, *s)))


def tiles(sheet: Sheet, paper: str = "a4") -> list[Tile]:
    """The page tiles (1:1) with something on them, top row first, left to right."""
    return _grid(sheet, *page_size(sheet, paper))


def _draw(ax, sheet: Sheet, lw: float = 0.6) -> None:
    sq = sheet.square
    ax.plot(sq[:, 0], sq[:, 1], color=COLORS["REFERENCE"], lw=lw)
    ax.text(sq[0, 0] + 50, sq[0, 1] - 5, "100 mm x 100 mm", ha="center", va="center", fontsize=7, clip_on=True)
    for p in sheet.pieces:
        for o in p.outlines:
            c = np.vstack([o, o[:1]])
            ax.plot(c[:, 0], c[:, 1], color=COLORS["CUT"], lw=lw)
        for m in p.marks:
            pts = np.vstack([m.points, m.points[:1]]) if m.closed else m.points
            ax.plot(pts[:, 0], pts[:, 1], color=COLORS["MARK"], lw=0.5 * lw,
                    ls="--" if m.kind == "clutch" else "-")
            if m.text and m.at is not None:
                ax.text(m.at[0], m.at[1], m.text, ha="center", va="center", fontsize=5, color=COLORS["MARK"],
                        clip_on=True)
        for b in p.buttons:
            ax.add_patch(_circle(b, 0.5 * BUTTON_MM, lw))
        ax.text(p.text_at[0], p.text_at[1] - 4, p.text, ha="center", va="center", fontsize=9, weight="bold",
                clip_on=True)


def _circle(c, r, lw):
    from matplotlib.patches import Circle

    return Circle((float(c[0]), float(c[1])), r, fill=False, color=COLORS["MARK"], lw=0.5 * lw)


def overview_figure(sheet: Sheet, ts: list[Tile], pw: float, ph: float, paper: str):
    """The first page: the whole sheet fitted to the page (not to scale) with the tiles."""
    import matplotlib.pyplot as plt
    from matplotlib.patches import Rectangle

    fig = plt.figure(figsize=(pw / INCH, ph / INCH))
    ax = fig.add_axes((0.08, 0.12, 0.84, 0.78))
    _draw(ax, sheet, 0.4)
    for t in ts:
        ax.add_patch(Rectangle((t.x, t.y), t.w, t.h, fill=False, ls=":", color="grey", lw=0.5))
        ax.text(t.x + t.w / 2, t.y + t.h / 2, t.name, color="grey", ha="center", va="center", fontsize=14)
    ax.set_aspect("equal")
    ax.set_xlim(-5, max(sheet.width, max(t.x + t.w for t in ts)) + 5)
    ax.set_ylim(min(0, min(t.y for t in ts)) - 5, sheet.height + 5)
    ax.set_xlabel("mm")
    fig.suptitle(f"{sheet.title}\noverview, NOT to scale: {len(ts)} tile page(s) follow at 1:1 on {paper.upper()}",
                 fontsize=9)
    return fig


def tile_figure(sheet: Sheet, t: Tile, pw: float, ph: float, index: int, count: int):
    """(figure, axes) of one tile on a pw x ph mm page; 1 data unit is 1 mm of paper."""
    import matplotlib.pyplot as plt

    fig = plt.figure(figsize=(pw / INCH, ph / INCH))
    ax = fig.add_axes((MARGIN_MM / pw, (MARGIN_MM + FOOTER_MM) / ph, t.w / pw, t.h / ph))
    _draw(ax, sheet)
    ax.set_xlim(t.x, t.x + t.w)
    ax.set_ylim(t.y, t.y + t.h)
    ax.set_xticks([])
    ax.set_yticks([])
    for s in ax.spines.values():
        s.set_color("lightgrey")
        s.set_linewidth(0.3)
    foot = fig.add_axes((MARGIN_MM / pw, MARGIN_MM / ph, t.w / pw, (FOOTER_MM - 2) / ph))
    foot.set_xlim(0, t.w)
    foot.set_ylim(0, FOOTER_MM - 2)
    foot.axis("off")
    foot.plot([0, 50], [2, 2], color="k", lw=1)
    for x in range(0, 51, 10):
        foot.plot([x, x], [2, 3.5 if x % 50 else 4.5], color="k", lw=0.6)
    foot.text(52, 2, "50 mm", va="center", fontsize=6)
    foot.text(t.w, 2, f"tile {t.name} ({index + 1}/{count}), 1:1 - print at actual size; overlap {OVERLAP_MM:.0f} mm",
              ha="right", va="center", fontsize=6)
    return fig, ax


def write_pdf(sheet: Sheet, path, paper: str = "a4") -> Path:
    """Write the overview and the 1:1 tiles to a PDF. Returns the path."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.backends.backend_pdf import PdfPages

    pw, ph = page_size(sheet, paper)
    ts = tiles(sheet, paper)
    path = Path(path)
    with PdfPages(path) as pdf:
        figs = [overview_figure(sheet, ts, pw, ph, paper)] + [tile_figure(sheet, t, pw, ph, i, len(ts))[0]
                                                               for i, t in enumerate(ts)]
        for fig in figs:
            pdf.savefig(fig)
            plt.close(fig)
    return path
