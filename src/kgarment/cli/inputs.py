"""``kgarment motions | garments | examples | render | clutches``: the inputs of a design."""

from __future__ import annotations

from pathlib import Path

from kgarment.cli.common import add_device, add_overrides, add_problem, integer, load, number
from kgarment.errors import KgarmentError


def cmd_motions(args) -> int:
    from kgarment.body.motions import PAPER_MOTIONS

    p = load(args)
    lib = p.library()
    if lib.user and p.body.model == "anny":  # the problem's own motions: every bone and axis on Anny's rig
        from kgarment.body.anny_backend import anny_rig
        from kgarment.body.motions import bone_rotations

        rig = anny_rig(p.body.phenotype)
        for name, m in lib.user.items():
            try:
                bone_rotations(m.target, *rig)
            except KgarmentError as exc:
                raise KgarmentError(f"[motions.define.{name}]: {exc}") from None
    for name, m in lib.all().items():
        tag = " (paper)" if name in PAPER_MOTIONS else ""
        print(f"{name:24s} {m.description}{tag}")
    return 0


def cmd_garments(args) -> int:
    from kgarment.garment import ALIASES, builtin_templates

    for name, t in builtin_templates().items():
        print(f"{name:22s} {t.description}")
    for a, b in ALIASES.items():
        print(f"{a:22s} = {b}")
    return 0


def cmd_examples(args) -> int:
    from kgarment.problem import example_files, example_title, examples_dir

    for f in example_files():
        print(f"{f!s:60s} {example_title(f)}")
    sweeps = sorted((examples_dir() / "sweeps").glob("*.toml"))
    if sweeps:
        print("sweep files (kgarment sweep FILE):")
        for f in sweeps:
            print(f"{f!s:60s} {example_title(f)}")
    return 0


def cmd_render(args) -> int:
    import logging
    import time

    from kgarment.io import check_output_file, check_output_folder
    from kgarment.problem import build_body, build_clutches, build_garment
    from kgarment.render import render_poses

    p = load(args)
    check_output_folder(args.out)
    if not args.quiet:
        print(p.describe())
    t0 = time.time()
    body = build_body(p)
    garment = build_garment(p, body)
    for pose in ("rest", *p.motions):  # render_poses' files: the user's pictures are not overwritten
        check_output_file(Path(args.out) / f"{garment.name}_{pose}.png", "--out", force=args.force)
    strips = build_clutches(p, body, garment)
    logging.getLogger("kgarment").info("body %d vertices, garment %s: %d faces (%.3f m^2), %.1f s", body.n_vertices,
                                       garment.name, garment.n_faces, garment.face_areas().sum(), time.time() - t0)
    for path in render_poses(Path(args.out), body, garment, strips, p.motions, tuple(args.views)):
        print(f"wrote {path}")
    return 0


