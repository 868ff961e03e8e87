"""The coarse levels of a coarse-to-fine design run, each an ordinary run folder
``RUN/level<L>`` (:mod:`kgarment.optimize.refine` for the method)."""

from __future__ import annotations

import dataclasses
import logging
from collections.abc import Callable
from pathlib import Path

from kgarment.case.levels import level_problem
from kgarment.design.run import load_checkpoint, run_status, save_checkpoint
from kgarment.errors import Cancelled
from kgarment.optimize.loop import LoopState, iterate
from kgarment.optimize.refine import coarse_levels, transfer
from kgarment.optimize.setup import DesignSetup
from kgarment.problem import Problem

log = logging.getLogger(__name__)


def run_coarse(run: Path, problem: Problem, open_level: Callable, progress: Callable | None = None,
               cancelled: Callable[[], bool] | None = None,
               first: Callable | None = None) -> tuple[DesignSetup, LoopState]:
    """Run (or resume, or reuse) every coarse level of ``problem`` in ``run / "level<L>"``;
    returns the last level's setup and state.  ``open_level(problem, folder, resume)`` opens
    a level's run (:func:`kgarment.design.driver.open_run`); ``first(level_run, state)``
    after the coarsest level's iteration 0 (the control screen)."""
    prev = None
    for i, level in enumerate(coarse_levels(problem)):
        folder = run / f"level{level}"
        status = run_status(folder)
        dr = open_level(level_problem(problem, level), folder, status != "new")
        st, p = dr.state, dr.setup.beso.params
        if status == "new":
            st = iterate(dr.setup, st)  # its own iteration 0 (the references at this level)
            if prev is None and first is not None:
                first(dr, st)
            if prev is not None:
                st = transfer(prev[0], prev[1], dr.setup, st)
            save_checkpoint(folder, st)
        at_target = 0 if i == 0 else p.window  # further levels adapt the design for a window
        while not _coarse_done(st, p, at_target):
            st = iterate(dr.setup, st)
            save_checkpoint(folder, st)
            row = st.metrics[-1]
            log.info("level %d iteration %d: area %.1f%%, objective %.4f, %.1f s", level, row["iteration"],
                     100 * row["area"], row["objective"], row["seconds"])
            if progress is not None:
                progress(st)
            if cancelled is not None and cancelled():
                raise Cancelled()
        if not st.done:
            save_checkpoint(folder, dataclasses.replace(st, done=True))
        log.info("level %d: %d iterations, target %.3f reached", level, st.iteration, st.target)
        prev = (dr.setup, load_checkpoint(folder))
    return prev


def _coarse_done(st: LoopState, p, at_target: int) -> bool:
    """A coarse level is done when its run is, or once ``at_target`` iterations beyond the
    first one at the target area have run."""
    if st.done:
        return True
    reached = [i for i, row in enumerate(st.metrics) if p.reached(row["area"])]
    return bool(reached) and len(st.metrics) - reached[0] > at_target
