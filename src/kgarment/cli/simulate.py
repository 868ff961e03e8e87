"""``kgarment simulate``: equilibria of a design under one clutch activation."""

from __future__ import annotations

from kgarment.cli.common import add_device, add_overrides, add_problem, load, parse_activation
from kgarment.errors import KgarmentError


def cmd_simulate(args) -> int:
    import numpy as np

    from kgarment.design import load_design
    from kgarment.design.report import write_equilibrium
    from kgarment.evaluate import Evaluator
    from kgarment.io import check_kind, make_folder
    from kgarment.problem import build_body, build_clutches, build_garment
    from kgarment.sim import clutch_tensions
    from kgarment.sim.slip import slides

    p = load(args)
    if not args.quiet:
        print(p.describe())
    motions = list(args.motion or p.motions)
    # a folder kgarment did not make is written into only when empty (or holding results of
    # a simulation made before folders were marked: its motions' .ply files)
    out = check_kind(args.out, "simulation", legacy=tuple(f"{m}.ply" for m in motions))
    if any((out / f"{m}.ply").exists() for m in motions) and not args.force:
        raise KgarmentError(f"{out} already holds results; use --force to overwrite them")
    body = build_body(p)
    garment = build_garment(p, body)
    strips = build_clutches(p, body, garment)
    design = load_design(args.design, garment.n_faces) if args.design else np.ones(garment.n_faces)
    ev = Evaluator.from_problem(p, body=body, garment=garment, strips=strips, device=args.device)
    g = parse_activation(args.clutches, ev.case.n_clutches)
    keyed = ev.activation_states(g, motions, label=args.clutches)
    results = ev.equilibria(design, keyed)
    print(f"solver: {ev.case.solver.method}, tolerance {ev.case.solver.tol:g}, materials {p.materials.preset}, "
          f"clutches {p.clutch_spec().hardware.model}")
    hold = ev.case.model.holding(g)
    make_folder(out, "simulation")  # only now, after the solves: a failed simulation leaves no folder
    for ((m, _), state), r in zip(keyed, results):
        w = ev.case.wearers.get(m)  # a multi-body problem's: this wearer's body and garment
        on, pose, model = (body, m, ev.case.model) if w is None else (w.body, w.motion, w.model)
        files = write_equilibrium(out, m, on.vertices(pose), on.faces, model, r, g,
                                  f"{garment.name} - {m} - clutches {args.clutches}")
        c = r.convergence
        terms = ", ".join(f"{k} {v:.3g}" for k, v in r.energy.items())
        print(f"{m}: {'converged' if c.converged else 'NOT CONVERGED'} in {c.iterations} iterations, "
              f"{c.wall_time:.1f} s; energy {r.total_energy:.4g} J ({terms})")
        if ev.case.n_clutches:
            tension = clutch_tensions(model, design, state, r.x)
            print("  clutch tension: " + ", ".join(
                f"{c.name} {t:.1f} N" + (f" (holds {h:.0f} N{', slips' if slides(t, h) else ''})"
                                         if np.isfinite(h) else "")
                for c, t, h in zip(ev.case.model.clutches, tension, hold)))
        print(f"  wrote {files[0]} and {files[-1]}")
    return 0 if all(r.converged for r in results) else 1


def add_parsers(sub) -> None:
    sp = sub.add_parser("simulate", help="equilibrium of the garment (and clutches) on the posed body")
    add_problem(sp)
    add_device(sp)
    add_overrides(sp, materials=True, solver=True, clutch=True)
    sp.add_argument("--clutches", default="on", help="activation: on, off, or one value in [0, 1] per clutch (1,0,0.5)")
    sp.add_argument("--design", help="per-face design: .npy/.npz/.txt file, a run folder or RUN@ITERATION; "
                                     "default: fully reinforced")
    sp.add_argument("--out", default="runs/simulate", help="output folder (default runs/simulate)")
    sp.add_argument("--force", action="store_true", help="overwrite existing results")
    sp.set_defaults(func=cmd_simulate)