def cmd_clutches(args) -> int:
    from kgarment.clutch import build_clutch, save_clutches
    from kgarment.clutch.suggest import suggest_clutches
    from kgarment.io import check_output_file, check_output_folder
    from kgarment.problem import build_body, build_clutches, build_garment
    from kgarment.render import render_scene

    if args.action != "suggest" and (args.count is not None or args.length is not None):
        raise KgarmentError("--count and --length are for clutches suggest; clutches show draws the problem's own")
    p = load(args)
    out = check_output_folder(args.out)
    name = "suggested" if args.action == "suggest" else "clutches"
    cfile = check_output_file(out / f"{name}.toml", "--out", force=args.force)  # never a run's own clutch file
    check_output_file(out / f"{name}.png", "--out", force=args.force)  # nor its picture
    if not args.quiet:
        print(p.describe())
    body = build_body(p)
    garment = build_garment(p, body)
    if args.action == "suggest":
        given = {k: v for k, v in (("count", args.count), ("length", args.length)) if v is not None}
        specs = suggest_clutches(garment, motions=p.motions, **given)  # else its defaults (3, 0.10 m)
        strips = [build_clutch(s, garment.rest_vertices, garment.faces) for s in specs]
    else:
        strips = build_clutches(p, body, garment)
        specs = strips
        # the names the problem gives its clutches elsewhere, checked as a design checks them
        from kgarment.case.setup import activation_vectors
        from kgarment.problem.build import holding_forces

        activation_vectors(p, [s.name for s in strips])
        holding_forces(p.clutch_spec().hardware, strips)
    out.mkdir(parents=True, exist_ok=True)
    save_clutches(cfile, specs, garment.rest_vertices, garment.faces)
    png = render_scene(out / f"{name}.png", body.rest_vertices, body.faces, garment.rest_vertices, garment.faces,
                       garment.attached, clutches=[(c.vertices, c.faces) for c in strips],
                       views=("front", "back", "left", "right"), title=f"{garment.name}: {name}")
    for c in strips:
        a, b = c.vertices[c.centerline[0]], c.vertices[c.centerline[-1]]
        print(f"  {c.name:18s} {100 * c.length:5.1f} cm x {100 * c.width:.1f} cm  from {a.round(3)} to {b.round(3)}")
    print(f"wrote {cfile} (portable: rest coordinates) and {png}")
    if args.action == "suggest" and not args.no_check and strips:
        from kgarment.case import case_from_problem
        from kgarment.constants import UNCONTROLLABLE
        from kgarment.evaluate.control import clutch_control, control_table

        print("can each clutch be felt? the fully reinforced garment's energy change with only that clutch ON "
              f"(* at least {100 * UNCONTROLLABLE:g}%; the paper's shirt motions: 1-3% with all three ON):")
        case = case_from_problem(p, body, garment, strips, device=args.device, objective="active")
        for line in control_table(clutch_control(case, [c.name for c in strips])):
            print("  " + line)
    return 0


def add_parsers(sub) -> None:
    from kgarment.render.raster import STANDARD_VIEWS, VIEWS

    sp = sub.add_parser("motions", help="list the motion library (built-in and the problem's own)")
    add_problem(sp)
    add_device(sp)
    sp.set_defaults(func=cmd_motions)

    sp = sub.add_parser("garments", help="list the garment templates")
    sp.set_defaults(func=cmd_garments)

    sp = sub.add_parser("examples", help="list the example problem files (one per experiment of the paper) and "
                        "sweep files")
    sp.set_defaults(func=cmd_examples)

    sp = sub.add_parser("render", help="render body, garment and attachments for each motion to PNG")
    add_problem(sp)
    add_device(sp)
    add_overrides(sp)
    sp.add_argument("--views", nargs="+", default=list(STANDARD_VIEWS), choices=list(VIEWS), help="views to draw")
    sp.add_argument("--out", default="runs/render", help="output folder (default runs/render)")
    sp.add_argument("--force", action="store_true", help="overwrite pictures already in --out")
    sp.set_defaults(func=cmd_render)

    sp = sub.add_parser("clutches", help="show the problem's clutches, or suggest placements over high strain")
    sp.add_argument("action", choices=("show", "suggest"), help="show: build and draw the problem's clutches; "
                    "suggest: propose clutches over the most stretched spots")
    add_problem(sp)
    add_device(sp)
    add_overrides(sp)
    sp.add_argument("--count", type=integer(1, 64), help="suggest: number of clutches (default 3)")
    sp.add_argument("--length", type=number(0.01, 1.0), help="suggest: clutch length in metres (default 0.10)")
    sp.add_argument("--out", default="runs/clutches", help="output folder (default runs/clutches)")
    sp.add_argument("--force", action="store_true", help="overwrite an existing clutch file")
    sp.add_argument("--no-check", action="store_true", help="suggest: skip simulating whether each suggested "
                    "clutch can be felt in each motion")
    sp.set_defaults(func=cmd_clutches)
