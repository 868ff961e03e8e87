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


def build_setup(problem, body, garment, strips, device: str = "cpu"):
    """The design loop's precomputed setup for a problem (model, motions, filter, ...)."""
    from kgarment.design import BesoParams
    from kgarment.design.loop import DesignSetup
    from kgarment.sim import SolverOptions, build_model
    from kgarment.simulate import sim_motions

    d = problem.design
    params = BesoParams(**{k: v for k, v in dataclasses.asdict(d).items()
                           if k not in ("objective", "protect_attachments", "protect_clutch_margin")})
    use_clutches = strips if d.objective != "passive" else []
    model = build_model(garment.rest_vertices, garment.faces, use_clutches, preset=problem.solver.preset)
    s = problem.solver
    opts = SolverOptions(method=s.method, tol=s.tol, max_iter=s.max_iter, device=device)
    return DesignSetup(model, sim_motions(body, garment), d.objective, params, opts,
                       protected=protected_faces(garment, use_clutches, d.protect_attachments, d.protect_clutch_margin))


def protected_faces(garment, strips, attachments: bool, margin: float):
    """(m,) bool faces kept reinforced: attachment rings and/or faces whose centroid is
    within ``margin`` metres of a clutch anchor; None when nothing is protected."""
    keep = garment.attached.copy() if attachments else np.zeros(garment.n_faces, bool)
    if margin > 0 and strips:
        cent = garment.rest_vertices[garment.faces].mean(axis=1)
        anchors = np.concatenate([c.vertices[c.anchors] for c in strips])
        d = np.linalg.norm(cent[:, None, :] - anchors[None, :, :], axis=2).min(axis=1)
        keep |= d <= margin
    return keep if keep.any() else None


def _expected_iterations(p) -> int:
    return math.ceil(math.log(p.target_area) / math.log(1 - p.er)) + 2 * p.window


def _progress_line(row: dict, motions) -> str:
    rho = "  ".join(f"{m} {row.get(f'rho[{m}:on]', row.get(f'rho[{m}:none]', float('nan'))):.2f}"
                    + (f"/{row[f'rho[{m}:off]']:.2f}" if f"rho[{m}:off]" in row else "") for m in motions)
    return f"area {100 * row['area']:5.1f}%  objective {row['objective']:8.4f}  rho {rho}"


def cmd_design(args) -> int:
    from rich.progress import BarColumn, Progress, TextColumn, TimeElapsedColumn, TimeRemainingColumn

    from kgarment.clutch import save_clutches
    from kgarment.cli import _problem
    from kgarment.design.loop import initial_state, run_loop
    from kgarment.design.run import load_checkpoint, prepare_run_folder, save_checkpoint
    from kgarment.problem import build_body, build_clutches, build_garment, clutch_specs, load_problem, problem_to_dict

    if args.resume:
        run = prepare_run_folder(args.resume, resume=True)
        p = load_problem(run / "problem.toml")
    else:
        p = _problem(args)
        if args.max_iterations:
            p = dataclasses.replace(p, design=dataclasses.replace(p.design, max_iterations=args.max_iterations))
        run = prepare_run_folder(args.out, force=args.force)
    print(p.describe())
    body = build_body(p)
    garment = build_garment(p, body)
    strips = build_clutches(p, body, garment)
    if not args.resume:
        import tomli_w

        specs = clutch_specs(p, body)
        if specs:
            save_clutches(run / "clutches.toml", specs, garment.rest_vertices, garment.faces)
        if p.source:
            (run / "problem.source.toml").write_text(Path(p.source).read_text())
        (run / "problem.toml").write_text(tomli_w.dumps(problem_to_dict(p, run / "clutches.toml" if specs else None)))
        (run / "problem.txt").write_text(p.describe() + "\n")
    setup = build_setup(p, body, garment, strips, args.device)
    st = load_checkpoint(run) if args.resume else initial_state(setup)
    print(f"garment {garment.name}: {garment.n_faces} faces, {len(strips)} clutches, "
          f"{len(setup.states())} states per iteration; run folder {run}")
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
            run_loop(setup, st, checkpoint=lambda s: save_checkpoint(run, s), progress=progress)
        except KeyboardInterrupt:
            print(f"\ninterrupted after iteration {st.iteration - 1}; continue with: kgarment design --resume {run}")
            return 130
    from kgarment.design.report import finish_run

    paths = finish_run(run, setup, st, body, garment, strips)
    last = st.metrics[-1]
    print(f"\n{len(st.metrics)} iterations in {time.time() - t0:.0f} s; final {_progress_line(last, motions)}")
    print(f"islands {last['islands']} ({last['islands_with_clutches']} counting clutches as links); "
          f"clutch ends on reinforcement {last['clutch_ends_supported']}/{last['clutch_ends']}")
    print(f"results in {run}/: metrics.csv, metrics.json, progress.png, designs.npz, final/")
    for path in paths:
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
    setup = build_setup(problem, body, garment, strips, device)
    keyed = setup.states()
    states = [s for _, s in keyed]
    full = solve_states(setup.model, np.ones(garment.n_faces), states, options=setup.solver)
    mine = solve_states(setup.model, design, states, warm_start=[r.x for r in full], options=setup.solver)
    rows = []
    for (key, _), rf, rd in zip(keyed, full, mine):
        cl = setup.objective != "passive"
        sf = Stored(rf.garment_energy, float(sum(e.sum() for e in rf.clutch_energy)) if cl else 0.0)
        sd = Stored(rd.garment_energy, float(sum(e.sum() for e in rd.clutch_energy)) if cl else 0.0)
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
