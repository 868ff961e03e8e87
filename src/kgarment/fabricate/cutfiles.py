"""Cut files at 1:1 scale in millimetres: SVG and DXF (ezdxf).

Both files hold the same geometry. Layers (DXF) / classes (SVG), with the usual laser
colours: ``CUT`` (red, the cut line: the piece outline, or the seam allowance around it),
``SEW`` (red dashed, only with a seam allowance: the piece outline, where it is sewn),
``MARK`` (blue: snap buttons, arrows, clutch lines, notches, leader lines: engrave or draw),
``TEXT`` (black), ``REFERENCE`` (green, the 100 mm square: measure it after printing or
cutting). A legend on the sheet says the same.

SVG: ``width``/``height`` in mm and a viewBox of the same numbers, so one user unit is one
millimetre; y grows downwards (y_svg = sheet height - y). Lines are drawn wide enough to see
on screen (cut 0.5 mm); the DXF keeps hairlines (lineweight 0) for the cutter. Every cut line
is a ``<polygon>`` with ``id="<patch>-outline-<k>"`` (the sew line, with an allowance,
``<patch>-sew-<k>``), every button a ``<circle class="button">`` with the clutch anchor in
``data-anchor``, every text a ``<text>`` with its kind in ``class`` and its font size in mm.
DXF: ``$INSUNITS`` = 4 (millimetres), y up; every patch's entities are in a DXF group named
after the patch.
"""

from __future__ import annotations

from pathlib import Path
from xml.sax.saxutils import escape

import numpy as np

from kgarment.fabricate.annotate import leader
from kgarment.fabricate.layout import BUTTON_MM, Sheet

UNITS_NOTE = "units: millimetres, scale 1:1 (the reference square measures 100 mm)"
COLORS = {"CUT": "#ff0000", "SEW": "#ff0000", "MARK": "#0000ff", "TEXT": "#000000", "REFERENCE": "#00a000"}
ACI = {"CUT": 1, "SEW": 1, "MARK": 5, "TEXT": 7, "REFERENCE": 3}
WIDTH_MM = {"CUT": 0.5, "SEW": 0.35, "MARK": 0.3, "REFERENCE": 0.4}  # on screen (SVG); the DXF has hairlines
TEXT_MM = 5.0


def _pts(a: np.ndarray, h: float) -> str:
    return " ".join(f"{x:.3f},{h - y:.3f}" for x, y in a)


def _style() -> str:
    c, w = COLORS, WIDTH_MM
    return ("<style>"
            f".cut{{fill:none;stroke:{c['CUT']};stroke-width:{w['CUT']}}}"
            f".sew{{fill:none;stroke:{c['SEW']};stroke-width:{w['SEW']};stroke-dasharray:3 1.5}}"
            f".mark{{fill:none;stroke:{c['MARK']};stroke-width:{w['MARK']}}}"
            f".clutch{{stroke-dasharray:4 2}}.leader{{stroke-width:0.2}}"
            f".button{{fill:none;stroke:{c['MARK']};stroke-width:{w['MARK']}}}"
            f".reference{{fill:none;stroke:{c['REFERENCE']};stroke-width:{w['REFERENCE']}}}"
            "text{font-family:sans-serif;fill:#000;stroke:none}text.bold{font-weight:bold}</style>")


