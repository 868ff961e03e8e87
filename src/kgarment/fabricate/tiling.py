"""The cutting sheet cut into printable pages: a full grid of tiles with overlaps.

Tiles overlap their neighbours by :data:`OVERLAP_MM`. Every tile of the grid is printed and
named row by row (A1, A2, ... then B1, ...), so names run without gaps and the pages form a
rectangle; a tile with nothing on it says so and may be skipped. The grid's origin (and,
when that helps, one more row or column) is chosen so that no tile holds only a sliver of
a piece: content cut by a tile edge and less than :data:`SLIVER_MM` deep into the tile.
Registration marks sit in the middle of the overlap bands, at every corner and edge middle
of each tile, so the same mark prints on every tile that shares it.
"""

from __future__ import annotations

import itertools
import string
from dataclasses import dataclass

import numpy as np

from kgarment.errors import KgarmentError

PAPERS = {"a4": (210.0, 297.0), "letter": (215.9, 279.4)}
MARGIN_MM = 10.0
FOOTER_MM = 12.0
OVERLAP_MM = 10.0
SLIVER_MM = 40.0
SHIFTS = 9  # grid origins tried along each axis


@dataclass(frozen=True)
class Tile:
    """One page's window on the sheet: lower-left corner (x, y) and size (w, h) in mm, its
    name, row and column (0-based, row 0 at the top) and whether anything is on it."""

    x: float
    y: float
    w: float
    h: float
    name: str
    row: int = 0
    col: int = 0
    empty: bool = False


@dataclass(frozen=True)
class Tiling:
    """The page grid: page size (pw, ph) mm, nx columns, ny rows, tiles row by row."""

    pw: float
    ph: float
    nx: int
    ny: int
    tiles: tuple[Tile, ...]

    def neighbour(self, t: Tile, dr: int, dc: int) -> Tile | None:
        r, c = t.row + dr, t.col + dc
        return self.tiles[r * self.nx + c] if 0 <= r < self.ny and 0 <= c < self.nx else None

    def registration_marks(self) -> np.ndarray:
        """(k, 2) mm: the centres of the overlap bands at the corners and edge middles of
        every tile (each shared by every tile it falls on)."""
        t0, step_x, step_y = self.tiles[0], self.tiles[0].w - OVERLAP_MM, self.tiles[0].h - OVERLAP_MM
        top = t0.y + t0.h
        xs = [t0.x + i * step_x + OVERLAP_MM / 2 for i in range(self.nx + 1)]
        xs += [t0.x + i * step_x + t0.w / 2 for i in range(self.nx)]
        ys = [top - j * step_y - OVERLAP_MM / 2 for j in range(self.ny + 1)]
        ys += [top - j * step_y - t0.h / 2 for j in range(self.ny)]
        pts = np.array(list(itertools.product(xs, ys)))
        # keep the points on a tile's corner or edge middle (not a tile's centre)
        on_edge = np.isin(np.round(pts[:, 0], 6), np.round(xs[: self.nx + 1], 6)) | \
            np.isin(np.round(pts[:, 1], 6), np.round(ys[: self.ny + 1], 6))
        return pts[on_edge]


def tile_name(row: int, col: int) -> str:
    letters = string.ascii_uppercase
    r = letters[row] if row < 26 else letters[row // 26 - 1] + letters[row % 26]
    return f"{r}{col + 1}"


def content(sheet):
    """The sheet's content as one shapely geometry (mm): the pieces' cut lines, the
    reference square and the legend's and labels' boxes."""
    from shapely import Polygon, box, unary_union

    parts = [Polygon(sheet.square[:-1])]
    for p in sheet.pieces:
        cut = p.cut_lines
        parts.append(Polygon(cut[0], [c for c in cut[1:] if len(c) > 2]).buffer(0))
    parts += [box(*lab.box()) for lab in sheet.labels]
    return unary_union(parts).simplify(0.5)


def _classify(shape, t: Tile) -> tuple[bool, bool]:
    """(empty, sliver) of a tile over the content ``shape``."""
    from shapely import clip_by_rect

    part = clip_by_rect(shape, t.x, t.y, t.x + t.w, t.y + t.h)
    if part.is_empty or part.area < 1.0:
        return True, False
    x0, y0, x1, y1 = part.bounds
    eps = 1e-6
    thin_x = x1 - x0 < SLIVER_MM and (x0 <= t.x + eps or x1 >= t.x + t.w - eps)
    thin_y = y1 - y0 < SLIVER_MM and (y0 <= t.y + eps or y1 >= t.y + t.h - eps)
    return False, bool(thin_x or thin_y)


def _tiles(x0: float, top: float, nx: int, ny: int, w: float, h: float) -> list[Tile]:
    return [Tile(x0 + c * (w - OVERLAP_MM), top - h - r * (h - OVERLAP_MM), w, h, tile_name(r, c), r, c)
            for r in range(ny) for c in range(nx)]


def _best_grid(sheet, shape, pw: float, ph: float):
    """(score, Tiling) of the best grid on pw x ph mm pages: fewest sliver tiles, then fewest
    pages, then fewest empty pages, then the thickest thinnest content."""
    w, h = pw - 2 * MARGIN_MM, ph - 2 * MARGIN_MM - FOOTER_MM
    nx0 = max(1, int(np.ceil((sheet.width - OVERLAP_MM) / (w - OVERLAP_MM))))
    ny0 = max(1, int(np.ceil((sheet.height - OVERLAP_MM) / (h - OVERLAP_MM))))
    best = None
    for nx, ny in ((nx0, ny0), (nx0 + 1, ny0), (nx0, ny0 + 1), (nx0 + 1, ny0 + 1)):
        spare_x = nx * (w - OVERLAP_MM) + OVERLAP_MM - sheet.width
        spare_y = ny * (h - OVERLAP_MM) + OVERLAP_MM - sheet.height
        for fx, fy in itertools.product(np.linspace(0, 1, SHIFTS), repeat=2):
            x0, top = -fx * spare_x, sheet.height + fy * spare_y
            ts = _tiles(x0, top, nx, ny, w, h)
            kinds = [_classify(shape, t) for t in ts]
            slivers = sum(s for _, s in kinds)
            empty = sum(e for e, _ in kinds)
            # tie-break: content as far from the grid's outer edges as possible (centred)
            score = (slivers, nx * ny, empty, abs(fx - 0.5) + abs(fy - 0.5))
            if best is None or score < best[0]:
                ts = [Tile(t.x, t.y, t.w, t.h, t.name, t.row, t.col, e) for t, (e, _) in zip(ts, kinds)]
                best = (score, Tiling(pw, ph, nx, ny, tuple(ts)))
    return best


def tiling(sheet, paper: str = "a4") -> Tiling:
    """The page grid for ``sheet`` on ``paper`` (portrait or landscape, whichever is better by
    the same score)."""
    if paper not in PAPERS:
        raise KgarmentError(f"paper {paper!r}; allowed: {', '.join(PAPERS)}")
    pw, ph = PAPERS[paper]
    shape = content(sheet)
    return min((_best_grid(sheet, shape, *s) for s in ((pw, ph), (ph, pw))), key=lambda b: b[0])[1]


def slivers(sheet, grid: Tiling) -> list[str]:
    """Names of the tiles that hold only a sliver of content (none, when it can be helped)."""
    shape = content(sheet)
    return [t.name for t in grid.tiles if _classify(shape, t)[1]]
