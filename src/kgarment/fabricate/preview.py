"""A printable PDF of the cutting sheet at true scale, tiled over A4 or Letter pages.

Page 1 is the assembly map (not to scale): the whole sheet with the grid of tiles, their
names, the empty ones, and how to put the pages together. Every following page is one tile
at 1:1 (see :mod:`kgarment.fabricate.tiling`): registration marks in the overlap bands,
dashed lines where the neighbouring tiles' edges fall (named), the tile's name and place
in the grid, and a 50 mm scale bar. Print at "actual size" (no fit-to-page) and measure
the sheet's 100 mm reference square or the scale bar.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from kgarment.fabricate.annotate import leader
from kgarment.fabricate.cutfiles import COLORS, WIDTH_MM
from kgarment.fabricate.layout import BUTTON_MM, Sheet
from kgarment.fabricate.tiling import FOOTER_MM, MARGIN_MM, OVERLAP_MM, PAPERS, Tile, Tiling, tiling

__all__ = ["INCH", "PAPERS", "Tile", "draw_sheet", "page_size", "tile_figure", "tiles", "write_pdf", "write_png"]

INCH = 25.4
PT = 72.0 / INCH  # points per millimetre
REG_MM = 3.0  # radius of a registration mark's circle


def page_size(sheet: Sheet, paper: str = "a4") -> tuple[float, float]:
    """(width, height) mm of the page, portrait or landscape, whichever tiles better."""
    g = tiling(sheet, paper)
    return g.pw, g.ph


def tiles(sheet: Sheet, paper: str = "a4") -> list[Tile]:
    """Every tile of the grid (1:1), top row first, left to right."""
    return list(tiling(sheet, paper).tiles)


def draw_sheet(ax, sheet: Sheet, scale: float = 1.0) -> None:
    """Draw the sheet on matplotlib axes whose data units are sheet millimetres; ``scale`` is
    millimetres of paper per sheet millimetre (1 on the tiles), for line widths and text."""
    from matplotlib.patches import Circle

    lw = lambda layer: max(WIDTH_MM[layer] * scale * PT, 0.15)
    sq = sheet.square
    ax.plot(sq[:, 0], sq[:, 1], color=COLORS["REFERENCE"], lw=lw("REFERENCE"))

    def button(b):
        r = 0.5 * BUTTON_MM
        ax.add_patch(Circle((float(b[0]), float(b[1])), r, fill=False, color=COLORS["MARK"], lw=lw("MARK")))
        ax.plot([b[0] - r, b[0] + r], [b[1], b[1]], color=COLORS["MARK"], lw=lw("MARK"))
        ax.plot([b[0], b[0]], [b[1] - r, b[1] + r], color=COLORS["MARK"], lw=lw("MARK"))

    for kind, pts in sheet.legend:
        if kind == "BUTTON":
            button(pts[0])
        else:
            ax.plot(pts[:, 0], pts[:, 1], color=COLORS[kind], lw=lw(kind), ls="--" if kind == "SEW" else "-")
    for p in sheet.pieces:
        for o in p.cut_lines:
            c = np.vstack([o, o[:1]])
            ax.plot(c[:, 0], c[:, 1], color=COLORS["CUT"], lw=lw("CUT"))
        for o in p.outlines if p.allowance else ():
            c = np.vstack([o, o[:1]])
            ax.plot(c[:, 0], c[:, 1], color=COLORS["SEW"], lw=lw("SEW"), ls="--")
        for m in p.marks:
            pts = np.vstack([m.points, m.points[:1]]) if m.closed else m.points
            ax.plot(pts[:, 0], pts[:, 1], color=COLORS["MARK"], lw=lw("MARK"), ls="--" if m.kind == "clutch" else "-")
        for b in p.buttons:
            button(b)
    for lab in sheet.labels:
        line = leader(lab)
        if line is not None:
            ax.plot(line[:, 0], line[:, 1], color=COLORS["MARK"], lw=0.5 * lw("MARK"))
        ax.text(lab.at[0], lab.at[1], lab.text, ha="center", va="center", fontsize=lab.size * scale * PT,
                weight="bold" if lab.bold else "normal", clip_on=True)


def overview_figure(sheet: Sheet, grid: Tiling, paper: str):
    """The first page: the assembly map, the whole sheet fitted to the page (not to scale)."""
    import matplotlib.pyplot as plt
    from matplotlib.patches import Rectangle

    pw, ph = grid.pw, grid.ph
    fig = plt.figure(figsize=(pw / INCH, ph / INCH))
    ax = fig.add_axes((0.06, 0.2, 0.88, 0.7))
    ts = grid.tiles
    x0, x1 = min(t.x for t in ts) - 5, max(t.x + t.w for t in ts) + 5
    y0, y1 = min(t.y for t in ts) - 5, max(t.y + t.h for t in ts) + 5
    scale = min(0.88 * pw / (x1 - x0), 0.7 * ph / (y1 - y0))
    draw_sheet(ax, sheet, scale)
    for t in ts:
        ax.add_patch(Rectangle((t.x, t.y), t.w, t.h, fill=t.empty, color="0.85" if t.empty else "0.4",
                               ls="-" if t.empty else ":", lw=0.6, zorder=0 if t.empty else 3))
        ax.text(t.x + t.w / 2, t.y + t.h / 2, t.name + ("\n(empty)" if t.empty else ""), color="0.3",
                ha="center", va="center", fontsize=16 if not t.empty else 10, alpha=0.7, zorder=4)
    ax.set_aspect("equal")
    ax.set_xlim(x0, x1)
    ax.set_ylim(y0, y1)
    ax.axis("off")
    empty = [t.name for t in ts if t.empty]
    fig.suptitle(f"{sheet.title}\nassembly map, NOT to scale: {len(ts)} tiles ({grid.ny} rows A-"
                 f"{ts[-1].name[:-len(str(grid.nx))]} x {grid.nx} columns) follow at 1:1 on {paper.upper()}",
                 fontsize=9)
    steps = [f"1. Print pages 2-{len(ts) + 1} at actual size (no fit-to-page); check the 50 mm scale bar.",
             (f"2. Lay the tiles out as above: row A at the top, column 1 at the left. Neighbouring tiles "
             f"overlap by {OVERLAP_MM:.0f} mm."),
             "3. Trim each tile's left and top margins along its grey frame; lay it on its left and upper neighbours",
             "   with its edge on their dashed line, the registration marks (circle and cross) on theirs; tape.",
             "4. Red: cut; blue: marks; green: the 100 mm square. The legend lists every clutch (C1, ...)."]
    if empty:
        which = f"Tiles {', '.join(empty)} hold" if len(empty) > 1 else f"Tile {empty[0]} holds"
        steps.append(f"{which} nothing: printed to keep the grid whole, it may be skipped.")
    for i, s in enumerate(steps):
        fig.text(0.06, 0.15 - 0.022 * i, s, fontsize=7)
    return fig


def _tile_marks(ax, grid: Tiling, t: Tile) -> None:
    """Registration marks, and dashed lines with the neighbour's name where its edge falls."""
    from matplotlib.patches import Circle

    for x, y in grid.registration_marks():
        if t.x <= x <= t.x + t.w and t.y <= y <= t.y + t.h:
            ax.add_patch(Circle((x, y), REG_MM, fill=False, color="k", lw=0.4))
            ax.plot([x - 4.5, x + 4.5], [y, y], color="k", lw=0.4)
            ax.plot([x, x], [y - 4.5, y + 4.5], color="k", lw=0.4)
    o = OVERLAP_MM
    sides = {(0, -1): ("x", t.x + o), (0, 1): ("x", t.x + t.w - o), (-1, 0): ("y", t.y + t.h - o),
             (1, 0): ("y", t.y + o)}
    for (dr, dc), (axis, v) in sides.items():
        nb = grid.neighbour(t, dr, dc)
        if nb is None:
            continue
        kw = {"color": "0.4", "lw": 0.4, "ls": (0, (4, 2))}
        if axis == "x":
            ax.plot([v, v], [t.y, t.y + t.h], **kw)
            ax.text(v + (-o / 2 if dc < 0 else o / 2), t.y + 0.25 * t.h, nb.name, rotation=90, fontsize=6,
                    color="0.3", ha="center", va="center")
        else:
            ax.plot([t.x, t.x + t.w], [v, v], **kw)
            ax.text(t.x + 0.25 * t.w, v + (o / 2 if dr < 0 else -o / 2), nb.name, fontsize=6, color="0.3",
                    ha="center", va="center")


