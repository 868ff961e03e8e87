"""``kgarment design``, ``evaluate`` and ``examples``: the design loop on the command line."""

from __future__ import annotations

import dataclasses
import logging
import math
import time
from pathlib import Path

import numpy as np

from kgarment.errors import KgarmentError

log = logging.getLogger("kgarment")
EXAMPLES = Path(__file__).resolve().parents[2] / "examples"


def _expected_iterations(p) -> int:
    return math.ceil(math.log(p.target_area) / math.log(1 - p.er)) + 2 * p.window


def _progress_line(row: dict, motions) -> str:
    rho = "  ".join(f"{m} {row.get(f'rho[{m}:on]', row.get(f'rho[{m}:none]', float('nan'))):.2f}"
                    + (f"/{row[f'rho[{m}:off]']:.2f}" if f"rho[{m}:off]" in row else "") for m in motions)
    return f"area {100 * row['area']:5.1f}%  objective {row['objective']:8.4f}  rho {rho}"


def cmd_design(args) -> int:
    from rich.progress import BarColumn, Progress, TextColumn, TimeElapsedColumn, TimeRemainingColumn

    from kgarment.cli import _problem
    from kgarment.design.driver import finish, open_run

    if args.resume:
        dr = open_run(None, args.resume, resume=True, device=args.device)
    else:
        p = _problem(args)
        if args.max_iterations:
            p = dataclasses.replace(p, design=dataclasses.replace(p.design, max_iterations=args.max_iterations))
        dr = open_run(p, args.out, force=args.force, device=args.device)
    print(dr.problem.describe())
    setup, st, run = dr.setup, dr.state, dr.run
    print(f"garment {dr.garment.name}: {dr.garment.n_faces} faces, {len(dr.strips)} clutches, "
          f"{len(setup.states())} states per iteration ({setup.solver.workers} worker processes); run folder {run}")
    motions = list(setup.motions)
    total = _expected_iterations(setup.params)
    t0 = time.time()
    with Progress(TextColumn("[bold]it {task.completed:>3}"), BarColumn(), TextColumn("{task.description}"),
                  TimeElapsedColumn(), TextColumn("ETA"), TimeRemainingColumn(), disable=args.quiet) as bar:
        task = bar.add_task("starting", total=total, completed=st.iteration)

        def progress(row):
            bar.update(task, completed=row["iteration"] + 1, description=_progress_line(row, motions),
                       total=max(total, row["iteration"] + 2))
            if row["unconverged_states"]:
                log.warning("iteration %d: states not converged: %s", row["iteration"], row["unconverged_states"])

        try:
            finish(dr, progress=progress)
        except KeyboardInterrupt:
            print(f"\ninterrupted after iteration {st.iteration - 1}; continue with: kgarment design --resume {run}")
            return 130
    last = st.metrics[-1]
    print(f"\n{len(st.metrics)} iterations in {time.time() - t0:.0f} s; final {_progress_line(last, motions)}")
    print(f"islands {last['islands']} ({last['islands_with_clutches']} counting clutches as links); "
          f"clutch ends on reinforcement {last['clutch_ends_supported']}/{last['clutch_ends']}")
    print(f"results in {run}/: metrics.csv, metrics.json, progress.png, designs.npz, final/")
    for path in dr.paths:
        print(f"  {path}")
    return 0


def cmd_examples(args) -> int:
    files = sorted(EXAMPLES.glob("*.toml"))
    if not files:
        raise KgarmentError(f"no example problems found in {EXAMPLES}")
    for f in files:
        first = f.read_text().splitlines()[0].lstrip("# ")
        print(f"{str(f):60s} {first}")
    return 0


def add_parsers(sub, common) -> None:
    sp = sub.add_parser("design", help="automatic design (BESO) of the reinforcement; checkpoints every iteration")
    common(sp)
    sp.add_argument("--out", default="runs/design", help="run folder (default runs/design)")
    sp.add_argument("--resume", metavar="RUN", help="continue a run folder where it stopped")
    sp.add_argument("--force", action="store_true", help="replace an existing run folder")
    sp.add_argument("--subdivision", type=int, choices=(0, 1, 2, 3), help="garment subdivision level (resolution)")
    sp.add_argument("--garment", help="garment template name (overrides the problem's)")
    sp.add_argument("--motion", action="append", help="motion (repeatable); default: the problem's motions")
    sp.add_argument("--max-iterations", type=int, help="stop after this many iterations")
    sp.set_defaults(func=cmd_design)

    add_evaluate_parser(sub, common)

    sp = sub.add_parser("examples", help="list the example problem files (one per experiment of the paper)")
    sp.set_defaults(func=cmd_examples)


