"""Switching a state's clutches on in steps: for states whose stiff ON clutches make the
direct solve slow (a garment sliding a long way before it settles).  Used by the evaluator
(:mod:`kgarment.evaluate.evaluator`, a state converged from neither start) and by the per-clutch
loads (:mod:`kgarment.evaluate.loads`, a load state still sliding after going on).
"""

from __future__ import annotations

import dataclasses
import logging

import numpy as np

from kgarment.case.keys import fraction_name
from kgarment.case.setup import Case
from kgarment.sim import SimState, SolverOptions, StateResult

log = logging.getLogger(__name__)
CONTINUATION = (0.0, 0.25, 0.5, 0.75, 1.0)  # the activation's steps, as shares of the state's


def activation_continuation(case: Case, design: np.ndarray, states: list[SimState],
                            offs: list[StateResult | None] | None = None,
                            options: SolverOptions | None = None) -> list[StateResult]:
    """Solve ``states`` for ``design`` (m,) by switching their clutches on in steps: each
    state's equilibrium with the clutches off (from the skin-tight start), then activations
    ``CONTINUATION`` times the state's, each from the previous equilibrium.  Returns per
    state the last step's StateResult (named as the state; iterations and time of all steps
    added up).

    The states take each step together, one batch of solves per step (the workers share
    them).  ``offs``: per state its motion's clutches-off equilibrium from the skin-tight start
    where it is already solved (None: solve it): the same solve as the first step, so it is
    not repeated.  ``options``: the case's solver options unless given.

    For states whose stiff ON clutches make the direct solve slow: on the long sleeve's
    bend-forward state (preview resolution, its iteration-117 design) the direct cold
    solve did not converge in 400 iterations; off, then 0.25, 0.5, 0.75, 1 converged in
    125 + 143 + 52 + 66 + 34 iterations, at a lower energy (5.96 J against 6.06 J).
    """
    states = list(states)
    offs = list(offs) if offs is not None else [None] * len(states)
    for s in states:
        log.info("state %s: switching the clutches on in steps %s", s.name, CONTINUATION)
    xs: list = [None] * len(states)
    last: list = [None] * len(states)
    iters, secs = [0] * len(states), [0.0] * len(states)
    for k, f in enumerate(CONTINUATION):
        todo = [i for i in range(len(states)) if not (k == 0 and offs[i] is not None)]
        steps = [states[i] if f == 1.0 else SimState.create(
            states[i].motion, f * np.asarray(states[i].activation, dtype=np.float64), name=fraction_name(states[i].name, f))
            for i in todo]
        done = dict(zip(todo, case.solve(design, steps, warm_start=[xs[i] for i in todo], options=options))) \
            if todo else {}
        for i in range(len(states)):
            r = done.get(i, offs[i] if k == 0 else None)
            iters[i] += r.convergence.iterations
            secs[i] += r.convergence.wall_time
            if not r.converged and k < len(CONTINUATION) - 1:
                log.info("state %s: step %g did not converge (residual %.3g); going on", states[i].name, f,
                         r.convergence.residual)
            xs[i], last[i] = r.x, r
    return [dataclasses.replace(r, convergence=dataclasses.replace(r.convergence, iterations=n, wall_time=t))
            for r, n, t in zip(last, iters, secs)]
