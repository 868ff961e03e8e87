"""``kgarment fabricate RUN|RUN@ITERATION|DESIGN.npz [--problem FILE] [--out DIR]``: cut files.

Cleans the design up, flattens the reinforcement into patches, and writes cut files at 1:1
in millimetres (SVG, DXF, tiled PDF), the 3D design (GLB, OBJ, PLY), a bill of materials
and a report; by default it also re-simulates the design before and after the clean-up
(with the one design evaluator) and reports how rho ON/OFF changed.
"""

from __future__ import annotations

import time
from pathlib import Path

from kgarment.cli.common import add_device, integer, number
from kgarment.errors import KgarmentError


def resolve_source(design: str, problem: str | None):
    """(DesignSource, problem file, label, default output folder) for 'RUN', 'RUN@K' or a
    design file (which needs ``problem``)."""
    from kgarment.design import parse_design_source

    src = parse_design_source(design)
    if src.run is not None:
        it = src.iteration
        label = f"{src.run} iteration {it}" if it is not None else f"{src.run} (final design)"
        out = src.run / (f"fabrication@{it}" if it is not None else "fabrication")
        return src, Path(problem) if problem else src.run / "problem.toml", label, out
    if problem is None:
        raise KgarmentError(f"a design file ({src.file.name}) needs --problem FILE (the problem it was designed for)")
    return src, Path(problem), str(src.file), src.file.parent / f"{src.file.stem}_fabrication"


def cmd_fabricate(args) -> int:
    from kgarment.design import load_design
    from kgarment.evaluate import Evaluator
    from kgarment.fabricate import (
        FabricationOptions,
        check_design_mesh,
        fabricate,
        with_loads,
        write_fabrication,
    )
    from kgarment.fabricate.cleanup import CleanupOptions
    from kgarment.fabricate.patterns import PatternOptions
    from kgarment.io import check_replaceable, replace_folder
    from kgarment.problem import build_body, build_clutches, build_garment, load_problem

    src, pfile, label, default_out = resolve_source(args.design, args.problem)
    options = FabricationOptions(
        cleanup=CleanupOptions(args.min_island_area, args.max_hole_area, args.min_width),
        patterns=PatternOptions(method=args.method, max_distortion=args.max_distortion, max_cuts=args.max_cuts),
        smooth_iterations=0 if args.no_smooth else 10, sheet_width=args.sheet_width, paper=args.paper,
        allowance=args.allowance)
    p = load_problem(pfile)
    out = Path(args.out) if args.out else default_out
    check_replaceable(out, args.force, kind="fabrication")  # fail before the slow part
    t0 = time.time()
    body = build_body(p)
    garment = build_garment(p, body)
    strips = build_clutches(p, body, garment)
    design = load_design(src, garment.n_faces)
    if src.file is not None:
        check_design_mesh(src.file, garment)
    print(f"design: {label}: {100 * (design > 0.5).mean():.1f}% of {garment.n_faces} faces of {garment.name} "
          f"reinforced; {len(strips)} clutches")
    fab = fabricate(garment, strips, design, options, title=f"kgarment {garment.name} - {label}", body=body)
    c = fab.cleanup
    print(f"clean-up: {c.holes_filled} holes filled, {c.faces_opened} faces removed by the minimum width, "
          f"{c.islands_removed} islands removed; reinforced {1e4 * c.area_before:.1f} -> {1e4 * c.area_after:.1f} cm^2")
    evaluation = None
    if not args.no_resimulate:
        print("re-simulating the design before and after the clean-up, and each clutch's load ...")
        ev = Evaluator.from_problem(p, body=body, garment=garment, strips=strips, device=args.device)
        same = c.changed_faces == 0
        ev_before = ev.evaluate(design, loads=same)
        ev_after = ev_before if same else ev.evaluate(fab.clean_design, loads=True)
        before, after = [s.row() for s in ev_before.states], [s.row() for s in ev_after.states]
        evaluation = (before, after)
        fab = with_loads(fab, ev_after.loads)
        for b, a in zip(before, after):
            flag = "" if b["converged"] and a["converged"] else "  (NOT converged)"
            print(f"  rho {b['motion']:22s} {b['state']:5s} {b['rho']:7.3f} -> {a['rho']:7.3f}{flag}")
        if ev_after.loads is not None:
            print("clutch loads of the cleaned design (share of the ON - OFF energy alone ON, "
                  "lost alone OFF / tension; *: loaded):")
            print(ev_after.loads.table())
    for n in fab.sheet.clutches:
        print(f"  {n.tag} {n.name}: {n.status}")
    written: list[Path] = []

    def fill(tmp: Path) -> None:  # written beside the old folder, then swapped in
        written.extend(Path(f).relative_to(tmp) for f in write_fabrication(fab, tmp, evaluation))

    replace_folder(out, fill, "fabrication")
    files = [out / f for f in written]
    print(f"{len(fab.patterns.patches)} patches, {len(fab.patterns.seams)} seams, {time.time() - t0:.1f} s:")
    limit = options.patterns.max_distortion
    for pt in fab.patterns.patches:
        f = pt.flat
        flag = f"  (over {100 * limit:g}%: allow more seams with --max-cuts)" if f.max_length_distortion > limit else ""
        print(f"  {pt.label:4s} {1e4 * f.area_3d:7.1f} cm^2  area distortion {100 * f.area_distortion:5.2f}%  "
              f"max length distortion {100 * f.max_length_distortion:5.2f}%{flag}")
    print(f"wrote {out}/ (cut files in millimetres at 1:1):")
    for f in files:
        print(f"  {f}")
    return 0