def _design_source(text: str):
    """'RUN' (final design), 'RUN@K' (iteration K) -> (run folder, iteration or None)."""
    run, _, it = text.partition("@")
    run = Path(run)
    if not (run / "problem.toml").is_file():
        raise KgarmentError(f"{run} is not a run folder (no problem.toml); give RUN or RUN@ITERATION")
    if it and not it.isdigit():
        raise KgarmentError(f"iteration {it!r} in {text!r} must be a number")
    return run, (int(it) if it else None)


def evaluate_design(problem, design: np.ndarray, device: str = "cpu") -> list[dict]:
    """rho ON/OFF (or the objective's states) of ``design`` (m,) on the problem's motions:
    one row per motion and state with the energies of the design and of the full garment."""
    from kgarment.design.metrics import Stored, relative_energy_density
    from kgarment.problem import build_body, build_clutches, build_garment
    from kgarment.sim import solve_states

    body = build_body(problem)
    garment = build_garment(problem, body)
    if len(design) != garment.n_faces:
        raise KgarmentError(f"the design has {len(design)} faces, the problem's garment {garment.n_faces}")
    strips = build_clutches(problem, body, garment)
    from kgarment.design.driver import build_setup, design_equilibria

    setup = build_setup(problem, body, garment, strips, device, evaluation=True)
    keyed = setup.states()
    states = [s for _, s in keyed]
    full = solve_states(setup.model, np.ones(garment.n_faces), states, options=setup.solver)
    mine = design_equilibria(setup, design, lambda: full)
    rows = []
    for (key, _), rf, rd in zip(keyed, full, mine):
        cl = setup.objective != "passive"
        sf, sd = Stored.of(rf, cl), Stored.of(rd, cl)
        rows.append({"motion": key[0], "state": key[1],
                     "rho": relative_energy_density(design, setup.areas, sd, sf, setup.clutch_area()),
                     "energy": float(sd.face_energy[design > 0.5].sum() + sd.clutch_energy),
                     "energy_full": float(sf.face_energy.sum() + sf.clutch_energy),
                     "converged": bool(rf.converged and rd.converged)})
    return rows


def cmd_evaluate(args) -> int:
    import json

    from kgarment.design.run import load_design_history
    from kgarment.problem import load_problem

    run, it = _design_source(args.design)
    p = load_problem(run / "problem.toml")
    if args.motion:
        lib = p.library()
        for m in args.motion:
            lib.get(m)
        p = dataclasses.replace(p, motions=tuple(args.motion))
    hist = load_design_history(run)
    k = len(hist) - 1 if it is None else it
    if not 0 <= k < len(hist):
        raise KgarmentError(f"{run} has iterations 0..{len(hist) - 1}; asked for {k}")
    from kgarment.design.beso import X_MIN

    design = np.where(hist[k], 1.0, X_MIN)
    area = hist[k].mean()
    print(f"design: {run} iteration {k} ({100 * area:.1f}% of faces reinforced)")
    rows = evaluate_design(p, design, args.device)
    print(f"{'motion':24s} {'state':6s} {'rho':>7s} {'E design (J)':>13s} {'E full (J)':>11s}")
    for r in rows:
        flag = "" if r["converged"] else "  (NOT converged)"
        print(f"{r['motion']:24s} {r['state']:6s} {r['rho']:7.3f} {r['energy']:13.5g} {r['energy_full']:11.5g}{flag}")
    if args.json:
        Path(args.json).write_text(json.dumps({"run": str(run), "iteration": k, "rows": rows}, indent=1))
        print(f"wrote {args.json}")
    return 0


def add_evaluate_parser(sub, common) -> None:
    sp = sub.add_parser("evaluate", help="evaluate a design (any iteration of a run) on any motions: rho ON/OFF")
    sp.add_argument("design", help="run folder (its final design) or RUN@ITERATION")
    sp.add_argument("--motion", action="append", help="motion to evaluate on (repeatable); default: the run's")
    sp.add_argument("--json", help="also write the table as JSON to this file")
    sp.add_argument("--device", default="cpu", help="torch device (default cpu)")
    sp.set_defaults(func=cmd_evaluate)
