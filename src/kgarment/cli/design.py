"""``kgarment design | evaluate | demo``: the design loop on the command line."""

from __future__ import annotations

import contextlib
import time
from pathlib import Path

from kgarment import constants as C
from kgarment.cli.common import (
    FRAMES,
    MAX_ITERATIONS,
    SUBDIVISION,
    add_clutch_model,
    add_device,
    add_overrides,
    add_problem,
    add_skin_friction,
    design_progress,
    load,
    parse_phenotype,
    print_evaluation,
    rho_line,
)
from kgarment.errors import KgarmentError

DEMO_EXAMPLE = "shirt_three_motions"
SIZES_EXAMPLE = "shirt_sizes"
PLOT_SUFFIXES = (".png", ".pdf", ".svg")  # what --plot can draw into
DESIGN_OUT = "runs/design"  # kgarment design --out's default


def run_design(problem, out, *, resume: bool, force: bool, device: str, quiet: bool, evaluate: bool = True) -> int:
    """Open (or resume) a run folder, iterate with a progress bar, print the summary."""
    from kgarment.design import finish, open_run
    from kgarment.optimize.beso import expected_iterations

    dr = open_run(None if resume else problem, out, resume=resume, force=force, device=device)
    if not quiet:
        print(dr.problem.describe())
    setup = dr.setup
    print(f"garment {dr.garment.name}: {dr.garment.n_faces} faces, {len(dr.strips)} clutches, "
          f"{len(setup.case.states())} states per iteration ({setup.case.solver.workers} worker processes); run folder {dr.run}")
    motions = list(setup.case.motions)
    last = [dr.state]
    t0 = time.time()
    with design_progress(expected_iterations(setup.beso.params), dr.state.iteration, motions, quiet) as update:
        def progress(st):
            last[0] = st
            update(st)

        try:
            dr = finish(dr, progress=progress, evaluate=evaluate)
        except KeyboardInterrupt:
            print(f"\ninterrupted after iteration {last[0].iteration - 1}; continue with: "
                  f"kgarment design --resume {dr.run}")
            return 130
    print_summary(dr, time.time() - t0)
    return 0


def print_summary(dr, seconds: float) -> None:
    st = dr.state
    frames = dr.problem.solver.path_frames
    row = st.metrics[-1]
    print(f"\n{len(st.metrics)} iterations in {seconds:.0f} s; last iteration {rho_line(row, list(dr.setup.case.motions))}")
    if dr.evaluation is not None:  # and dr.selection: how finish chose it
        sel = dr.selection
        k = sel.iteration
        checked = dr.setup.beso.path_start > 0
        how = ("the best objective at the target area" + (" among the iterations solved over the motion"
                                                           if checked else ""))
        if len(sel.tried) > 1:
            n = len(sel.tried)
            how += (f" that the evaluator reproduces; {n - 1} better one(s) not" if sel.reproduced else
                    f"; the evaluator reproduces none of the {n} best, this one is the best as evaluated")
        print(f"final design: iteration {k} ({how}), evaluated like kgarment evaluate {dr.run}"
              + (f" --path {frames}" if checked else "") + ":")
        print_evaluation(dr.evaluation)
    print(f"results in {dr.run}/: metrics.csv, metrics.json, progress.png, designs.npz, final/")
    for path in dr.paths:
        print(f"  {path}")
    if dr.evaluation is not None and dr.evaluation.loads is not None and not dr.setup.case.wearers:  # clutches to feel
        print(f"next: the force each clutch carries over the motion: kgarment evaluate {dr.run} --path {frames}; "
              f"which clutches to switch on for which motion: kgarment plan {dr.run}; cut files: "
              f"kgarment fabricate {dr.run}")


# what a new run takes and a resumed one cannot: it continues with its own problem.toml
RESUME_IGNORES = ("problem", "motion", "garment", "subdivision", "preset", "solver", "tol", "max_iterations",
                  "refine", "clutch_model", "holding_force", "buckle", "channel", "skin_friction", "force")


