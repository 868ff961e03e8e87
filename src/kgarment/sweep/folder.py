"""The sweep folder: what a sweep wrote, what it ran and what each task gave.

Layout of ``kgarment sweep SWEEP.toml --out DIR``::

    DIR/.kgarment           marks a folder kgarment made (kind "sweep")
    DIR/sweep.toml          the sweep file as given (copy)
    DIR/sweep.json          every task's problem (name -> problem dict) and its record
    DIR/tasks/NAME.toml     each task's problem file (``kgarment design`` runs it alone)
    DIR/runs/NAME/          each task's run folder (``kgarment evaluate DIR/runs/NAME``, ...)
    DIR/logs/NAME.log       each task's log
    DIR/sweep.csv, .md, .png  the table and the plots (:mod:`kgarment.sweep.table`)

A sweep over an existing folder is refused when its tasks differ from the ones the folder
ran (other names, or another problem under a name; comments and spacing of the file do
not count) unless ``force``: then the tasks whose problem changed start again, their run
folders replaced (only kgarment run folders; :func:`kgarment.io.check_replaceable`), and
the run folders of tasks the sweep no longer has are left where they are.
"""

from __future__ import annotations

import contextlib
import json
import logging
from dataclasses import dataclass, field
from pathlib import Path

import tomli_w

from kgarment.errors import KgarmentError
from kgarment.io import MARKER, atomic_write_text, check_output_folder, mark_folder, owned

log = logging.getLogger(__name__)
STATE = "sweep.json"
COPY = "sweep.toml"
LOCK = ".sweep.lock"


def _key(data) -> str:
    return json.dumps(data, sort_keys=True, default=str)


@dataclass
class SweepFolder:
    """An open sweep folder.

    root : the folder;  runs : name -> problem dict of every task it has run (also tasks a
    later sweep file dropped, so that a name coming back with another problem is seen);
    tasks : the current sweep's task names, in order;  axes : its axis labels;
    results : name -> record (:func:`summarise_run` + ``wall_s``, ``error``);
    replace : tasks whose run folders start again (their problem changed; ``force``).
    """

    root: Path
    runs: dict = field(default_factory=dict)
    tasks: list = field(default_factory=list)
    axes: list = field(default_factory=list)
    values: dict = field(default_factory=dict)
    results: dict = field(default_factory=dict)
    replace: frozenset = frozenset()

    def run(self, name: str) -> Path:
        return self.root / "runs" / name

    def log(self, name: str) -> Path:
        return self.root / "logs" / f"{name}.log"

    def task_file(self, name: str) -> Path:
        return self.root / "tasks" / f"{name}.toml"

    def save(self) -> None:
        """sweep.json (atomically; unless it holds the same already)."""
        doc = {"kind": "sweep", "tasks": self.tasks, "axes": self.axes, "values": self.values,
               "runs": self.runs, "results": self.results}
        write_if_changed(self.root / STATE, json.dumps(doc, indent=1, default=str) + "\n")

    def record(self, name: str, rec: dict) -> None:
        self.results[name] = rec
        self.save()