def add_parsers(sub) -> None:
    sp = sub.add_parser("fabricate", help="clean a design up and write cut files (SVG, DXF, PDF), 3D files and a BOM")
    sp.add_argument("design", help="run folder (its final design), RUN@ITERATION, or a design file (.npz/.npy/.txt) "
                                   "with --problem")
    sp.add_argument("--problem", help="problem file (TOML); needed for a design file "
                                      "(default for a run: RUN/problem.toml)")
    sp.add_argument("--out", help="output folder (default RUN/fabrication, RUN/fabrication@K, or DESIGN_fabrication)")
    sp.add_argument("--force", action="store_true", help="replace an existing output folder")
    sp.add_argument("--no-resimulate", action="store_true", help="skip re-simulating rho before/after the clean-up")
    add_device(sp)
    g = sp.add_argument_group("clean-up (SI units; 0 switches a step off)")
    g.add_argument("--min-island-area", type=number(0.0, 1.0), default=4e-4, metavar="M2",
                   help="remove islands of reinforcement smaller than this, m^2 (default 4e-4 = 4 cm^2)")
    g.add_argument("--max-hole-area", type=number(0.0, 1.0), default=4e-4, metavar="M2",
                   help="fill enclosed soft holes smaller than this, m^2 (default 4e-4)")
    g.add_argument("--min-width", type=number(0.0, 0.5), default=0.01, metavar="M",
                   help="minimum feature width, m (default 0.01)")
    g = sp.add_argument_group("patterns")
    g.add_argument("--method", default="arap", choices=("arap", "lscm"), help="flattening (default arap)")
    g.add_argument("--max-distortion", type=number(0.0, 1.0, low_open=True), default=0.05,
                   help="cut a seam where an edge's length changes by more than this fraction (default 0.05)")
    g.add_argument("--max-cuts", type=integer(0, 64), default=4, help="at most this many seams per piece (default 4)")
    g.add_argument("--no-smooth", action="store_true", help="keep the raw triangle-edge outlines")
    g.add_argument("--sheet-width", type=number(50.0, 10000.0), default=600.0, help="cutting sheet width, mm (default 600)")
    g.add_argument("--allowance", type=number(0.0, 100.0), default=0.0, metavar="MM",
                   help="seam allowance around every piece and panel, mm (default 0: heat-pressed film needs "
                        "none; sewn fabric about 10)")
    g.add_argument("--paper", default="a4", choices=("a4", "letter"), help="PDF page size (default a4)")
    sp.set_defaults(func=cmd_fabricate)