def cmd_design(args) -> int:
    if args.resume:
        given = [n for n in RESUME_IGNORES if getattr(args, n, None) not in (None, False)]
        if args.out != DESIGN_OUT:
            given.insert(0, "out")
        if given:
            flag = "a problem file" if given[0] == "problem" else "--" + given[0].replace("_", "-")
            raise KgarmentError(f"--resume {args.resume} continues the run with its own problem.toml and folder; "
                                f"{flag} would be ignored: leave it out, or start a new run (--out, --force)")
    problem = None if args.resume else load(args)
    return run_design(problem, args.resume or args.out, resume=bool(args.resume), force=args.force,
                      device=args.device, quiet=args.quiet, evaluate=not args.no_evaluation)


def cmd_demo(args) -> int:
    """The main job: design the three-motion shirt (resumes or reports an existing run)."""
    from kgarment.design import run_status
    from kgarment.problem import example_path, load_problem, override

    out = Path(args.out)
    status = run_status(out)
    if status != "new" and not args.force:  # what it holds must be what was asked for
        held = load_problem(out / "problem.toml")
        for flag, asked, has in (("--subdivision", args.subdivision, held.garment.subdivision),
                                 ("--max-iterations", args.max_iterations, held.design.beso.max_iterations)):
            if asked is not None and asked != has:
                raise KgarmentError(f"{out} holds a run with {flag} {has}, not {asked}; use --force to replace "
                                    "it or --out for another folder")
    if status == "finished" and not args.force:
        from kgarment.constants import SIM_MODEL
        from kgarment.design.run import checkpoint_model, other_model

        then = checkpoint_model(out)
        older = f", made with {other_model(then)}" if then != SIM_MODEL else ""
        print(f"{out} already holds a finished design{older} (use --force to redo it); results:")
        for f in [out / "metrics.csv", out / "progress.png"] + sorted((out / "final").glob("*")):
            print(f"  {f}")
        return 0
    resume = status == "unfinished" and not args.force
    if resume:
        print(f"resuming the unfinished run in {out}")
    problem = override(load_problem(example_path(DEMO_EXAMPLE)), subdivision=args.subdivision,
                       max_iterations=args.max_iterations)
    return run_design(problem, out, resume=resume, force=args.force, device=args.device, quiet=args.quiet)


def cmd_sizes(args) -> int:
    """One design for a size range against one design per size (kgarment.design.sizes)."""
    from kgarment.design.sizes import run_sizes
    from kgarment.problem import example_path, load_problem, override

    problem = load(args) if args.problem else override(load_problem(example_path(SIZES_EXAMPLE)),
                                                          subdivision=args.subdivision,
                                                          max_iterations=args.max_iterations)
    if not problem.body.names:
        raise KgarmentError(f"{args.problem}: kgarment sizes needs a multi-body problem ([body] phenotypes = "
                            f"[{{name = ...}}, ...], e.g. the example {SIZES_EXAMPLE})")
    motions = list(problem.motions)  # run_sizes checks --out before any work
    print(f"wearers: {', '.join(problem.body.names)}; motions: {', '.join(motions)}; runs in {args.out}/runs")
    from kgarment.case.keys import wearer_motion
    from kgarment.optimize.beso import expected_iterations

    total = expected_iterations(problem.design.beso)
    bars = contextlib.ExitStack()

    def progress(name):  # a progress bar per design, each closed when the next one starts
        bars.close()
        print(f"design {name}: " + ("every wearer at once" if name == "all" else f"for {name} alone"))
        keys = motions if name != "all" else [wearer_motion(m, n) for n in problem.body.names for m in motions]
        return bars.enter_context(design_progress(total, 0, keys[:3], args.quiet))

    try:
        with bars:
            doc = run_sizes(problem, args.out, device=args.device, force=args.force, progress=progress)
    except KeyboardInterrupt:
        print(f"\ninterrupted; run the same command again to continue (finished runs in {args.out}/runs are kept)")
        return 130
    print(Path(args.out, "sizes.md").read_text())
    print(f"wrote {args.out}/sizes.json, sizes.md, sizes.png")
    return 0 if doc["rows"] else 1