def open_folder(sweep, out, force: bool = False, write: bool = True) -> SweepFolder:
    """Check ``out`` for ``sweep`` (a :class:`kgarment.sweep.spec.Sweep`) before any work and
    (``write``) write the sweep's files into it: the copy of the sweep file, sweep.json and
    the task files.  Refusals are one KgarmentError: a folder kgarment did not write, a
    folder of something else, or (without ``force``) a sweep whose tasks differ."""
    root = check_output_folder(out)
    new = {t.name: t.data for t in sweep.tasks}
    old: dict = {}
    if root.is_dir() and any(p.name != LOCK for p in root.iterdir()):
        state = root / STATE
        if not state.is_file():
            what = ("a kgarment folder of another kind" if owned(root) or (root / MARKER).is_file()
                    else "a folder of files kgarment did not write")
            raise KgarmentError(f"--out {root} is {what}, not a sweep folder; it is never replaced, give another --out")
        try:
            old = json.loads(state.read_text())
            if old.get("kind") != "sweep":
                raise ValueError("not a sweep's state")
        except ValueError as exc:
            raise KgarmentError(f"{state} is damaged ({exc}); give another --out") from None
    runs = dict(old.get("runs", {}))
    changed = [n for n in new if n in runs and _key(runs[n]) != _key(new[n])]
    added = [n for n in new if n not in old.get("tasks", [])]
    dropped = [n for n in old.get("tasks", []) if n not in new]
    if old and (changed or added or dropped) and not force:
        parts = [f"{len(v)} {what} ({', '.join(v[:3])}{', ...' if len(v) > 3 else ''})"
                 for what, v in (("changed", changed), ("new", [n for n in added if n not in changed]),
                                 ("dropped", dropped)) if v]
        raise KgarmentError(f"{root} holds a sweep with other tasks: {'; '.join(parts)}; use --force to run this "
                            f"sweep there (changed tasks start again, their run folders replaced; dropped tasks' run "
                            f"folders stay in {root / 'runs'}), or give another --out")
    results = {n: r for n, r in old.get("results", {}).items() if n in new and n not in changed}
    runs.update(new)
    folder = SweepFolder(root, runs, list(new), list(sweep.axes),
                         {t.name: dict(t.values) for t in sweep.tasks}, results, frozenset(changed))
    if changed:
        log.warning("tasks whose problem changed start again: %s", ", ".join(changed))
    if write:
        root.mkdir(parents=True, exist_ok=True)
        if not (root / MARKER).is_file():
            mark_folder(root, "sweep")
        write_if_changed(root / COPY, sweep.text)
        for t in sweep.tasks:
            write_if_changed(folder.task_file(t.name), task_file_text(sweep, t))
        folder.save()
    return folder


def task_file_text(sweep, task) -> str:
    """A task's problem file: the base with the task's fields, paths absolute."""
    head = [f"# sweep {sweep.path.name}, task {task.name}: {sweep.base}"]
    head += [f"#   {k} = {json.dumps(v, default=str)}" for k, v in task.values]
    head.append("# [solver] workers = 1: the sweep runs one process per task")
    return "\n".join(head) + "\n" + tomli_w.dumps(task.data)


@contextlib.contextmanager
def locked(root: Path):
    """Hold the sweep folder's lock (one ``kgarment sweep`` at a time per folder)."""
    import fcntl

    root.mkdir(parents=True, exist_ok=True)
    with open(root / LOCK, "a") as f:
        try:
            fcntl.flock(f, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            raise KgarmentError(f"another kgarment sweep is running in {root}; wait for it or stop it") from None
        try:
            yield
        finally:
            fcntl.flock(f, fcntl.LOCK_UN)


def summarise_run(run) -> dict:
    """What the sweep's table needs from a run folder: its status (``run_status``:
    new / unfinished / finished), iterations (metrics rows) and, from the final design's
    evaluation (``final/evaluation.json``): the best iteration, rho ON / OFF per motion
    ({motion: {state: rho}}), the reinforced area share, parts counting clutches as links,
    islands, clutch ends on reinforcement / all, and per motion and clutch the load share,
    needed and tension (N) with all clutches ON."""
    from kgarment.design.run import run_status

    run = Path(run)
    try:
        rec: dict = {"status": run_status(run)}
    except KgarmentError as exc:
        return {"status": "damaged", "error": str(exc)}
    metrics = run / "metrics.json"
    if metrics.is_file():
        with contextlib.suppress(ValueError, OSError):
            rec["iterations"] = len(json.loads(metrics.read_text()))
    path = run / "final" / "evaluation.json"
    if rec["status"] != "finished" or not path.is_file():
        return rec
    try:
        ev = json.loads(path.read_text())
    except (ValueError, OSError):
        return rec
    rec.update(best_iteration=ev.get("iteration"), rho=ev.get("rho", {}), area=ev.get("area"),
               parts=ev.get("islands_with_clutches"), islands=ev.get("islands"),
               ends_supported=ev.get("clutch_ends_supported"), ends=ev.get("clutch_ends"),
               converged=ev.get("converged"),
               clutches=[{k: c.get(k) for k in ("motion", "clutch", "share", "needed", "tension_N", "loaded")}
                         for c in ev.get("clutches", [])])
    return rec


def write_if_changed(path, text: str) -> bool:
    """Write ``text`` to ``path`` (atomically) unless it holds it already; whether it wrote
    (a sweep run again over finished tasks rewrites nothing)."""
    path = Path(path)
    if path.is_file() and path.read_text() == text:
        return False
    atomic_write_text(path, text)
    return True
