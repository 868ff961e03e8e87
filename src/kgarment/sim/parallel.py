"""Solving states in worker processes (``SolverOptions.workers > 1``).

The sparse factorisations run one thread each (CHOLMOD through scikit-sparse also holds
the GIL) and the rest of a Newton iteration is Python, so threads would not overlap;
states are independent, so they go to a pool of processes instead.  The pool is created
on first use and kept for the rest of the session.  A task carries the design, the warm
start, and the model and the state -- unless its workers inherited them: the objects of
the call that creates a forked pool are registered (under a token each) before the
workers fork, so those tasks carry only the tokens.  Measured at subdivision 0: the model
(3.3 MB pickled) and a state with its posed body (2.7 MB) cost 70 ms per 6-state call
(empty tasks 1 ms), against ~1 s of warm solves; a design run creates the pool with its
own model and states, so each of its iterations saves most of that (35 ms per call at
subdivision 0, 150 ms at 1).  The registered objects stay alive as long as the pool.
Results come back in the order of the states.  Tasks are submitted longest first (by the
Newton iterations the same state name took in the last call, a longest-processing-time
schedule): with 6 states on 2 workers, a long state submitted last would leave one worker
idle.  Each task is independent, so the order does not change any result.  Workers are
forked (POSIX): "spawn" would re-run an unguarded calling script in every worker.  The
exception is a parent that has itself run a CHOLMOD supernodal factorisation
(``factorization="supernodal"``): it runs GNU OpenMP regions, and a forked child of such
a process hangs in its first own region (measured), so that parent's pool uses
"forkserver" (whose workers inherit nothing).  So does a pool created from a thread other
than the main one (the studio's jobs, beside its server's and the browser's threads): a
fork copies whatever locks those threads hold at that moment, and a worker that waits on
one never takes a task (seen: the studio's force over the motion, then a process that
hung at exit waiting for its workers).  MKL PARDISO runs sequentially
(``pardiso``), so forking after it is safe.  Workers run torch and BLAS single-threaded and
ignore Ctrl-C (the main process handles it).
"""

from __future__ import annotations

import atexit
import multiprocessing as mp
import os
import signal
import threading
import time
from concurrent.futures import ProcessPoolExecutor
from dataclasses import replace

from kgarment.sim.assembly import SparseCholesky
from kgarment.sim.serial import blas_threads, solve_serial

_POOLS: dict[int, ProcessPoolExecutor] = {}
_REGISTRY: dict[int, object] = {}  # token -> object, registered before a pool forks (its workers hold a copy)
_INHERITED: dict[int, frozenset[int]] = {}  # pool (workers) -> the tokens its workers inherited
_LAST_ITERATIONS: dict[str, int] = {}  # state name -> Newton iterations in the last solve (scheduling only)


def _pool(workers: int, objects=()) -> ProcessPoolExecutor:
    """The pool of ``workers`` processes; a new forked one inherits ``objects`` (models and
    states, see the module doc)."""
    pool = _POOLS.get(workers)
    if pool is None:
        methods = mp.get_all_start_methods()
        method = "fork" if "fork" in methods else "spawn"
        threaded = threading.current_thread() is not threading.main_thread()
        if (SparseCholesky.openmp_used or threaded) and "forkserver" in methods:
            method = "forkserver"  # a fork would inherit OpenMP's threads, or other threads' locks, as dead
        if method == "fork":  # every worker forks at the first submit, after this (concurrent.futures)
            _REGISTRY.update((id(obj), obj) for obj in objects)  # held for the pool's life: the ids stay theirs
        pool = ProcessPoolExecutor(max_workers=workers, mp_context=mp.get_context(method), initializer=_init_worker)
        _POOLS[workers] = pool
        _INHERITED[workers] = frozenset(_REGISTRY) if method == "fork" else frozenset()  # a fork copies all
    return pool


def _ref(obj, workers: int) -> tuple[int, object]:
    """(token, the object, or None where the pool's workers inherited it)."""
    return (id(obj), None) if id(obj) in _INHERITED.get(workers, ()) else (id(obj), obj)


def _resolve(ref):
    token, obj = ref
    return _REGISTRY[token] if obj is None else obj


def _init_worker() -> None:
    """Workers leave Ctrl-C to the main process (which stops them): a worker interrupted
    mid-task would leave the pool's shutdown waiting for it forever.  They run BLAS on one
    thread for good (``solve.blas_threads``: OpenBLAS's spinning idle threads would take
    the other workers' cores)."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    blas_threads(1)
    threading.Thread(target=_watch_parent, args=(os.getppid(),), daemon=True, name="kgarment-parent-watch").start()


PARENT_POLL = 0.5  # seconds between a worker's checks that its parent still lives


def _watch_parent(parent: int) -> None:
    """End this worker when the process that started it is gone (killed with SIGKILL, say:
    no atexit runs then, and the orphan would hold its memory and a core).  The worker's
    parent is the main process, or with "forkserver" the fork server, which exits when
    the main process does.  A thread polling ``getppid`` rather than Linux's parent-death
    signal: that signal fires when the *thread* that forked the worker ends, and pools are
    also started from the studio's job threads."""
    while os.getppid() == parent:
        time.sleep(PARENT_POLL)
    os._exit(1)


@atexit.register
def shutdown() -> None:
    """Stop the worker processes (also done at interpreter exit)."""
    for pool in _POOLS.values():
        pool.shutdown(wait=False, cancel_futures=True)
    _POOLS.clear()
    _INHERITED.clear()
    _REGISTRY.clear()


def _task(model, design, state, warm, options):
    return solve_serial(_resolve(model), design, [_resolve(state)], [warm], options)[0]


def solve_parallel(models, design, states, warm, options) -> list:
    """One task per state on ``options.workers`` processes (each single-process); models :
    the SimModel of each state."""
    sub = replace(options, workers=1)
    pool = _pool(options.workers, list({id(m): m for m in models}.values()) + list(states))
    order = sorted(range(len(states)), key=lambda i: -_LAST_ITERATIONS.get(states[i].name, 0))
    futures = {i: pool.submit(_task, _ref(models[i], options.workers), design, _ref(states[i], options.workers),
                              warm[i], sub) for i in order}
    results = [futures[i].result() for i in range(len(states))]
    for s, r in zip(states, results):
        _LAST_ITERATIONS[s.name] = r.convergence.iterations
    return results