def cmd_evaluate(args) -> int:

    from kgarment.case.store import run_store
    from kgarment.design import load_design, parse_design_source
    from kgarment.design.driver import run_inputs
    from kgarment.design.run import iteration_of
    from kgarment.evaluate import Evaluator
    from kgarment.evaluate.loads import load_chart
    from kgarment.io import atomic_write_text, check_output_file, json_text
    from kgarment.problem import load_problem, override

    if args.plot and args.no_loads:
        raise KgarmentError("--plot draws the clutch loads, which --no-loads leaves out; give one of them")
    if args.plot and args.json and Path(args.plot).resolve() == Path(args.json).resolve():
        raise KgarmentError(f"--json and --plot name the same file {args.json}; give two files")
    for flag, path, suffixes in (("--json", args.json, ()), ("--plot", args.plot, PLOT_SUFFIXES)):
        if path:
            check_output_file(path, flag, force=args.force, suffixes=suffixes)  # before the evaluation
    src = parse_design_source(args.design, run_required=True)
    p = override(load_problem(src.run / "problem.toml"), motions=args.motion, clutch_model=args.clutch_model,
                 holding_force=args.holding_force, buckle=args.buckle, friction=args.skin_friction,
                 channel=args.channel)
    if args.converge and not args.path:
        raise KgarmentError("--converge refines the force over the motion: give --path K too")
    if args.path and p.body.phenotypes:
        raise KgarmentError("--path: the force over the motion is solved on one body; for a multi-body design "
                            "([body] phenotypes) leave --path out (each wearer is evaluated at the target pose)")
    if args.phenotype:  # checked before the work
        if p.body.model != "anny":
            raise KgarmentError("--phenotype needs a run on the Anny body (body model 'anny')")
        phenotypes = [parse_phenotype(text, p.body.phenotype) for text in args.phenotype]
    hw = p.clutch_spec().hardware
    other_hw = args.clutch_model or args.holding_force or args.buckle is not None or args.channel is not None
    if other_hw:
        print("clutches: " + {"locked": "locked (never slip)", "slip": "slip at their holding force",
                              "cable": "pull-only cables between their ends, slipping at their holding force"}[hw.model]
              + ("; the strips buckle (no compression)" if hw.buckle else "; the strips resist compression")
              + ("; in channels sewn to the garment" if hw.channel else "; snapped on at their ends"))
    k = iteration_of(src)
    # another clutch model or skin friction than the run's gets --path files of its own (the run's path stays)
    stem = src.run / (f"path-{k}" + (f"-{hw.model}" + ("-buckle" if hw.buckle else "") + ("-channel" if hw.channel else "")
                                     if other_hw else "")
                      + (f"-mu{args.skin_friction:g}" if args.skin_friction is not None else ""))
    for flag, f in (("--json", args.json), ("--plot", args.plot)):
        if args.path and f and Path(f).resolve() in (stem.with_suffix(".json").resolve(), stem.with_suffix(".png").resolve()):
            raise KgarmentError(f"{flag} {f} is where --path writes the force over the motion; give another file")
    p, body, garment, strips = run_inputs(src.run, p)
    store = run_store(src.run)  # the run's final evaluation left its equilibria there
    ev = Evaluator.from_problem(p, body=body, garment=garment, strips=strips, device=args.device, store=store)
    design = load_design(src, ev.n_faces)
    print(f"design: {src.run} iteration {k} ({100 * (design > 0.5).mean():.1f}% of faces reinforced)")
    path = None
    if args.path:  # first: the motion's end from rest competes with the evaluation's two starts
        from kgarment.evaluate.path import path_forces
        from kgarment.evaluate.path_plot import path_plot

        def progress(line: str) -> None:
            print(f"  {line}", flush=True)

        checks = []
        if args.converge:
            from kgarment.evaluate.path_converge import converged_path

            print(f"force over the motion: from {args.path} frames from rest to the target pose, doubled until two "
                  f"counts agree within {100 * C.PATH_CONVERGE_TOL:g}% (at most {C.PATH_MAX_FRAMES}), ON and OFF")
            path, checks = converged_path(ev, design, p, frames=args.path, report=progress)
        else:
            print(f"force over the motion: {args.path} frames from rest to the target pose, ON and OFF")
            path = path_forces(ev, design, p, frames=args.path, report=progress)
        print(path.table())
        for check in checks:
            print(check.line())
        atomic_write_text(stem.with_suffix(".json"), json_text({"run": str(src.run), "iteration": k, **path.to_json(),
                                                                **({"frames_checked": [c.to_json() for c in checks]}
                                                                   if checks else {})}))
        title = f"{src.run.name} iteration {k}: force over the motion" + {"slip": " (clutches slip)", "cable": " (cable clutches)"}.get(hw.model, "")
        print(f"wrote {path_plot(path, stem.with_suffix('.png'), title)}"
              f" and {stem.with_suffix('.json')}")
    res = ev.evaluate(design, loads=not args.no_loads, known=path.ends if path is not None else None)
    if store.hits or store.borrowed:
        shared = f", {store.borrowed} from the machine's cache of fully reinforced garments" if store.borrowed else ""
        print(f"{store.hits} solves read back from {store.folder} (the same state from the same start, "
              f"solved before){shared}, {store.misses - store.borrowed} solved now")
    print_evaluation(res)
    if args.plot and res.loads is not None:
        print(f"wrote {load_chart(res.loads, args.plot, f'{src}: clutch loads')}")
    others = [evaluate_on_phenotype(args, p, phen, body, garment, design) for phen in phenotypes] \
        if args.phenotype else []
    if args.json:
        doc = {"run": str(src.run), "iteration": k, **res.to_json()}
        if path is not None:
            doc["path"] = path.to_json()
        if others:
            doc["transfer"] = others
        atomic_write_text(args.json, json_text(doc))
        print(f"wrote {args.json}")
    return 0


