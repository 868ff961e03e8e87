"""``kgarment reproduce``: every experiment of the paper, the baselines and a report."""

from __future__ import annotations

import time

from kgarment import constants as C
from kgarment.cli.common import add_clutch_model, add_device
from kgarment.errors import KgarmentError


def cmd_reproduce(args) -> int:
    from rich.progress import TextColumn

    from kgarment.cli.progress import progress_bars
    from kgarment.io import check_kind, read_json_object
    from kgarment.reproduce.catalog import DATA, RESOLUTIONS, select
    from kgarment.reproduce.pipeline import reproduce, rewrite_summary
    from kgarment.reproduce.report import write_report

    exps = select(args.experiments)
    out = check_kind(args.out, "reproduction", legacy=(DATA, "evaluations.json", "runs"))
    if args.report_only:
        if not (out / DATA).is_file():
            raise KgarmentError(f"{out} has no data.json; run kgarment reproduce --out {out} first")
        doc = read_json_object(out / DATA, "reproduction data", ("resolution", "experiments"))
        if not isinstance(doc["experiments"], dict):
            raise KgarmentError(f"reproduction data {out / DATA} is damaged ('experiments' is not a table)")
        md, page = write_report(out, doc)
        rewrite_summary(out, doc)  # results.json from the same data.json as the report
        print(f"report: {page} (Markdown: {md})")
        return 0
    res = RESOLUTIONS[args.resolution]
    print(f"reproducing {len(exps)} experiment(s) at {res.name} resolution"
          + (f" with the {args.preset} material preset" if args.preset else "")
          + (f" with clutches {args.clutch_model or 'slip'}" if args.clutch_model or args.holding_force else "")
          + (" with buckling clutch strips" if args.buckle else "")
          + f" into {out} "
          f"(finished runs and evaluations there are reused): {', '.join(e.name for e in exps)}")
    t0 = time.time()
    with progress_bars((TextColumn("[bold]{task.fields[run]:34s}"), TextColumn("it {task.completed:>3}")),
                       lambda t: f"{t['run']}: it {t['completed']:>3} of ~{t['total']}", args.quiet) as bar:
        tasks: dict = {}

        def progress(run: str, row: dict, expected: int) -> None:
            if run not in tasks:
                # this iteration counts as done before the clock starts: the rate comes from those after it
                tasks[run] = bar.add_task("", total=expected, completed=row["iteration"] + 1, run=run)
            bar.update(tasks[run], completed=row["iteration"] + 1, total=max(expected, row["iteration"] + 2),
                       description=f"area {100 * row['area']:5.1f}%  objective {row['objective']:8.4f}  "
                                   f"{row['seconds']:5.1f} s/it")

        doc = reproduce(out, res.name, args.experiments, args.device, progress,
                        {"preset": args.preset, "clutch_model": args.clutch_model, "holding_force": args.holding_force,
                         "buckle": args.buckle, "channel": args.channel})
    md, page = write_report(out, doc)
    print(f"done in {(time.time() - t0) / 60:.1f} min; report: {page} (Markdown twin: {md}); runs in {out / 'runs'}")
    return 0


def add_parsers(sub) -> None:
    from kgarment.reproduce.catalog import EXPERIMENTS, RESOLUTIONS

    sp = sub.add_parser("reproduce", help="run every design experiment of the paper with baselines; "
                        "write an HTML + Markdown report")
    sp.description = ("Design every experiment of the paper (" + ", ".join(e.name for e in EXPERIMENTS) + "), "
                      "the compliance, manual, fully reinforced and random baselines at the same budget, the "
                      "cross-evaluation of the sleeve and shirt designs, and a report with tables and pictures. "
                      "Runs and evaluations are kept in OUT and reused: run it again to continue. OUT/data.json "
                      "accumulates: --experiments adds to the experiments already there (same resolution and preset), "
                      "so a long reproduction can be done a few experiments at a time.")
    sp.add_argument("--resolution", default="preview", choices=tuple(RESOLUTIONS),
                    help="tiny: a smoke run (3 iterations); preview (default): subdivision 0, the target "
                         "shrinking by 3%% per iteration; default: the example files as they are (subdivision 1)")
    sp.add_argument("--out", default="runs/reproduce", help="output folder (default runs/reproduce)")
    sp.add_argument("--experiments", help="comma-separated subset of experiments (default: all); those already "
                    "in OUT are kept in the report")
    sp.add_argument("--preset", choices=C.PRESET_NAMES, help="material preset of every experiment (default: the "
                    "example files', paper); give each preset its own --out")
    sp.add_argument("--report-only", action="store_true", help="rewrite the report from OUT/data.json")
    ours = "the example's in the selective sleeve (ours, not the paper's)"
    add_clutch_model(sp, f"the paper's strips in the paper's experiments, whatever the example files say, {ours}; "
                     "a buckling reproduction needs its own --out",
                     f"the paper's locked clutches in the paper's experiments, {ours}")
    add_device(sp)
    sp.set_defaults(func=cmd_reproduce)
