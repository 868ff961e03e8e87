"""The design loop's motion start (``[solver] path_start``): every few iterations the ON states
are solved over their motion from rest **as the evaluator solves them**, and the loop goes on
from that end where it is clearly lower (README, "Design runs").

The check is :func:`kgarment.evaluate.path.path_forces` itself, ON states only: the design's
rest equilibrium from the evaluator's starts, :data:`~kgarment.constants.PATH_FRAMES` frames
each predicted from the ones before, skin friction holding each frame where the one before
left the garment, the evaluator's two starts where a frame does not converge, all at the
evaluator's tolerance (``min(tol, EVALUATION_TOL)``): a cheaper check does not find what the
evaluator finds.
"""

from __future__ import annotations

import dataclasses
import logging

import numpy as np

from kgarment.constants import EVALUATION_TOL

log = logging.getLogger(__name__)


def motion_ends(setup, design: np.ndarray, keyed, results: list, starts: list | None = None
                ) -> tuple[list, list[str]]:
    """Each ON state of ``keyed`` ([(StateKey, SimState)]) of a motion with frames in
    ``setup.beso.path_frames`` solved over its motion from rest as the evaluator does (module doc).

    With ``starts`` (per state, the better of this iteration's solves from the evaluator's two
    starts; ``skin_start``) the state becomes what the evaluator reports: the lower of those
    and the motion's end (:func:`kgarment.case.starts.with_known`), not an equilibrium
    only the loop's continuation from the iterations before reaches, higher or lower.  Without, the end replaces ``results``' equilibrium (the same
    order) where it is converged and lower by more than MULTISTABLE.  Returns (the results,
    the motions whose ON state changed by more than MULTISTABLE)."""
    from kgarment.case.starts import Equilibrium, pick_equilibrium, with_known
    from kgarment.evaluate.evaluator import Evaluator
    from kgarment.evaluate.path import path_forces

    _, index = setup.beso.path_frames
    framed = {m for _, m, _ in index}
    motions = list(dict.fromkeys(m for (m, s), _ in keyed if s == "on" and m in framed))
    if not motions:
        return results, []
    tight = dataclasses.replace(setup.case.solver, tol=min(setup.case.solver.tol, EVALUATION_TOL))
    evaluator = Evaluator(dataclasses.replace(setup.case, solver=tight))
    frames = sum(1 for _, m, _ in index if m == motions[0])
    report = path_forces(evaluator, design, None, motions, frames, kinds=("on",), framed=setup.beso.path_frames)
    out, moved = list(results), []
    for i, ((m, s), st) in enumerate(keyed):
        end = report.ends.get((m, s)) if s == "on" else None
        if end is None:
            continue
        end = dataclasses.replace(end, name=st.name)
        if starts is not None:
            new = with_known(Equilibrium(starts[i]), end).result
            if pick_equilibrium(out[i], new).other is None and out[i].converged == new.converged:
                continue  # the same equilibrium (within MULTISTABLE)
        elif with_known(Equilibrium(out[i]), end).from_path:
            new = end
        else:
            continue
        log.info("%s: the evaluator's equilibrium (the motion from rest or its two starts) stores %.4g J, the "
                 "design loop's %.4g J; going on from it", st.name, new.total_energy, out[i].total_energy)
        out[i] = new
        moved.append(m)
    return out, moved
