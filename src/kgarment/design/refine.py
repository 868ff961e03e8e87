"""Coarse-to-fine design: evolve at a coarse subdivision level, finish at the garment's.

The first hundred BESO iterations only rank sensitivities while the target area shrinks
from 100% to A*; a coarse mesh ranks them as well, at a fraction of the cost.  With
``[design] levels = [0]`` on a subdivision-1 garment, a run

1. designs at level 0 in its own run folder ``RUN/level0`` until the target area is reached
   (an ordinary, resumable run; each further coarse level starts from the one before and
   runs ``window`` iterations at A*);
2. solves iteration 0 at the garment's level (the fully reinforced garment: the
   references of rho and of the objective at this level), then
3. goes on from the coarse run's state, transferred through the subdivision's exact
   parent-child maps: the design and the filtered sensitivities (the history) face to face
   (midpoint subdivision splits a face into four children of a quarter of its area, in
   blocks, so child ``c`` of a level with ``m`` faces has parent ``c mod m`` and the
   reinforced area share is kept exactly), the target area, and every state's equilibrium
   as its warm start (garment vertices by the subdivision's vertex map -- old vertices,
   then edge midpoints -- and the clutches bound to the refined garment again);
4. runs to convergence at the garment's level, where convergence is judged; the run folder
   is an ordinary run at that level (its iteration 1 is the transferred design).
"""

from __future__ import annotations

import dataclasses
import logging
from collections.abc import Callable
from pathlib import Path

import numpy as np

from kgarment.design.beso import design_values
from kgarment.design.levels import level_problem, parent_faces, vertex_map
from kgarment.design.loop import FULL, LoopState, iterate
from kgarment.design.run import load_checkpoint, run_status, save_checkpoint
from kgarment.design.setup import DesignSetup
from kgarment.errors import Cancelled
from kgarment.problem import Problem

log = logging.getLogger(__name__)


def coarse_levels(problem: Problem) -> tuple[int, ...]:
    """The problem's coarse levels below its garment's level (others are ignored, so that
    ``--subdivision 0`` on a coarse-to-fine problem is a plain design)."""
    return tuple(level for level in problem.design.levels if level < problem.garment.subdivision)


def transfer(coarse_setup: DesignSetup, coarse: LoopState, fine_setup: DesignSetup, fine: LoopState) -> LoopState:
    """``fine`` (after its iteration 0) going on from ``coarse``: design, target, filtered
    sensitivities and warm starts mapped to the fine level (module docstring); the fine
    run's references, records and objectives are kept (convergence is judged anew)."""
    cm, fm = coarse_setup.model, fine_setup.model
    parent = parent_faces(fm.n_faces, cm.n_faces)
    S = vertex_map(cm.garment_faces, cm.n_garment, fm.n_faces)
    warm = dict(fine.warm)
    for name, x in coarse.warm.items():
        if name in warm and not name.endswith(FULL):  # the same state at both levels (the fully
            # reinforced garment's equilibria, a skin_start run's FULL starts, are the fine level's own)
            warm[name] = fm.initial_positions(S @ np.asarray(x)[: cm.n_garment])
    alpha = None if coarse.alpha_prev is None else np.asarray(coarse.alpha_prev)[parent]
    design = design_values(np.asarray(coarse.design)[parent] > 0.5)
    if fine_setup.protected is not None:
        design[fine_setup.protected] = 1.0
    guarded = None if coarse.guarded is None else np.asarray(coarse.guarded)[parent]
    return dataclasses.replace(fine, design=design, target=coarse.target, alpha_prev=alpha, warm=warm,
                               guarded=guarded)


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
        st, p = dr.state, dr.setup.params
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
