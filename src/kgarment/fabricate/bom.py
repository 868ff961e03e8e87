"""Bill of materials (Markdown and CSV) and the fabrication report (Markdown and JSON)."""

from __future__ import annotations

import csv
import io
import json
from pathlib import Path

import numpy as np

from kgarment.fabricate.outline import polygon_area

BUTTONS_PER_CLUTCH = 6  # 3 anchors at each end, one snap fastener each


COLUMNS = ("category", "item", "quantity", "area_cm2", "length_mm", "width_mm", "notes")


def _row(*values) -> dict:
    return dict(zip(COLUMNS, values, strict=True))


def bom_rows(fab) -> list[dict]:
    """The bill of materials, one dict per line (areas cm^2, lengths mm; see ``COLUMNS``)."""
    rows = []
    g = fab.garment
    patches = fab.patterns.patches
    for p, piece in zip(patches, fab.sheet.pieces, strict=True):
        w, h = np.ptp(np.concatenate(piece.outlines), axis=0)
        rows.append(_row("reinforced fabric", p.label, 1, round(1e4 * p.flat.area_3d, 2), round(float(h), 1),
                         round(float(w), 1), f"bounding box on the sheet; {p.mesh.n_faces} faces"))
    rows.append(_row("reinforced fabric", "total", len(patches), round(1e4 * sum(p.flat.area_3d for p in patches), 2),
                     round(fab.sheet.height, 1), round(fab.sheet.width, 1), "sheet size with the reference square"))
    ring = round(1e4 * float(g.face_areas()[g.attached].sum()), 1)
    rows.append(_row("base garment", g.name, 1, round(1e4 * float(g.face_areas().sum()), 2), "", "",
                     f"stretch cloth, {g.n_faces} faces; attachment rings {ring} cm2"))
    for c in fab.strips:
        rows.append(_row("clutch", c.name, 1, round(1e4 * c.length * c.width, 2), round(1e3 * c.length, 1),
                         round(1e3 * c.width, 1), f"prestrain {c.prestrain:g}"))
    on = sum(len(p.buttons) for p in fab.sheet.pieces)
    total = BUTTONS_PER_CLUTCH * len(fab.strips)
    rows.append(_row("snap button", "snap fastener pair", total, "", "", "",
                     f"{BUTTONS_PER_CLUTCH} per clutch (3 per end); {on} on reinforcement patches, "
                     f"{total - on} on the base garment"))
    for s in fab.patterns.seams:
        rows.append(_row("seam", s.label, 1, "", round(1e3 * s.length(g.rest_vertices), 1), "",
                         "opens a hole" if s.kind == "hole" else "joins two patches"))
    return rows


def write_bom(fab, out: Path) -> list[Path]:
    """bom.csv and bom.md in ``out``."""
    rows = bom_rows(fab)
    cols = list(COLUMNS)
    buf = io.StringIO()
    w = csv.DictWriter(buf, fieldnames=cols)
    w.writeheader()
    w.writerows(rows)
    (out / "bom.csv").write_text(buf.getvalue())
    md = [f"# Bill of materials: {fab.garment.name}", "",
          "Areas in cm^2 (3D, on the rest body), lengths in mm. Cut files are 1:1 in millimetres.", "",
          "| " + " | ".join(cols) + " |", "|" + "---|" * len(cols)]
    md += ["| " + " | ".join(str(r[c]) for c in cols) + " |" for r in rows]
    (out / "bom.md").write_text("\n".join(md) + "\n")
    return [out / "bom.md", out / "bom.csv"]


def patch_rows(fab) -> list[dict]:
    """Per patch: areas, distortion, outline area after smoothing (all SI and %)."""
    rows = []
    for p, piece in zip(fab.patterns.patches, fab.sheet.pieces, strict=True):
        f = p.flat
        outline = abs(polygon_area(piece.outlines[0])) - sum(abs(polygon_area(o)) for o in piece.outlines[1:])
        rows.append({
            "patch": p.label, "piece": p.piece, "faces": p.mesh.n_faces, "method": f.method,
            "area_3d_m2": f.area_3d, "area_2d_m2": f.area_2d, "outline_area_m2": outline * 1e-6,
            "area_distortion_pct": 100 * f.area_distortion,
            "max_length_distortion_pct": 100 * f.max_length_distortion,
            "median_length_distortion_pct": 100 * float(np.median(np.abs(f.edge_ratio - 1))),
            "flipped": f.flipped, "buttons": len(piece.buttons),
        })
    return rows


