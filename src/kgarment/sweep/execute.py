"""Running a sweep's tasks on Ray.

Every task is an ordinary design run (:func:`kgarment.design.open_run` /
:func:`kgarment.design.finish`) into ``DIR/runs/NAME``, in one Ray task that takes one CPU
and solves in one process on one thread (``[solver] workers = 1``; torch and BLAS held to
one thread), as the design's worker processes do.  A finished run is skipped, an
unfinished one resumed (its checkpoint), a new one started; a task whose problem changed
(``--force``) starts again.  A task that fails (a user error, or anything else) records
its error and the sweep goes on.  Ctrl-C cancels the tasks and shuts Ray down: finished
runs stay as they are, unfinished ones resume next time.

Ray: a local cluster by default (``address="local"``, ``num_cpus`` = workers) whose
servers listen on 127.0.0.1 only, no dashboard, quiet logs; or an existing cluster by
address.  Tasks return what the table needs (:func:`kgarment.sweep.folder.summarise_run`),
so the table is complete even where the run folders stay on the nodes that ran them.
"""

from __future__ import annotations

import contextlib
import copy
import logging
import os
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

from kgarment.errors import KgarmentError
from kgarment.sweep.folder import SweepFolder, locked, open_folder, summarise_run, write_if_changed
from kgarment.sweep.plot import sweep_plot
from kgarment.sweep.table import csv_text, markdown_text

log = logging.getLogger(__name__)
# every task on one thread: read by OpenMP, MKL, OpenBLAS and numba when a worker starts
THREAD_ENV = {"OMP_NUM_THREADS": "1", "MKL_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1", "NUMBA_NUM_THREADS": "1"}
# Ray takes the machine's address for a local node unless it runs "without clusters" (as
# on macOS and Windows): then its servers listen on 127.0.0.1 only
LOOPBACK = {"RAY_ENABLE_WINDOWS_OR_OSX_CLUSTER": "0", "RAY_USAGE_STATS_ENABLED": "0"}
INSTALL = "pip install 'kgarment[sweep]' (or pip install 'ray>=2.40')"
POLL_S = 1.0  # s between the driver's looks at the tasks


@dataclass
class SweepProgress:
    """What the sweep has done so far: tasks in all, finished (skipped ones included),
    failed, and the running ones' iterations done (name -> count; 0 when just started)."""

    total: int
    finished: int = 0
    failed: int = 0
    running: dict = field(default_factory=dict)


@dataclass
class SweepOutcome:
    """A sweep's end: the folder (records per task), which tasks ran, were skipped and
    failed, and the table and plot files."""

    folder: SweepFolder
    ran: list
    skipped: list
    failed: list
    paths: list


def import_ray():
    """The ray module, or one KgarmentError saying how to install it."""
    try:
        import ray
    except ImportError:
        raise KgarmentError(f"kgarment sweep runs its tasks on Ray, which is not installed: {INSTALL}") from None
    return ray


def run_sweep(sweep, out, *, workers: int | None = None, address: str | None = None, force: bool = False,
              progress: Callable[[SweepProgress], None] | None = None) -> SweepOutcome:
    """Run every task of ``sweep`` (:class:`kgarment.sweep.spec.Sweep`) that has not
    finished into ``out`` and write the table and plots.  ``workers``: the local cluster's
    CPUs (default: the machine's cores); ``address``: an existing Ray cluster instead.
    ``progress(SweepProgress)`` after every change.  Raises KeyboardInterrupt after
    Ctrl-C (tables written, Ray shut down)."""
    root = Path(out).resolve()
    open_folder(sweep, root, force, write=False)  # refusals before the lock and before Ray
    with locked(root):
        folder = open_folder(sweep, root, force)
        todo, skipped = [], []
        for t in sweep.tasks:
            if t.name not in folder.replace and _status(folder.run(t.name)) == "finished":
                skipped.append(t.name)
                rec = folder.results.get(t.name, {})
                if rec.get("status") != "finished":  # e.g. a run finished by hand: read it
                    folder.record(t.name, {**summarise_run(folder.run(t.name)), "wall_s": rec.get("wall_s")})
            else:
                todo.append(t)
                folder.results.pop(t.name, None)  # recorded again when it ends
        state = SweepProgress(len(sweep.tasks), finished=len(skipped))
        if progress is not None:
            progress(state)
        try:
            if todo:
                ray = import_ray()
                with ray_cluster(ray, workers, address):
                    _execute(ray, folder, todo, state, progress, address, sweep.base_dir)
        finally:
            for name in folder.tasks:  # what an interrupted or failed task left
                if name not in folder.results:
                    folder.record(name, summarise_run(folder.run(name)))
            paths = write_outputs(folder, sweep)
    ran = [t.name for t in todo]
    failed = [n for n in folder.tasks if folder.results.get(n, {}).get("status") == "failed"]
    return SweepOutcome(folder, ran, skipped, failed, paths)


