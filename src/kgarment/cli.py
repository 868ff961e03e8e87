"""The ``kgarment`` command line. User errors print one line and exit with status 2."""

from __future__ import annotations

import argparse
import logging
import sys
import time
from pathlib import Path

from kgarment import __version__
from kgarment.errors import KgarmentError

log = logging.getLogger("kgarment")


def _problem(args):
    from kgarment.problem import Problem, load_problem

    p = load_problem(args.problem) if getattr(args, "problem", None) else Problem()
    import dataclasses

    changes = {}
    if getattr(args, "motion", None):
        changes["motions"] = tuple(args.motion)
    g = p.garment
    if getattr(args, "garment", None):
        g = dataclasses.replace(g, template=args.garment, mask=None)
    if getattr(args, "subdivision", None) is not None:
        g = dataclasses.replace(g, subdivision=args.subdivision)
    changes["garment"] = g
    p = dataclasses.replace(p, **changes)
    # validate overrides the same way a file is validated
    lib = p.library()
    if p.body.model == "anny":
        for n in p.motions:
            lib.get(n)
    from kgarment.garment import template_names

    if g.template and g.template not in template_names():
        from kgarment.errors import unknown

        raise unknown("garment", g.template, template_names())
    return p


def cmd_motions(args) -> int:
    from kgarment.body.motions import PAPER_MOTIONS

    p = _problem(args)
    for name, m in p.library().all().items():
        tag = " (paper)" if name in PAPER_MOTIONS else ""
        print(f"{name:24s} {m.description}{tag}")
    return 0


def cmd_garments(args) -> int:
    from kgarment.garment import builtin_templates
    from kgarment.garment.garment import ALIASES

    for name, t in builtin_templates().items():
        print(f"{name:22s} {t.description}")
    for a, b in ALIASES.items():
        print(f"{a:22s} = {b}")
    return 0


def _render_all(p, out: Path, views) -> list[Path]:
    from kgarment.problem import build_body, build_clutches, build_garment
    from kgarment.render import render_scene

    t0 = time.time()
    body = build_body(p)
    garment = build_garment(p, body)
    strips = build_clutches(p, body, garment)
    log.info("body %d vertices, garment %s: %d faces (%.3f m^2), %.1f s", body.n_vertices,
             garment.name, garment.n_faces, garment.face_areas().sum(), time.time() - t0)
    out.mkdir(parents=True, exist_ok=True)
    paths = []
    for motion in ("rest",) + tuple(p.motions):
        path = out / f"{garment.name}_{motion}.png"
        gv = garment.vertices(motion)
        cl = [(c.bound_positions(gv, garment.faces), c.faces) for c in strips]
        render_scene(path, body.vertices(motion), body.faces, gv, garment.faces,
                     attached=garment.attached, views=views, clutches=cl,
                     title=f"{garment.name} (subdivision {garment.subdivision}) - {motion}")
        paths.append(path)
    return paths


def cmd_render(args) -> int:
    p = _problem(args)
    print(p.describe())
    for path in _render_all(p, Path(args.out), tuple(args.views)):
        print(f"wrote {path}")
    return 0


def cmd_demo(args) -> int:
    """The main job: design the three-motion shirt (resumes or reports an existing run)."""
    import argparse

    from kgarment.cli_design import EXAMPLES, cmd_design

    out = Path(args.out)
    ck = out / "checkpoint.npz"
    if ck.is_file():
        import numpy as np

        with np.load(ck) as z:
            done = bool(z["done"])
        if done and not args.force:
            print(f"{out} already holds a finished design (use --force to redo it); results:")
            for f in [out / "metrics.csv", out / "progress.png"] + sorted((out / "final").glob("*")):
                print(f"  {f}")
            return 0
    problem = EXAMPLES / "shirt_three_motions.toml"
    ns = argparse.Namespace(problem=str(problem), out=str(out), force=args.force,
                            resume=str(out) if ck.is_file() and not args.force else None,
                            subdivision=args.subdivision, garment=None, motion=None,
                            max_iterations=args.max_iterations, device=args.device, quiet=args.quiet)
    if ns.resume:
        print(f"resuming the unfinished run in {out}")
    return cmd_design(ns)


