"""``kgarment sweep``: many variations of a problem, each an ordinary run folder, on Ray."""

from __future__ import annotations

import math
import os
from contextlib import contextmanager
from pathlib import Path

from kgarment.cli.common import integer
from kgarment.errors import KgarmentError


def cmd_sweep(args) -> int:
    from kgarment.sweep import load_sweep, open_folder

    if args.address and args.workers:
        raise KgarmentError("--workers sets the CPUs of the local Ray cluster; a cluster given by --address has "
                            "its own (ray start --num-cpus)")
    sweep = load_sweep(args.sweep)  # every task validated before anything runs
    out = Path(args.out) if args.out else Path("runs") / "sweeps" / sweep.path.stem
    folder = open_folder(sweep, out, args.force, write=False)  # refusals before Ray starts (and in a dry run)
    if args.dry_run:
        print(f"{len(sweep.tasks)} tasks of {sweep.base} (axes: {', '.join(sweep.axes) or 'none'}); run folders "
              f"would go to {out / 'runs'}:")
        for t in sweep.tasks:
            print(f"  {t.name:40s} " + ", ".join(f"{k} = {v!r}" for k, v in t.values))
        return 0
    from kgarment.design.run import run_status

    todo = [t for t in sweep.tasks if t.name in folder.replace or run_status(folder.run(t.name)) != "finished"]
    if todo:
        from kgarment.sweep.execute import import_ray

        import_ray()  # not installed: one line before any work
    where = f"the Ray cluster at {args.address}" if args.address else \
        f"a local Ray cluster of {args.workers or os.cpu_count()} CPUs"
    print(f"sweep {sweep.path}: {len(sweep.tasks)} tasks, {len(sweep.tasks) - len(todo)} finished already"
          + (f", {len(todo)} to run on {where}" if todo else "") + f"; folder {out}")
    from kgarment.optimize.beso import expected_iterations
    from kgarment.sweep.execute import run_sweep

    expected = {t.name: expected_iterations(t.problem.design.beso) for t in sweep.tasks}
    try:
        with sweep_progress(len(sweep.tasks), expected, args.quiet or not todo) as update:
            res = run_sweep(sweep, out, workers=args.workers, address=args.address, force=args.force,
                            progress=update)
    except KeyboardInterrupt:
        print(f"\ninterrupted; finished runs are kept, unfinished ones resume when you run the same command again "
              f"(the table so far: {out / 'sweep.md'})")
        return 130
    print_outcome(res)
    return 1 if res.failed else 0


def print_outcome(res) -> None:
    """One line per task (status, iterations, rho ON / OFF per motion), the counts, the files."""
    f = res.folder
    for name in f.tasks:
        rec = f.results.get(name, {})
        rho = "  ".join(f"{m} {v.get('on', math.nan):.2f}/{v.get('off', math.nan):.3f}"
                        for m, v in rec.get("rho", {}).items())
        tag = "skipped (finished before)" if name in res.skipped else rec.get("status", "new")
        extra = rec.get("error") if rec.get("status") == "failed" else rho
        it = rec.get("iterations")
        print(f"  {name:40s} {tag:25s} {'' if it is None else f'{it:4d} it':8s} {extra or ''}")
    print(f"{len(res.ran)} ran, {len(res.skipped)} skipped, {len(res.failed)} failed; run folders in {f.root / 'runs'}")
    for p in res.paths:
        print(f"  {p}")


@contextmanager
def sweep_progress(total: int, expected: dict, quiet: bool):
    """A progress bar over tasks (the running ones count by their iterations; lines where standard
    output is not a terminal: :mod:`kgarment.cli.progress`); yields
    ``update(SweepProgress)`` for :func:`kgarment.sweep.execute.run_sweep`."""
    from rich.progress import TextColumn

    from kgarment.cli.progress import progress_bars

    with progress_bars((TextColumn("[bold]{task.fields[done]}/{task.total:.0f} tasks"),),
                       lambda t: f"{t['done']}/{t['total']:.0f} tasks", quiet) as bar:
        task = bar.add_task("starting", total=total, done=0)

        def update(state) -> None:
            partial = sum(min(0.95, it / max(1, expected.get(n, 1))) for n, it in state.running.items())
            running = ", ".join(f"{n} it {it}" for n, it in list(state.running.items())[:3])
            more = len(state.running) - 3
            desc = ", ".join(([f"{state.failed} failed"] if state.failed else []) +
                             ([f"running {running}" + (f" (+{more})" if more > 0 else "")] if state.running else []))
            bar.update(task, completed=state.finished + state.failed + partial, description=desc,
                       done=state.finished + state.failed)

        yield update


def add_parsers(sub) -> None:
    sp = sub.add_parser("sweep", help="design many variations of a problem (a grid or a list of runs), each an "
                        "ordinary run folder, on Ray; resumable; a table and plots of them all")
    sp.add_argument("sweep", help="sweep file (TOML): a base problem (problem = FILE, example = NAME or [problem]), "
                    "[set] fields for every task, and [grid] axes or [[runs]]")
    sp.add_argument("--out", help="sweep folder (default runs/sweeps/<sweep file name>); run again to resume: "
                    "finished runs are skipped, unfinished ones resumed")
    sp.add_argument("--workers", type=integer(1, 1024), help="CPUs of the local Ray cluster: tasks run side by "
                    "side, one CPU each (default: the machine's cores)")
    sp.add_argument("--address", help="run on an existing Ray cluster (ray start --head; e.g. auto or HOST:6379) "
                    "instead of a local one; the sweep folder should be on storage every node shares")
    sp.add_argument("--force", action="store_true", help="run a changed sweep file over an existing sweep folder: "
                    "tasks whose problem changed start again (their run folders replaced); others are kept")
    sp.add_argument("--dry-run", action="store_true", help="list the tasks (validated) and stop")
    sp.set_defaults(func=cmd_sweep)