def _status(run: Path) -> str:
    from kgarment.design.run import run_status

    try:
        return run_status(run)
    except KgarmentError:
        return "damaged"  # the task says what (its record's error)


@contextlib.contextmanager
def ray_cluster(ray, workers: int | None, address: str | None):
    """Ray started (a local cluster: loopback only, ``workers`` CPUs) or connected (an
    existing cluster at ``address``) for the block, shut down after it."""
    saved = {k: os.environ.get(k) for k in {**LOOPBACK, **THREAD_ENV}}
    constants = ray._private.ray_constants
    saved_flag = getattr(constants, "ENABLE_RAY_CLUSTER", None)
    kw = {"include_dashboard": False, "log_to_driver": False, "logging_level": logging.ERROR}
    try:
        if address is None:  # the local workers inherit the environment (a runtime_env would start others)
            os.environ.update({**LOOPBACK, **THREAD_ENV})
            constants.ENABLE_RAY_CLUSTER = False  # read when the node's address is chosen
            try:
                ray.init(address="local", num_cpus=workers or os.cpu_count() or 1, **kw)
            except (ConnectionError, RuntimeError, OSError) as exc:
                raise KgarmentError(f"Ray's local cluster did not start ({str(exc).splitlines()[0]}); see "
                                    "/tmp/ray/session_latest/logs") from None
            ip = ray.util.get_node_ip_address()
            if ip not in ("127.0.0.1", "::1", "localhost"):
                raise KgarmentError(f"Ray's local cluster took the address {ip}, not 127.0.0.1; kgarment starts no "
                                    "server on other addresses: start a cluster yourself and give --address")
        else:
            os.environ.setdefault("RAY_USAGE_STATS_ENABLED", "0")
            try:
                ray.init(address=address, runtime_env={"env_vars": dict(THREAD_ENV)}, **kw)
            except (ConnectionError, ValueError, RuntimeError) as exc:
                raise KgarmentError(f"--address {address}: cannot connect to a Ray cluster there "
                                    f"({str(exc).splitlines()[0]})") from None
        yield ray
    finally:
        with contextlib.suppress(Exception):  # also after a Ctrl-C while Ray was starting
            ray.shutdown()
        if saved_flag is not None:
            constants.ENABLE_RAY_CLUSTER = saved_flag
        for k, v in saved.items():
            if v is None:
                os.environ.pop(k, None)
            else:
                os.environ[k] = v


def _execute(ray, folder: SweepFolder, tasks, state: SweepProgress, progress, address, base_dir: Path) -> None:
    """Submit ``tasks``, record each as it ends, report progress; Ctrl-C cancels them."""
    if address is not None:
        log.warning("tasks run on the Ray cluster at %s and write their run folders under %s on the node that runs "
                    "each: put that folder on storage every node shares to have them all there (the table is made "
                    "from what the tasks return either way)", address, folder.root)
    cpus = int(ray.cluster_resources().get("CPU", 1))
    log.info("%d tasks on Ray (%d CPUs), one CPU each; run folders in %s", len(tasks), cpus, folder.root / "runs")
    queue = ray.remote(num_cpus=0)(Reports).remote()
    remote = ray.remote(num_cpus=1, max_retries=0)(run_task)
    refs = {remote.remote(_job(folder, t, base_dir), queue): t.name for t in tasks}
    started = {}
    pending = list(refs)
    try:
        while pending:
            ready, pending = ray.wait(pending, num_returns=1, timeout=POLL_S)
            for name, kind, value in _drain(queue):
                if kind == "start":
                    started[name] = time.time()
                    state.running[name] = 0
                elif kind == "iteration" and name in state.running:
                    state.running[name] = value
            for ref in ready:
                name = refs[ref]
                rec = _result(ray, ref, name, started.get(name))
                folder.record(name, rec)
                state.running.pop(name, None)
                if rec["status"] == "finished":
                    state.finished += 1
                else:
                    state.failed += 1
                    log.warning("task %s: %s", name, rec.get("error") or rec["status"])
            if progress is not None:
                progress(state)
    except BaseException:
        for ref in pending:
            with contextlib.suppress(Exception):
                ray.cancel(ref, force=True)
        raise


class Reports:
    """A Ray actor holding the tasks' reports ((task, "start" | "iteration", value), ...)
    until the driver takes them: one call each way, nothing waits."""

    def __init__(self) -> None:
        self.items: list = []

    def put(self, item) -> None:
        self.items.append(item)

    def take(self) -> list:
        out, self.items = self.items, []
        return out


def _drain(queue) -> list:
    import ray

    with contextlib.suppress(Exception):
        return ray.get(queue.take.remote(), timeout=10)
    return []