def evaluate_on_phenotype(args, p, phen, run_body, garment, design) -> dict:
    """The design evaluated on the body with ``--phenotype`` (:mod:`kgarment.case.transfer`):
    the same garment faces and clutch spots on the other body; printed, and returned for
    the JSON (the phenotype and the evaluation)."""
    import dataclasses

    from kgarment.case.transfer import clutches_on, garment_on
    from kgarment.case.wearers import on_phenotype
    from kgarment.evaluate import Evaluator
    from kgarment.problem import build_body, clutch_specs

    other = on_phenotype(p, phen)
    body = build_body(other)
    g = garment_on(body, garment)
    strips = clutches_on(clutch_specs(p, run_body), run_body, garment, g)
    ev = Evaluator.from_problem(other, body=body, garment=g, strips=strips, device=args.device)
    res = ev.evaluate(design, loads=not args.no_loads)
    changed = ", ".join(f"{k} {v:g}" for k, v in dataclasses.asdict(phen).items()
                        if v != getattr(p.body.phenotype, k)) or "the run's own"
    print(f"on another body (phenotype: {changed}; the same garment faces and clutch spots):")
    print_evaluation(res)
    return {"phenotype": dataclasses.asdict(phen), **res.to_json()}


def add_parsers(sub) -> None:
    sp = sub.add_parser("design", help="automatic design (BESO) of the reinforcement; checkpoints every iteration")
    add_problem(sp)
    add_device(sp)
    add_overrides(sp, max_iterations=True, clutch=True)
    sp.add_argument("--out", default=DESIGN_OUT, help=f"run folder (default {DESIGN_OUT})")
    sp.add_argument("--resume", metavar="RUN", help="continue a run folder where it stopped (with its own "
                    "problem.toml: no problem file or problem flags)")
    sp.add_argument("--force", action="store_true", help="replace an existing run folder")
    sp.add_argument("--no-evaluation", action="store_true", help="skip the final design's evaluation (rho from two "
                    "starts and the load of every clutch: one more solve per clutch and motion); "
                    "kgarment evaluate RUN does it later")
    sp.set_defaults(func=cmd_design)

    sp = sub.add_parser("sizes", help="one design for a size range ([body] phenotypes) against one design per "
                        "size: runs both (resumable) and writes sizes.md/json/png")
    sp.add_argument("problem", nargs="?", help="a multi-body problem file (default: the example shirt_sizes)")
    add_device(sp)
    add_overrides(sp, motion=False, garment=False)
    sp.add_argument("--max-iterations", type=MAX_ITERATIONS, help="stop each design after this many iterations")
    sp.add_argument("--out", default="runs/sizes", help="folder (default runs/sizes): runs/all, runs/<wearer>, "
                    "sizes.md, sizes.json, sizes.png")
    sp.add_argument("--force", action="store_true", help="run every design again (replacing its run folder)")
    sp.set_defaults(func=cmd_sizes)

    sp = sub.add_parser("evaluate", help="evaluate a design (any iteration of a run) on any motions: rho ON/OFF, "
                        "islands, clutch ends, and the load each clutch carries",
                        description="Evaluate a design of a run with the one design evaluator. Solves done "
                        "before on the run (its final evaluation, an earlier evaluate or plan) are read back "
                        "from RUN/equilibria/ instead of solved again: the same numbers, without the work; "
                        "the fully reinforced garment's also from the machine's cache (~/.cache/kgarment/"
                        "equilibria/, KGARMENT_SOLVE_CACHE=0 turns it off).")
    sp.add_argument("design", help="run folder (its final design) or RUN@ITERATION")
    sp.add_argument("--motion", action="append", help="motion to evaluate on (repeatable); default: the run's")
    sp.add_argument("--json", help="also write the results as JSON to this file")
    sp.add_argument("--plot", help="also draw the clutch loads (share and tension per motion) into this PNG "
                    "(or .pdf, .svg)")
    sp.add_argument("--force", action="store_true", help="overwrite an existing --json or --plot file (never a "
                    "file of a run folder)")
    sp.add_argument("--no-loads", action="store_true", help="skip the per-clutch loads (one more solve per "
                    "clutch and motion)")
    sp.add_argument("--path", type=FRAMES, metavar="K", help="also the force over the motion: K quasi-static frames "
                    "from rest to the target pose, ON and OFF (garment energy and every clutch's tension per "
                    "frame; plot and JSON written to RUN/path-ITERATION.png/.json; 10 is a good start)")
    sp.add_argument("--converge", action="store_true", help="with --path K: solve each motion again over 2K, 4K, "
                    "... frames until two counts agree (the energy at every frame within "
                    f"{100 * C.PATH_CONVERGE_TOL:g}%% of the ON energy at the target; at most {C.PATH_MAX_FRAMES} "
                    "frames) and report the finest; with skin friction a coarse step can carry the garment past "
                    "where it slips")
    sp.add_argument("--phenotype", metavar="FIELD=V,...", action="append", help="also evaluate the design on "
                    "another body (repeatable): Anny with these phenotype fields changed (gender, age, muscle, "
                    "weight, height, proportions, each in [0, 1]), the garment cut from the same faces and the "
                    "clutches at the same spots")
    add_clutch_model(sp)
    add_skin_friction(sp)
    add_device(sp)
    sp.set_defaults(func=cmd_evaluate)

    sp = sub.add_parser("demo", help=f"the main job: design the three-motion shirt ({DEMO_EXAMPLE}.toml, "
                                     "see kgarment examples)")
    add_device(sp)
    sp.add_argument("--out", default="runs/demo", help="run folder (default runs/demo); an unfinished run is resumed")
    sp.add_argument("--subdivision", type=SUBDIVISION, default=0,
                    help="garment resolution (default 0; 1 is the default elsewhere, 2 matches the paper)")
    sp.add_argument("--max-iterations", type=MAX_ITERATIONS, help="stop after this many iterations")
    sp.add_argument("--force", action="store_true", help="start over, replacing the run folder")
    sp.set_defaults(func=cmd_demo)