def tile_figure(sheet: Sheet, t: Tile, pw: float, ph: float, index: int, count: int, grid: Tiling | None = None):
    """(figure, axes) of one tile on a pw x ph mm page; 1 data unit is 1 mm of paper."""
    import matplotlib.pyplot as plt

    fig = plt.figure(figsize=(pw / INCH, ph / INCH))
    ax = fig.add_axes((MARGIN_MM / pw, (MARGIN_MM + FOOTER_MM) / ph, t.w / pw, t.h / ph))
    draw_sheet(ax, sheet)
    if grid is not None:
        _tile_marks(ax, grid, t)
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
    where = f"row {t.row + 1}, column {t.col + 1}" + (" - nothing to cut here" if t.empty else "")
    foot.text(t.w, 2, f"tile {t.name} ({where}; page {index + 2} of {count + 1}), 1:1 - print at actual size; "
                      f"overlap {OVERLAP_MM:.0f} mm", ha="right", va="center", fontsize=6)
    foot.text(t.w, 6.5, t.name, ha="right", va="center", fontsize=12, weight="bold")
    return fig, ax


def write_pdf(sheet: Sheet, path, paper: str = "a4") -> Path:
    """Write the assembly map and every 1:1 tile to a PDF. Returns the path."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.backends.backend_pdf import PdfPages

    grid = tiling(sheet, paper)
    ts = grid.tiles
    path = Path(path)
    with PdfPages(path) as pdf:
        fig = overview_figure(sheet, grid, paper)
        pdf.savefig(fig)
        plt.close(fig)
        for i, t in enumerate(ts):
            fig = tile_figure(sheet, t, grid.pw, grid.ph, i, len(ts), grid)[0]
            pdf.savefig(fig)
            plt.close(fig)
    return path


def write_png(sheet: Sheet, path, px: int = 1000) -> Path:
    """A preview of the whole sheet (not to scale), ``px`` pixels on its longer side."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    scale = px / 100 * INCH / max(sheet.width, sheet.height)  # paper mm per sheet mm at 100 dpi
    fig = plt.figure(figsize=(sheet.width * scale / INCH, sheet.height * scale / INCH))
    ax = fig.add_axes((0, 0, 1, 1))
    draw_sheet(ax, sheet, scale)
    ax.set_xlim(0, sheet.width)
    ax.set_ylim(0, sheet.height)
    ax.axis("off")
    path = Path(path)
    fig.savefig(path, dpi=100, facecolor="white")
    plt.close(fig)
    return path
