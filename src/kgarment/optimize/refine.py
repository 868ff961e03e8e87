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

import numpy as np

from kgarment.case.keys import Start, is_started
from kgarment.case.levels import parent_faces, vertex_map
from kgarment.case.values import design_values
from kgarment.optimize.loop import LoopState
from kgarment.optimize.setup import DesignSetup
from kgarment.problem import Problem


def coarse_levels(problem: Problem) -> tuple[int, ...]:
    """The problem's coarse levels below its garment's level (others are ignored, so that
    ``--subdivision 0`` on a coarse-to-fine problem is a plain design)."""
    return tuple(level for level in problem.design.levels if level < problem.garment.subdivision)


def transfer(coarse_setup: DesignSetup, coarse: LoopState, fine_setup: DesignSetup, fine: LoopState) -> LoopState:
    """``fine`` (after its iteration 0) going on from ``coarse``: design, target, filtered
    sensitivities and warm starts mapped to the fine level (module docstring); the fine
    run's references, records and objectives are kept (convergence is judged anew)."""
    cm, fm = coarse_setup.case.model, fine_setup.case.model
    parent = parent_faces(fm.n_faces, cm.n_faces)
    S = vertex_map(cm.garment_faces, cm.n_garment, fm.n_faces)
    warm = dict(fine.warm)
    for name, x in coarse.warm.items():
        if name in warm and not is_started(name, Start.FULL):  # the same state at both levels (the fully
            # reinforced garment's equilibria, a skin_start run's FULL starts, are the fine level's own)
            warm[name] = fm.initial_positions(S @ np.asarray(x)[: cm.n_garment])
    alpha = None if coarse.alpha_prev is None else np.asarray(coarse.alpha_prev)[parent]
    design = design_values(np.asarray(coarse.design)[parent] > 0.5)
    if fine_setup.beso.protected is not None:
        design[fine_setup.beso.protected] = 1.0
    guarded = None if coarse.guarded is None else np.asarray(coarse.guarded)[parent]
    return dataclasses.replace(fine, design=design, target=coarse.target, alpha_prev=alpha, warm=warm,
                               guarded=guarded)