def rho_rows(before: list[dict], after: list[dict]) -> list[dict]:
    """rho before and after the clean-up for each motion and state (``StateEvaluation.row()`` dicts)."""
    return [{"motion": b["motion"], "state": b["state"], "rho_before": b["rho"], "rho_after": a["rho"],
             "change_pct": 100 * (a["rho"] / b["rho"] - 1) if b["rho"] else float("nan"),
             "converged": bool(b["converged"] and a["converged"])} for b, a in zip(before, after, strict=True)]


def write_report(fab, out: Path, evaluation=None, files=()) -> list[Path]:
    """report.md and report.json in ``out``; evaluation = (rows before, rows after) or None."""
    c = fab.cleanup
    o = fab.options
    clean = {"holes_filled": c.holes_filled, "islands_removed": c.islands_removed, "faces_opened": c.faces_opened,
             "faces_changed": c.changed_faces, "area_before_m2": c.area_before, "area_after_m2": c.area_after,
             "options": {k: getattr(o.cleanup, k) for k in ("min_island_area", "max_hole_area", "min_width")}}
    patches = patch_rows(fab)
    seams = [{"seam": s.label, "kind": s.kind, "length_m": s.length(fab.garment.rest_vertices),
              "vertices": len(s.garment_vertices)} for s in fab.patterns.seams]
    rho = rho_rows(*evaluation) if evaluation else []
    doc = {"garment": fab.garment.name, "faces": fab.garment.n_faces, "cleanup": clean, "patches": patches,
           "seams": seams, "rho": rho, "max_distortion": o.patterns.max_distortion, "method": o.patterns.method,
           "units": "SI (m, m^2); cut files in mm", "files": [Path(f).name for f in files]}
    (out / "report.json").write_text(json.dumps(doc, indent=1, default=float))
    md = [f"# Fabrication report: {fab.garment.name}", "", "## Clean-up", "",
          (f"- holes filled: {c.holes_filled}; islands removed: {c.islands_removed}; faces removed by the "
           f"{1e3 * o.cleanup.min_width:.0f} mm minimum width: {c.faces_opened}"),
          (f"- reinforced area {1e4 * c.area_before:.1f} -> {1e4 * c.area_after:.1f} cm^2 "
           f"({c.changed_faces} faces changed)"), ""]
    if rho:
        md += ["## Re-simulation (rho, before -> after clean-up)", "",
               "| motion | state | before | after | change |", "|---|---|---|---|---|"]
        md += [f"| {r['motion']} | {r['state']} | {r['rho_before']:.3f} | {r['rho_after']:.3f} | {r['change_pct']:+.1f}%"
               f"{'' if r['converged'] else ' (not converged)'} |" for r in rho]
        md.append("")
    else:
        md += ["Re-simulation skipped (--no-resimulate).", ""]
    md += [f"## Patches (seams cut above {100 * o.patterns.max_distortion:.1f}% length distortion)", "",
           "| patch | faces | area 3D (cm^2) | area 2D (cm^2) | area dist. | max length dist. | median | flipped |",
           "|---|---|---|---|---|---|---|---|"]
    md += [f"| {r['patch']} | {r['faces']} | {1e4 * r['area_3d_m2']:.1f} | {1e4 * r['area_2d_m2']:.1f} | "
           f"{r['area_distortion_pct']:.2f}% | {r['max_length_distortion_pct']:.2f}% | "
           f"{r['median_length_distortion_pct']:.2f}% | {r['flipped']} |" for r in patches]
    if seams:
        md += ["", "## Seams", ""] + [f"- {s['seam']}: {s['kind']}, {1e3 * s['length_m']:.0f} mm" for s in seams]
    md += ["", "## Files", ""] + [f"- {Path(f).name}" for f in files]
    (out / "report.md").write_text("\n".join(md) + "\n")
    return [out / "report.md", out / "report.json"]