def cmd_clutches(args) -> int:
    from kgarment.clutch import build_clutch, save_clutches
    from kgarment.clutch.suggest import suggest_clutches
    from kgarment.problem import build_body, build_clutches, build_garment
    from kgarment.render import render_scene

    p = _problem(args)
    print(p.describe())
    body = build_body(p)
    garment = build_garment(p, body)
    out = Path(args.out)
    if args.action == "suggest":
        specs = suggest_clutches(garment, count=args.count, length=args.length)
        strips = [build_clutch(s, garment.rest_vertices, garment.faces) for s in specs]
        name = "suggested"
    else:
        strips = build_clutches(p, body, garment)
        specs = strips
        name = "clutches"
    out.mkdir(parents=True, exist_ok=True)
    cfile = out / f"{name}.toml"
    if cfile.exists() and not args.force:
        raise KgarmentError(f"{cfile} exists; use --force to overwrite it")
    save_clutches(cfile, specs, garment.rest_vertices, garment.faces)
    png = render_scene(out / f"{name}.png", body.rest_vertices, body.faces, garment.rest_vertices, garment.faces,
                       garment.attached, clutches=[(c.vertices, c.faces) for c in strips],
                       views=("front", "back", "left", "right"), title=f"{garment.name}: {name}")
    for c in strips:
        a, b = c.vertices[c.centerline[0]], c.vertices[c.centerline[-1]]
        print(f"  {c.name:18s} {100 * c.length:5.1f} cm x {100 * c.width:.1f} cm  from {a.round(3)} to {b.round(3)}")
    print(f"wrote {cfile} (portable: rest coordinates) and {png}")
    return 0


def cmd_simulate(args) -> int:
    import numpy as np

    from kgarment.problem import build_body, build_clutches, build_garment
    from kgarment.render import render_scene
    from kgarment.sim import SimState, SolverOptions, build_model, solve_states
    from kgarment.simulate import load_design, parse_activation, sim_motions, write_ply

    p = _problem(args)
    print(p.describe())
    body = build_body(p)
    garment = build_garment(p, body)
    strips = build_clutches(p, body, garment)
    motions = args.motion or list(p.motions)
    design = load_design(args.design, garment.n_faces) if args.design else np.ones(garment.n_faces)
    g = parse_activation(args.clutches, len(strips))
    out = Path(args.out)
    targets = [out / f"{m}.ply" for m in motions]
    if any(t.exists() for t in targets) and not args.force:
        raise KgarmentError(f"{out} already holds results; use --force to overwrite them")
    model = build_model(garment.rest_vertices, garment.faces, strips, preset=args.preset)
    sm = sim_motions(body, garment, motions)
    states = [SimState.create(sm[m], g, name=f"{m}[{args.clutches}]") for m in motions]
    opts = SolverOptions(method=args.solver, device=args.device)
    results = solve_states(model, design, states, options=opts)
    for m, r in zip(motions, results):
        gx, cx = model.split(r.x)
        write_ply(out / f"{m}.ply", gx, garment.faces, {"energy_density": r.garment_density})
        for c, (strip, x) in enumerate(zip(strips, cx)):
            write_ply(out / f"{m}_clutch_{strip.name}.ply", x, strip.faces, {"energy_density": r.clutch_density[c]})
        png = render_scene(out / f"{m}.png", body.vertices(m), body.faces, gx, garment.faces,
                           face_values=r.garment_density, clutches=[(x, s.faces) for s, x in zip(strips, cx)],
                           clutch_activation=g, value_label="energy density (J/m^2)",
                           title=f"{garment.name} - {m} - clutches {args.clutches}")
        c = r.convergence
        terms = ", ".join(f"{k} {v:.3g}" for k, v in r.energy.items())
        print(f"{m}: {'converged' if c.converged else 'NOT CONVERGED'} in {c.iterations} iterations, "
              f"{c.wall_time:.1f} s; energy {r.total_energy:.4g} J ({terms})")
        print(f"  wrote {out / f'{m}.ply'} and {png}")
    return 0 if all(r.converged for r in results) else 1


