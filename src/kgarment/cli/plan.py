"""``kgarment plan RUN|RUN@ITERATION``: the control table of a design (which clutches to
switch on for which motion), written as plan.json and plan.md."""

from __future__ import annotations

import time
from pathlib import Path

from kgarment.cli.common import FRAMES, add_device, integer
from kgarment.constants import PLAN_EXHAUSTIVE


def cmd_plan(args) -> int:

    from kgarment.design import load_design, parse_design_source
    from kgarment.design.driver import run_inputs
    from kgarment.design.run import iteration_of
    from kgarment.errors import KgarmentError
    from kgarment.evaluate import Evaluator
    from kgarment.evaluate.plan import make_plan, plan_markdown
    from kgarment.io import atomic_write_text, check_output_folder, json_text
    from kgarment.problem import load_problem, override

    if args.out:
        check_output_folder(args.out, "--out")  # before the evaluation, not after it
    src = parse_design_source(args.design, run_required=True)
    k = iteration_of(src)
    out = Path(args.out) if args.out else src.run
    stem = "plan" if src.iteration is None else f"plan@{src.iteration}"
    files = [out / f"{stem}.json", out / f"{stem}.md"]
    folders = [f for f in files if f.is_dir()]
    if folders:
        raise KgarmentError(f"{folders[0]} is a folder; the plan is written there as a file: give --out DIR")
    existing = [f for f in files if f.exists()]
    if existing and not args.force:
        raise KgarmentError(f"{existing[0]} exists; --force replaces it, --out DIR writes elsewhere")
    p = override(load_problem(src.run / "problem.toml"), motions=args.motion)
    p, body, garment, strips = run_inputs(src.run, p)
    if not strips:
        raise KgarmentError(f"{src.run} has no clutches: there is nothing to switch")
    from kgarment.case.store import run_store

    ev = Evaluator.from_problem(p, body=body, garment=garment, strips=strips, device=args.device,
                                store=run_store(src.run))  # the run's equilibria
    design = load_design(src, ev.n_faces)
    n = len(strips)
    how = f"all {2 ** n - 1} sets" if n <= args.exhaustive else "greedy sets"
    print(f"design: {src.run} iteration {k}; {n} clutches, {len(ev.motions)} motions: evaluating {how} ...")
    t0 = time.time()
    known = None
    if args.path:  # the motion's end from rest competes with the two starts, as in evaluate --path
        from kgarment.evaluate.path import path_forces

        if p.body.phenotypes:
            raise KgarmentError("--path: the motion from rest is solved on one body; for a multi-body design "
                                "([body] phenotypes) leave --path out")
        print(f"the motion from rest first: {args.path} frames to the target pose, ON and OFF")
        known = path_forces(ev, design, p, frames=args.path).ends
    plan = make_plan(ev, design, exhaustive_up_to=args.exhaustive, known=known)
    if plan.from_path:
        print(f"  kept the motion from rest's end (lower than the two starts'): {', '.join(plan.from_path)}")
    for m in plan.motions:
        if not plan.controllable(m):
            print(f"  {m:22s} no clutch set changes this motion")
            continue
        s = plan.smallest(m)
        locks = ", ".join(f"{r.motion} {r.fraction:.0%}" for r in plan.locks(s))
        print(f"  {m:22s} switch on {', '.join(s.clutches):30s} {s.resistance_J:8.3g} J "
              f"({s.fraction:.0%} of all ON)" + (f"; also locks {locks}" if locks else ""))
    out.mkdir(parents=True, exist_ok=True)
    doc = {"run": str(src.run), "iteration": k, **plan.to_json()}
    atomic_write_text(files[0], json_text(doc))
    atomic_write_text(files[1], plan_markdown(plan, f"{src.run} iteration {k}"))
    print(f"{time.time() - t0:.0f} s; wrote {files[0]} and {files[1]}")
    return 0


def add_parsers(sub) -> None:
    sp = sub.add_parser("plan", help="the control table of a design: for each motion the clutches to switch "
                        "on, their resistance and tensions, and which sets lock other motions")
    sp.add_argument("design", help="run folder (its final design) or RUN@ITERATION")
    sp.add_argument("--motion", action="append", help="motion (repeatable); default: the run's")
    sp.add_argument("--out", help="folder for plan.json and plan.md (default: the run folder)")
    sp.add_argument("--exhaustive", type=integer(0, 10), default=PLAN_EXHAUSTIVE,
                    help=f"try every clutch subset up to this many clutches, greedy sets beyond "
                         f"(default {PLAN_EXHAUSTIVE})")
    sp.add_argument("--path", type=FRAMES, metavar="K", help="solve each motion from rest in K frames first; "
                    "where it ends lower than the evaluator's two starts, the table starts from there (as "
                    "kgarment evaluate --path K; 10 is a good start)")
    sp.add_argument("--force", action="store_true", help="replace an existing plan")
    add_device(sp)
    sp.set_defaults(func=cmd_plan)
