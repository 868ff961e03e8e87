"""The design loop's motion start (``[solver] path_start``): the ON states solved over their
motion from rest every few iterations, the end kept where it is clearly lower than the
design loop's equilibrium (README, "Design runs"; the frames as in
:func:`kgarment.design.path.path_forces`)."""

from __future__ import annotations

import logging

import numpy as np

from kgarment.design.path import held_at, predicted
from kgarment.sim import SimState

log = logging.getLogger(__name__)


def motion_ends(setup, design: np.ndarray, keyed, results: list, options) -> tuple[list, int]:
    """Each ON state of ``keyed`` ([(StateKey, SimState)]) solved over its motion from rest:
    the frames of ``setup.path_frames`` (the first from the skin-tight garment, each next one
    where the frames before predict it, :func:`kgarment.design.path.predicted`, and with
    skin friction held where the frame before left it, :func:`kgarment.design.path.held_at`;
    all states' frame i in one batch), then the target state itself from the last frame.
    Its end is kept instead of ``results``' equilibrium (the same order) where converged and
    lower by more than :data:`kgarment.design.evaluate.MULTISTABLE`.  Returns (the results,
    Newton iterations spent)."""
    from kgarment.design.evaluate import Equilibrium, with_known

    todo = [i for i, ((m, s), _) in enumerate(keyed) if s == "on" and m in setup.path_frames]
    if not todo:
        return results, 0
    past: list[list] = [[] for _ in todo]  # per state: the frames' equilibria so far [(x, Motion)]
    last: list = [None for _ in todo]  # per state: (SimState, x) of the frame before
    newton = 0
    n = len(setup.path_frames[keyed[todo[0]][0][0]])  # every motion has as many frames
    for f in range(n + 1):
        states = [st if f == n else SimState.create(
            setup.path_frames[k[0]][f], st.activation, name=f"{st.name}@{f + 1}",
            anchor=held_at(setup.model_of(k[0]), design, b, setup.path_frames[k[0]][f], options))
                  for b, (k, st) in zip(last, (keyed[i] for i in todo))]
        warm = [predicted(setup.model_of(keyed[i][0][0]), p[-2:], st.motion) for i, p, st in zip(todo, past, states)]
        solved = setup.solve(design, states, warm_start=warm, options=options)
        newton += sum(r.convergence.iterations for r in solved)
        for p, st, r in zip(past, states, solved):
            p.append((r.x, st.motion))
        last = [(st, r.x) for st, r in zip(states, solved)]
    out = list(results)
    for i, end in zip(todo, solved):
        if with_known(Equilibrium(out[i]), end).from_path:
            log.info("%s: the motion from rest ends %.4g J below the design loop's equilibrium (%.4g J); "
                     "going on from it", end.name, out[i].total_energy - end.total_energy, out[i].total_energy)
            out[i] = end
    return out, newton