def build_parser() -> argparse.ArgumentParser:
    from kgarment.render.raster import STANDARD_VIEWS, VIEWS

    ap = argparse.ArgumentParser(prog="kgarment", description="Design active kinesthetic garments with electrostatic clutches.")
    ap.add_argument("--version", action="version", version=f"kgarment {__version__}")
    ap.add_argument("-v", "--verbose", action="count", default=0, help="more log output (-vv for debug)")
    ap.add_argument("-q", "--quiet", action="store_true", help="only warnings and errors")
    sub = ap.add_subparsers(dest="command", metavar="COMMAND")

    def common(sp, problem=True):
        if problem:
            sp.add_argument("problem", nargs="?", help="problem file (TOML); default: the built-in three-motion shirt")
        sp.add_argument("--device", default="cpu", help="torch device for numerical work (default cpu)")

    sp = sub.add_parser("motions", help="list the motion library (built-in and the problem's own)")
    common(sp)
    sp.set_defaults(func=cmd_motions)

    sp = sub.add_parser("garments", help="list the garment templates")
    sp.set_defaults(func=cmd_garments)

    sp = sub.add_parser("render", help="render body, garment and attachments for each motion to PNG")
    common(sp)
    sp.add_argument("--motion", action="append", help="motion name (repeatable); default: the problem's motions")
    sp.add_argument("--garment", help="garment template name (overrides the problem's)")
    sp.add_argument("--subdivision", type=int, choices=(0, 1, 2, 3), help="garment subdivision level")
    sp.add_argument("--views", nargs="+", default=list(STANDARD_VIEWS), choices=list(VIEWS), help="views to draw")
    sp.add_argument("--out", default="runs/render", help="output folder (default runs/render)")
    sp.set_defaults(func=cmd_render)

    sp = sub.add_parser("clutches", help="show the problem's clutches, or suggest placements over high strain")
    sp.add_argument("action", choices=("show", "suggest"), help="show: build and draw the problem's clutches; "
                    "suggest: propose clutches over the most stretched spots")
    common(sp)
    sp.add_argument("--count", type=int, default=3, help="suggest: number of clutches (default 3)")
    sp.add_argument("--length", type=float, default=0.10, help="suggest: clutch length in metres (default 0.10)")
    sp.add_argument("--out", default="runs/clutches", help="output folder (default runs/clutches)")
    sp.add_argument("--force", action="store_true", help="overwrite an existing clutch file")
    sp.set_defaults(func=cmd_clutches)

    sp = sub.add_parser("simulate", help="equilibrium of the garment (and clutches) on the posed body")
    common(sp)
    sp.add_argument("--motion", action="append", help="motion (repeatable); default: the problem's motions")
    sp.add_argument("--clutches", default="on", help="activation: on, off, or one value in [0, 1] per clutch (1,0,0.5)")
    sp.add_argument("--design", help="per-face design: .npy/.npz/.txt file, a run folder or RUN@ITERATION; default: fully reinforced")
    sp.add_argument("--preset", default="paper", choices=("paper", "reference"), help="material preset")
    sp.add_argument("--solver", default="newton", choices=("newton", "lbfgs"), help="solver (default newton)")
    sp.add_argument("--garment", help="garment template name (overrides the problem's)")
    sp.add_argument("--subdivision", type=int, choices=(0, 1, 2, 3), help="garment subdivision level")
    sp.add_argument("--out", default="runs/simulate", help="output folder (default runs/simulate)")
    sp.add_argument("--force", action="store_true", help="overwrite existing results")
    sp.set_defaults(func=cmd_simulate)

    from kgarment.cli_design import add_parsers
    from kgarment.cli_fabricate import add_parser as add_fabricate

    add_parsers(sub, common)
    add_fabricate(sub, common)
    from kgarment.cli_studio import add_parser as add_studio

    add_studio(sub, common)
    from kgarment.cli_reproduce import add_parser as add_reproduce

    add_reproduce(sub, common)

    sp = sub.add_parser("demo", help="the main job: design the three-motion shirt (examples/shirt_three_motions.toml)")
    common(sp, problem=False)
    sp.add_argument("--out", default="runs/demo", help="run folder (default runs/demo); an unfinished run is resumed")
    sp.add_argument("--subdivision", type=int, default=0, choices=(0, 1, 2, 3),
                    help="garment resolution (default 0; 1 is the default elsewhere, 2 matches the paper)")
    sp.add_argument("--max-iterations", type=int, help="stop after this many iterations")
    sp.add_argument("--force", action="store_true", help="start over, replacing the run folder")
    sp.set_defaults(func=cmd_demo)
    return ap


def main(argv=None) -> int:
    ap = build_parser()
    args = ap.parse_args(argv)
    level = logging.WARNING if args.quiet else (logging.DEBUG if args.verbose > 1 else logging.INFO)
    logging.basicConfig(level=level, format="%(message)s")
    for noisy in ("anny", "warp", "matplotlib", "PIL"):
        logging.getLogger(noisy).setLevel(max(level, logging.WARNING))
    if args.verbose == 0 and getattr(args, "command", None) in ("design", "demo", "reproduce"):
        logging.getLogger("kgarment.sim").setLevel(logging.WARNING)  # the progress bar says enough
    if not getattr(args, "command", None):
        ap.print_help()
        return 2
    try:
        return args.func(args)
    except KgarmentError as exc:
        print(f"kgarment: error: {exc}", file=sys.stderr)
        return 2
    except BrokenPipeError:  # output piped into head and the like
        return 0
    except KeyboardInterrupt:
        print("kgarment: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