def _result(ray, ref, name: str, t0: float | None) -> dict:
    """A task's record; a task that died (its worker killed, out of memory) -> failed."""
    try:
        return ray.get(ref)
    except ray.exceptions.RayError as exc:
        text = next((line for line in str(exc).splitlines() if line.strip()), type(exc).__name__)
        return {"status": "failed", "error": f"{type(exc).__name__}: {text}",
                "wall_s": None if t0 is None else time.time() - t0}


def _job(folder: SweepFolder, task, base_dir: Path) -> dict:
    return {"name": task.name, "run": str(folder.run(task.name)), "data": task.data,
            "base_dir": str(base_dir), "source": str(folder.task_file(task.name)),
            "log": str(folder.log(task.name)), "replace": task.name in folder.replace}


def write_outputs(folder: SweepFolder, sweep) -> list[Path]:
    """sweep.csv, sweep.md and sweep.png, each written only when its content changed."""
    title = f"sweep {sweep.path.name}: {sweep.base}"
    root = folder.root
    changed = write_if_changed(root / "sweep.csv", csv_text(folder))
    write_if_changed(root / "sweep.md", markdown_text(folder, title))
    png = root / "sweep.png"
    if changed or not png.is_file():
        sweep_plot(folder, png, title)
    return [p for p in (root / "sweep.csv", root / "sweep.md", png) if p.is_file()]


# ---- in the Ray worker ---------------------------------------------------------------

def run_task(job: dict, queue=None) -> dict:
    """One task in a Ray worker: the run folder ``job["run"]`` finished (skipped when it
    already is, resumed when unfinished), logged to ``job["log"]``, on one thread.
    Returns its record (:func:`summarise_run` + ``wall_s``; ``status`` "failed" and
    ``error`` when it failed)."""
    t0 = time.time()
    logger = logging.getLogger("kgarment")
    Path(job["log"]).parent.mkdir(parents=True, exist_ok=True)
    handler = logging.FileHandler(job["log"])
    handler.setFormatter(logging.Formatter("%(asctime)s %(levelname)s %(name)s: %(message)s"))
    level = logger.level
    logger.addHandler(handler)
    logger.setLevel(logging.INFO)

    def report(kind: str, value=None) -> None:
        # fire and forget: a task blocked in ray.get lends its CPU to another task
        if queue is not None:
            with contextlib.suppress(Exception):
                queue.put.remote((job["name"], kind, value))

    try:
        with single_thread() as threads:
            log.info("task %s: process %d on %s; torch threads %d, %s", job["name"], os.getpid(), os.uname().nodename,
                     threads, ", ".join(f"{k} {os.environ.get(k)}" for k in THREAD_ENV))
            _run(job, report)
        rec = summarise_run(job["run"])
        if rec["status"] != "finished":
            rec.update(status="failed", error=f"the run stopped as {rec['status']}")
    except KgarmentError as exc:
        log.error("task %s: %s", job["name"], exc)
        rec = {**_partial(job["run"]), "status": "failed", "error": str(exc)}
    except Exception as exc:  # a bug: recorded, the sweep goes on; the traceback is in the log
        log.exception("task %s failed", job["name"])
        rec = {**_partial(job["run"]), "status": "failed",
               "error": f"{type(exc).__name__}: {exc} (traceback in {job['log']})".replace("\n", " ")}
    finally:
        logger.removeHandler(handler)
        logger.setLevel(level)
        handler.close()
    rec["wall_s"] = time.time() - t0
    return rec


def _partial(run) -> dict:
    with contextlib.suppress(Exception):
        return summarise_run(run)
    return {}


def _run(job: dict, report) -> None:
    from kgarment.design import finish, open_run, run_status
    from kgarment.problem import parse_problem

    run = Path(job["run"])
    status = run_status(run)
    report("start", status)
    if status == "finished" and not job["replace"]:
        log.info("task %s: %s is finished", job["name"], run)
        return
    if status == "unfinished" and not job["replace"]:
        log.info("task %s: resuming %s", job["name"], run)
        dr = open_run(None, run, resume=True)
    else:
        log.info("task %s: a new run in %s", job["name"], run)
        problem = parse_problem(copy.deepcopy(job["data"]), Path(job["base_dir"]), Path(job["source"]))
        dr = open_run(problem, run, force=run.exists())
    report("iteration", len(dr.state.metrics))
    finish(dr, progress=lambda st: report("iteration", len(st.metrics)))


@contextlib.contextmanager
def single_thread():
    """torch and BLAS on one thread for the block (restored after)."""
    import torch
    from threadpoolctl import threadpool_limits

    saved = torch.get_num_threads()
    torch.set_num_threads(1)
    try:
        with threadpool_limits(limits=1):
            yield torch.get_num_threads()
    finally:
        torch.set_num_threads(saved)