def write_svg(sheet: Sheet, path) -> Path:
    """Write the sheet as SVG (millimetres, 1:1). Returns the path."""
    W, H = sheet.width, sheet.height
    out = ['<?xml version="1.0" encoding="UTF-8"?>',
           (f'<svg xmlns="http://www.w3.org/2000/svg" width="{W:.3f}mm" height="{H:.3f}mm" '
            f'viewBox="0 0 {W:.3f} {H:.3f}" data-units="mm">'),
           f"<title>{escape(sheet.title or 'kgarment cut patterns')}</title>",
           f"<desc>{escape(UNITS_NOTE)}; red: cut, red dashed: sew, blue: marks, green: reference</desc>", _style()]
    r = 0.5 * BUTTON_MM

    def button(b, name=""):
        anchor = f' data-anchor="{escape(name)}"' if name else ""
        out.append(f'<circle class="button" cx="{b[0]:.3f}" cy="{H - b[1]:.3f}" r="{r:.3f}"{anchor}/>')
        out.append(f'<polyline class="mark" points="{_pts(np.array([b - [r, 0], b + [r, 0]]), H)}"/>')
        out.append(f'<polyline class="mark" points="{_pts(np.array([b - [0, r], b + [0, r]]), H)}"/>')

    sq = sheet.square
    out.append(f'<polygon id="reference-square" class="reference" points="{_pts(sq[:-1], H)}"/>')
    out.append('<g id="legend">')
    for kind, pts in sheet.legend:
        if kind == "BUTTON":
            out.append('<g class="legend-button">')
            button(pts[0])
            out.append("</g>")
        else:
            out.append(f'<polyline class="{kind.lower()}" points="{_pts(pts, H)}"/>')
    out.append("</g>")
    for p in sheet.pieces:
        out.append(f'<g id="{p.label}">')
        for k, o in enumerate(p.cut_lines):
            out.append(f'<polygon id="{p.label}-outline-{k}" class="cut" points="{_pts(o, H)}"/>')
        if p.allowance:
            for k, o in enumerate(p.outlines):
                out.append(f'<polygon id="{p.label}-sew-{k}" class="sew" points="{_pts(o, H)}"/>')
        for b, n in zip(p.buttons, p.button_names):
            button(b, n)
        for m in p.marks:
            tag = "polygon" if m.closed else "polyline"
            out.append(f'<{tag} class="mark {m.kind}" points="{_pts(m.points, H)}"/>')
        out.append("</g>")
    out.append('<g id="labels">')
    for lab in sheet.labels:
        line = leader(lab)
        if line is not None:
            out.append(f'<polyline class="mark leader" points="{_pts(line, H)}"/>')
        cls = f"{lab.kind} bold" if lab.bold else lab.kind
        out.append(f'<text class="{cls}" x="{lab.at[0]:.3f}" y="{H - lab.at[1]:.3f}" font-size="{lab.size:.2f}" '
                   f'text-anchor="middle" dominant-baseline="middle">{escape(lab.text)}</text>')
    out.append("</g>")
    out.append("</svg>")
    path = Path(path)
    path.write_text("\n".join(out) + "\n")
    return path


def write_dxf(sheet: Sheet, path) -> Path:
    """Write the sheet as DXF (R2010, millimetres, 1:1, hairlines). Returns the path."""
    import ezdxf
    from ezdxf import units
    from ezdxf.enums import TextEntityAlignment

    doc = ezdxf.new("R2010", setup=["linetypes"])
    doc.units = units.MM
    doc.header["$INSUNITS"] = 4
    doc.header["$MEASUREMENT"] = 1
    for name, color in ACI.items():
        layer = doc.layers.add(name, color=color)
        layer.dxf.lineweight = 0  # hairline: the cutter follows the line's centre
        if name == "SEW":
            layer.dxf.linetype = "DASHED"
    msp = doc.modelspace()
    r = 0.5 * BUTTON_MM

    def text(at, s, size=TEXT_MM):
        t = msp.add_text(s, height=size, dxfattribs={"layer": "TEXT"})
        t.set_placement((float(at[0]), float(at[1])), align=TextEntityAlignment.MIDDLE_CENTER)
        return t

    def button(b):
        return [msp.add_circle((float(b[0]), float(b[1])), r, dxfattribs={"layer": "MARK"}),
                msp.add_line(tuple(b - [r, 0]), tuple(b + [r, 0]), dxfattribs={"layer": "MARK"}),
                msp.add_line(tuple(b - [0, r]), tuple(b + [0, r]), dxfattribs={"layer": "MARK"})]

    sq = sheet.square
    msp.add_lwpolyline(sq[:-1].tolist(), close=True, dxfattribs={"layer": "REFERENCE"})
    text([sheet.width / 2, sheet.height + 8.0], f"{sheet.title} - {UNITS_NOTE}", 4.0)
    for kind, pts in sheet.legend:
        if kind == "BUTTON":
            button(pts[0])
        else:  # a LINE: every LWPOLYLINE on a layer is part of a piece or the square
            msp.add_line(tuple(pts[0]), tuple(pts[-1]), dxfattribs={"layer": kind})
    for lab in sheet.labels:
        text(lab.at, lab.text, lab.size)
        line = leader(lab)
        if line is not None:
            msp.add_lwpolyline(line.tolist(), dxfattribs={"layer": "MARK"})
    for p in sheet.pieces:
        ents = []
        for o in p.cut_lines:
            ents.append(msp.add_lwpolyline(o.tolist(), close=True, dxfattribs={"layer": "CUT"}))
        if p.allowance:
            for o in p.outlines:
                ents.append(msp.add_lwpolyline(o.tolist(), close=True, dxfattribs={"layer": "SEW"}))
        for b in p.buttons:
            ents += button(b)
        for m in p.marks:
            ents.append(msp.add_lwpolyline(m.points.tolist(), close=m.closed, dxfattribs={"layer": "MARK"}))
        doc.groups.new(p.label).extend(ents)
    path = Path(path)
    doc.saveas(path)
    return path
