"""Batched quasi-static solves over states (motion x activation pattern): in this process
(:mod:`kgarment.sim.serial`) or in worker processes (:mod:`kgarment.sim.parallel`)."""

from __future__ import annotations

import logging
from collections.abc import Mapping, Sequence

import numpy as np
import torch

from kgarment.sim.energy import SimulationError
from kgarment.sim.model import SimModel, SimState
from kgarment.sim.options import SolverOptions
from kgarment.sim.parallel import solve_parallel
from kgarment.sim.serial import StateResult, blas_threads, held_after, prepare_state, solve_serial

__all__ = ["ConvergenceError", "StateResult", "blas_threads", "evaluate_state", "held_after", "prepare_state",
           "solve_states"]

log = logging.getLogger(__name__)


class ConvergenceError(SimulationError):
    """Raised (with ``on_fail="raise"``) when states did not converge; ``.states`` names them."""

    def __init__(self, message: str, states: list[str]):
        super().__init__(message)
        self.states = states


def _warm(warm_start, states: Sequence[SimState], sizes: Sequence[int]) -> list[np.ndarray | None]:
    if warm_start is None:
        return [None] * len(states)
    if isinstance(warm_start, Mapping):
        got = [warm_start.get(s.name) for s in states]
    else:
        got = list(warm_start)
        if len(got) != len(states):
            raise ValueError(f"warm_start has {len(got)} entries for {len(states)} states")
    out = []
    for s, w, n in zip(states, got, sizes):
        if isinstance(w, StateResult):
            w = w.x
        if w is not None:
            w = np.asarray(w, dtype=np.float64)
            if w.shape != (n, 3):
                raise ValueError(f"warm start for state {s.name!r} must have shape ({n}, 3)")
        out.append(w)
    return out


def solve_states(model: SimModel | Sequence[SimModel], design: np.ndarray, states: Sequence[SimState],
                 warm_start: Sequence | Mapping | None = None,
                 options: SolverOptions | None = None) -> list[StateResult]:
    """Equilibrium of every state under one design.

    model : SimModel, or one per state (the garments of one design on several bodies: same
    faces, other rest shapes);  design : (m,) per garment face in [x_min, 1];  states : SimState list
    (each a motion + activation (K,));  warm_start : per state (N, 3) positions or
    StateResult or None -- a sequence aligned with ``states`` or a mapping by state name;
    states without one start from the motion's skin-tight garment with bound clutches.
    Returns one StateResult per state, in order.  Non-converged states are logged by name
    with their force norm (and raise ConvergenceError with ``on_fail="raise"``); a
    non-finite energy raises SimulationError naming the state and the term.
    """
    options = options or SolverOptions()
    names = [s.name for s in states]
    if len(set(names)) != len(names):
        raise ValueError("state names must be unique")
    models = list(model) if isinstance(model, Sequence) else [model] * len(states)
    if len(models) != len(states):
        raise ValueError(f"{len(models)} models for {len(states)} states")
    warm = _warm(warm_start, states, [m.n_vertices for m in models])
    saved_threads = torch.get_num_threads()
    if options.threads is not None:
        torch.set_num_threads(options.threads)
    try:
        with blas_threads(options.threads):
            if options.workers > 1 and len(states) > 1:
                results = solve_parallel(models, design, states, warm, options)
                for r in results:
                    log.info("state %s: %s in %d iterations, %.3f s (worker)", r.name,
                             "converged" if r.converged else "NOT converged", r.convergence.iterations,
                             r.convergence.wall_time)
            else:
                results = _serial(models, design, states, warm, options)
    finally:
        torch.set_num_threads(saved_threads)
    _report(results, options)
    return results


def _serial(models: list[SimModel], design, states, warm, options) -> list[StateResult]:
    """:func:`solve_serial` over runs of consecutive states that share a model."""
    out, i = [], 0
    while i < len(states):
        j = i + 1
        while j < len(states) and models[j] is models[i]:
            j += 1
        out += solve_serial(models[i], design, states[i:j], warm[i:j], options)
        i = j
    return out


def _report(results: list[StateResult], options: SolverOptions) -> None:
    failed = [r for r in results if not r.converged]
    if failed:
        msg = "; ".join(f"{r.name}: residual {r.convergence.residual:.3g} > {r.convergence.tolerance:.3g} "
                        f"(max force {r.convergence.force_max:.3g} N, |grad| {r.convergence.grad_norm:.3g} N)"
                        for r in failed)
        if options.on_fail == "raise":
            raise ConvergenceError(f"states did not converge: {msg}", [r.name for r in failed])
        (log.info if options.on_fail == "info" else log.warning)("states did not converge: %s", msg)


def evaluate_state(model: SimModel, design: np.ndarray, state: SimState, x: np.ndarray,
                   options: SolverOptions | None = None) -> tuple[float, np.ndarray, dict[str, float]]:
    """Energy (J), gradient (N, 3) N and energy by term at positions x (N, 3)."""
    options = options or SolverOptions()
    prob = prepare_state(model, design, state, options)
    xt = torch.as_tensor(np.asarray(x, dtype=np.float64), device=prob.device)
    e, g, _ = prob.evaluate(xt, order=1)
    terms, _ = prob.terms(xt)
    return e, g.cpu().numpy(), terms
