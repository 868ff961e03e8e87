"""Bill of materials (Markdown and CSV) and the fabrication report (Markdown and JSON)."""

from __future__ import annotations

import csv
import dataclasses
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
    a = fab.options.allowance
    for p, piece in zip(patches, fab.sheet.pieces, strict=True):
        w, h = np.ptp(np.concatenate(piece.cut_lines), axis=0)
        extra = f"; cut {_cut_area(piece) / 100:.1f} cm2 with the {a:g} mm allowance" if piece.allowance else ""
        rows.append(_row("reinforced fabric", p.label, 1, round(1e4 * p.flat.area_3d, 2), round(float(h), 1),
                         round(float(w), 1), f"bounding box on the sheet; {p.mesh.n_faces} faces{extra}"))
    rows.append(_row("reinforced fabric", "total", len(patches), round(1e4 * sum(p.flat.area_3d for p in patches), 2),
                     round(fab.sheet.height, 1), round(fab.sheet.width, 1), "sheet size with the reference square "
                     "and the legend"))
    ring = round(1e4 * float(g.face_areas()[g.attached].sum()), 1)
    rows.append(_row("base garment", g.name, 1, round(1e4 * float(g.face_areas().sum()), 2), "", "",
                     f"stretch cloth, {g.n_faces} faces; attachment rings {ring} cm2"))
    for pn in fab.panels:
        w, h = _panel_size(pn)
        rows.append(_row("base garment panel", pn.name, 1, round(1e4 * pn.patch.flat.area_3d, 2), round(h, 1),
                         round(w, 1), f"flat bounding box (placement.svg); length distortion up to "
                                      f"{100 * pn.patch.flat.max_length_distortion:.0f}%, taken up by the stretch"))
    for c, n in zip(fab.strips, fab.sheet.clutches, strict=True):
        rows.append(_row("clutch", f"{n.tag} {c.name}", 1, round(1e4 * c.length * c.width, 2),
                         round(1e3 * c.length, 1), round(1e3 * c.width, 1),
                         f"prestrain {c.prestrain:g}; start on {n.ends[0]}, end on {n.ends[1]}; {n.status}"))
    on = sum(len(p.buttons) for p in fab.sheet.pieces)
    total = BUTTONS_PER_CLUTCH * len(fab.strips)
    rows.append(_row("snap button", "snap fastener pair", total, "", "", "",
                     f"{BUTTONS_PER_CLUTCH} per clutch (3 per end); {on} on reinforcement patches, "
                     f"{total - on} on the base garment"))
    for s in fab.patterns.seams:
        rows.append(_row("seam", s.label, 1, "", round(1e3 * s.length(g.rest_vertices), 1), "",
                         "opens a hole" if s.kind == "hole" else "joins two patches"))
    return rows


def _cut_area(piece) -> float:
    """mm^2 inside the piece's cut line (outer minus holes)."""
    cut = piece.cut_lines
    return abs(polygon_area(cut[0])) - sum(abs(polygon_area(o)) for o in cut[1:])


def _panel_size(panel) -> tuple[float, float]:
    """(width, height) mm of a panel turned up, as on the placement sheet."""
    from kgarment.fabricate.layout import MM, up_direction, up_rotation

    m, uv = panel.patch.mesh, panel.patch.flat.uv
    pts = (MM * uv) @ up_rotation(up_direction(m.vertices, m.faces, uv)).T
    w, h = np.ptp(pts, axis=0)
    return float(w), float(h)


def how_to(fab) -> list[str]:
    """The steps from the files to the garment, with this design's numbers (Markdown lines)."""
    g, pieces, notes = fab.garment, fab.sheet.pieces, fab.sheet.clutches
    a = fab.options.allowance
    film = 1e4 * sum(p.flat.area_3d for p in fab.patterns.patches)
    cloth = 1e4 * float(g.face_areas().sum())
    names = ", ".join(p.name for p in fab.panels) or g.name
    unloaded = [f"{n.tag} {n.name}" for n in notes if n.loaded is False]
    lines = ["## How to make it", "",
             (f"1. Base garment ({cloth:.0f} cm^2 of stretch fabric): cut the panels {names} from "
             f"`placement.svg` (1:1; {'a ' + format(a, 'g') + ' mm' if a else 'no'} seam allowance included; "
             f"for sewing, rerun with `--allowance 10`) and sew them together; hem the openings."),
             (f"2. Reinforcement ({film:.0f} cm^2, {len(pieces)} pieces on a {fab.sheet.width:.0f} x "
             f"{fab.sheet.height:.0f} mm sheet): cut {', '.join(p.label for p in pieces)} from `cut_patterns.svg`/"
             f"`.dxf` (laser or plotter) or the tiled `cut_patterns.pdf` (print at actual size, check the 100 mm "
             f"square; assemble the tiles with page 1's map)."),
             ("3. Place each piece where `placement.svg` and `placement_3d.png` show it, UP arrow towards the "
             "head, notches on the hem and cuffs; pieces cut apart by a seam (S1, ...) meet at notches with the "
             "same name. Heat-press film (no allowance) or sew fabric (with allowance)."),
             (f"4. Clutches ({len(notes)}): mount each along its centre line; its ends' three snap buttons go at "
             f"the circles labelled C1 start / C1 end, ... on the pieces (or on the base garment where the "
             f"legend says so).")]
    lines += [f"   - {n.tag} {n.name}: {n.length_mm:.0f} x {n.width_mm:.0f} mm; start on {n.ends[0]}, end on "
              f"{n.ends[1]}; {n.status}" for n in notes]
    lines.append(f"5. Snap buttons: {BUTTONS_PER_CLUTCH * len(notes)} fastener pairs ({BUTTONS_PER_CLUTCH} per "
                 f"clutch); press the garment halves at the circles, the clutch halves at the clutch ends.")
    if unloaded:
        lines.append(f"\nCarrying no load in the design's evaluation: {', '.join(unloaded)}. The design works "
                     f"without them; mount them only to follow the problem as given.")
    return lines + [""]


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
    md += [""] + how_to(fab)
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
    loads = fab.loads.to_json() if fab.loads is not None else None
    doc = {"clutch_loads": loads, "clutches": [dataclasses.asdict(n) for n in fab.sheet.clutches],
           "seam_allowance_mm": fab.options.allowance,
           "panels": [{"panel": pn.name, "area_3d_m2": pn.patch.flat.area_3d,
                       "max_length_distortion_pct": 100 * pn.patch.flat.max_length_distortion} for pn in fab.panels],
           "garment": fab.garment.name, "faces": fab.garment.n_faces, "cleanup": clean, "patches": patches,
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
    md += ["", "## Clutches", ""] + [f"- {n.tag} {n.name}: {n.status}" for n in fab.sheet.clutches]
    if fab.loads is not None:
        md += ["", "```", fab.loads.table(), "```"]
    if seams:
        md += ["", "## Seams", ""] + [f"- {s['seam']}: {s['kind']}, {1e3 * s['length_m']:.0f} mm" for s in seams]
    md += ["", "## Files", ""] + [f"- {Path(f).name}" for f in files]
    (out / "report.md").write_text("\n".join(md) + "\n")
    return [out / "report.md", out / "report.json"]
