"""Cut files at 1:1 scale in millimetres: SVG and DXF (ezdxf).

Both files hold the same geometry. Layers (DXF) / classes (SVG), with the usual laser
colours: ``CUT`` (red, the patch outlines: cut through), ``MARK`` (blue: snap buttons,
arrows, clutch lines, notches: engrave or draw), ``TEXT`` (black), ``REFERENCE`` (green,
the 100 mm square: measure it after printing or cutting).

SVG: ``width``/``height`` in mm and a viewBox of the same numbers, so one user unit is one
millimetre; y grows downwards (y_svg = sheet height - y). Every outline is a ``<polygon>``
with ``id="<patch>-outline-<k>"``, every button a ``<circle class="button">`` with the
clutch anchor in ``data-anchor``. DXF: ``$INSUNITS`` = 4 (millimetres), y up; every patch's
entities are in a DXF group named after the patch.
"""

from __future__ import annotations

from pathlib import Path
from xml.sax.saxutils import escape

import numpy as np

from kgarment.fabricate.layout import BUTTON_MM, Sheet

UNITS_NOTE = "units: millimetres, scale 1:1 (the reference square measures 100 mm)"
COLORS = {"CUT": "#ff0000", "MARK": "#0000ff", "TEXT": "#000000", "REFERENCE": "#00a000"}
ACI = {"CUT": 1, "MARK": 5, "TEXT": 7, "REFERENCE": 3}
TEXT_MM = 5.0


def _pts(a: np.ndarray, h: float) -> str:
    return " ".join(f"{x:.3f},{h - y:.3f}" for x, y in a)


def write_svg(sheet: Sheet, path) -> Path:
    """Write the sheet as SVG (millimetres, 1:1). Returns the path."""
    W, H = sheet.width, sheet.height
    out = ['<?xml version="1.0" encoding="UTF-8"?>',
           (f'<svg xmlns="http://www.w3.org/2000/svg" width="{W:.3f}mm" height="{H:.3f}mm" '
           f'viewBox="0 0 {W:.3f} {H:.3f}" data-units="mm">'),
           f"<title>{escape(sheet.title or 'kgarment cut patterns')}</title>",
           f"<desc>{escape(UNITS_NOTE)}; red: cut, blue: marks, green: reference</desc>",
           "<style>.cut{{fill:none;stroke:{};stroke-width:0.1}}.mark{{fill:none;stroke:{};stroke-width:0.3}}"
           ".button{{fill:none;stroke:{};stroke-width:0.3}}.reference{{fill:none;stroke:{};stroke-width:0.3}}"
           "text{{font-family:sans-serif;fill:#000}}</style>".format(COLORS["CUT"], COLORS["MARK"], COLORS["MARK"],
                                                               COLORS["REFERENCE"])]

    def text(at, s, size=TEXT_MM, cls="label"):
        out.append(f'<text class="{cls}" x="{at[0]:.3f}" y="{H - at[1]:.3f}" font-size="{size:.2f}" '
                   f'text-anchor="middle" dominant-baseline="middle">{escape(s)}</text>')

    sq = sheet.square
    out.append(f'<polygon id="reference-square" class="reference" points="{_pts(sq[:-1], H)}"/>')
    text(sq[0] + [50.0, -5.0], "100 mm x 100 mm", 4.0, "reference")
    text(sq[0] + [50.0, 50.0], "1:1, mm", 4.0, "reference")
    for p in sheet.pieces:
        out.append(f'<g id="{p.label}">')
        for k, o in enumerate(p.outlines):
            out.append(f'<polygon id="{p.label}-outline-{k}" class="cut" points="{_pts(o, H)}"/>')
        for b, n in zip(p.buttons, p.button_names):
            r = 0.5 * BUTTON_MM
            out.append(f'<circle class="button" cx="{b[0]:.3f}" cy="{H - b[1]:.3f}" r="{r:.3f}" '
                       f'data-anchor="{escape(n)}"/>')
            out.append(f'<polyline class="mark" points="{_pts(np.array([b - [r, 0], b + [r, 0]]), H)}"/>')
            out.append(f'<polyline class="mark" points="{_pts(np.array([b - [0, r], b + [0, r]]), H)}"/>')
        for m in p.marks:
            tag = "polygon" if m.closed else "polyline"
            out.append(f'<{tag} class="mark {m.kind}" points="{_pts(m.points, H)}"/>')
            if m.text and m.at is not None:
                text(m.at, m.text, 3.0, m.kind)
        text(p.text_at - [0.0, 4.0], p.text)
        out.append("</g>")
    out.append("</svg>")
    path = Path(path)
    path.write_text("\n".join(out) + "\n")
    return path


def write_dxf(sheet: Sheet, path) -> Path:
    """Write the sheet as DXF (R2010, millimetres, 1:1). Returns the path."""
    import ezdxf
    from ezdxf import units
    from ezdxf.enums import TextEntityAlignment

    doc = ezdxf.new("R2010")
    doc.units = units.MM
    doc.header["$INSUNITS"] = 4
    doc.header["$MEASUREMENT"] = 1
    for name, color in ACI.items():
        doc.layers.add(name, color=color)
    msp = doc.modelspace()

    def text(at, s, size=TEXT_MM):
        t = msp.add_text(s, height=size, dxfattribs={"layer": "TEXT"})
        t.set_placement((float(at[0]), float(at[1])), align=TextEntityAlignment.MIDDLE_CENTER)
        return t

    sq = sheet.square
    msp.add_lwpolyline(sq[:-1].tolist(), close=True, dxfattribs={"layer": "REFERENCE"})
    text(sq[0] + [50.0, -5.0], "100 mm x 100 mm", 4.0)
    text(sq[0] + [50.0, 50.0], "1:1, mm", 4.0)
    text([sheet.width / 2, sheet.height + 8.0], f"{sheet.title} - {UNITS_NOTE}", 4.0)
    for p in sheet.pieces:
        ents = []
        for o in p.outlines:
            ents.append(msp.add_lwpolyline(o.tolist(), close=True, dxfattribs={"layer": "CUT"}))
        r = 0.5 * BUTTON_MM
        for b in p.buttons:
            ents.append(msp.add_circle((float(b[0]), float(b[1])), r, dxfattribs={"layer": "MARK"}))
            ents.append(msp.add_line(tuple(b - [r, 0]), tuple(b + [r, 0]), dxfattribs={"layer": "MARK"}))
            ents.append(msp.add_line(tuple(b - [0, r]), tuple(b + [0, r]), dxfattribs={"layer": "MARK"}))
        for m in p.marks:
            ents.append(msp.add_lwpolyline(m.points.tolist(), close=m.closed, dxfattribs={"layer": "MARK"}))
            if m.text and m.at is not None:
                ents.append(text(m.at, m.text, 3.0))
        ents.append(text(p.text_at - [0.0, 4.0], p.text))
        doc.groups.new(p.label).extend(ents)
    path = Path(path)
    doc.saveas(path)
    return path
