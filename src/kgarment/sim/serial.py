"""Solving states one after the other in this process: the energy object of a state, the
Newton (or L-BFGS) solve with its rescue, and the per-state result.

:mod:`kgarment.sim.solve` batches states over this (in this process) or over
:mod:`kgarment.sim.parallel` (worker processes, each running :func:`solve_serial`).
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, field, replace

import numpy as np
import torch

from kgarment.constants import FRICTION_SETTLED
from kgarment.sim.assembly import SparseCholesky
from kgarment.sim.energy import TERMS, StateProblem
from kgarment.sim.lbfgs import lbfgs_solve
from kgarment.sim.model import SimModel, SimState
from kgarment.sim.newton import newton_solve
from kgarment.sim.options import Convergence, SolverOptions

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class StateResult:
    """Equilibrium of one state.

    name : state name;  x : (N, 3) positions (garment then clutches), m;
    garment_energy : (m,) J per garment face;  garment_density : (m,) J/m^2 of rest area
    (= W t);  clutch_energy, clutch_density : lists of (mc_k,) per clutch;
    energy : dict term -> J (``membrane_garment``, ``membrane_clutch``, ``contact``,
    ``attach``, ``anchor``, ``tie``);  convergence : Convergence;  friction : the
    skin-garment friction potential at x (J; ``sim.friction``: a dissipation, not in
    ``energy``).
    """

    name: str
    x: np.ndarray
    garment_energy: np.ndarray
    garment_density: np.ndarray
    clutch_energy: list[np.ndarray]
    clutch_density: list[np.ndarray]
    energy: dict[str, float]
    convergence: Convergence
    garment_x: np.ndarray = field(repr=False, default=None)
    friction: float = 0.0

    @property
    def converged(self) -> bool:
        return self.convergence.converged

    @property
    def total_energy(self) -> float:
        return float(sum(self.energy.values()))


def result_of(prob: StateProblem, x: np.ndarray, rec: Convergence) -> StateResult:
    model = prob.model
    xt = torch.as_tensor(x, device=prob.device)
    terms, e_el = prob.terms(xt)
    area = model.elements.area
    dens = e_el / area
    m, fo = model.n_faces, model.face_offsets
    ce = [e_el[fo[k + 1]: fo[k + 2]] for k in range(model.n_clutches)]
    cd = [dens[fo[k + 1]: fo[k + 2]] for k in range(model.n_clutches)]
    return StateResult(name=prob.name, x=x, garment_energy=e_el[:m], garment_density=dens[:m],
                       clutch_energy=ce, clutch_density=cd, energy={t: terms[t] for t in TERMS},
                       convergence=rec, garment_x=x[: model.n_garment], friction=terms.get("friction", 0.0))


def prepare_state(model: SimModel, design: np.ndarray, state: SimState,
                  options: SolverOptions | None = None) -> StateProblem:
    """The energy object of one state (for custom solvers / diagnostics)."""
    options = options or SolverOptions()
    return StateProblem(model, design, state, device=options.device, projection=options.projection,
                        exact_contact_hessian=options.exact_contact_hessian)


def held_after(model: SimModel, design: np.ndarray, state: SimState, x: np.ndarray,
               options: SolverOptions | None = None) -> np.ndarray:
    """Where skin friction holds the garment after the equilibrium ``x`` (N, 3) of ``state``
    (``sim.friction.slid_anchor`` from the state's own anchor, with the contact normals and
    strip directions lagged at ``x``): the anchor of what comes next in the same pose, (N, 3)
    m; the model must have friction.  A motion's next frame carries it with the skin
    (:func:`kgarment.evaluate.path.carried`)."""
    from kgarment.sim.friction import slid_anchor

    prob = prepare_state(model, design, state, options)
    if not prob.friction_on:
        raise ValueError("held_after: the model has no skin friction (SimModel.friction is 0)")
    _, normal, along = prob.friction_lag(torch.as_tensor(np.asarray(x, dtype=np.float64), device=prob.device))
    return slid_anchor(np.asarray(x, dtype=np.float64), prob.fr_anchor.cpu().numpy(), normal, along,
                       model.friction_slip)


def blas_threads(threads: int | None):
    """A context limiting numpy's and SciPy's BLAS (OpenBLAS) to ``threads`` threads (None:
    unchanged), through threadpoolctl.  A solve makes many small BLAS calls (dot products
    and Woodbury updates on 3N-vectors); OpenBLAS parallelises those and its idle threads
    then spin, so each process kept a second core ~90% busy: two worker processes on 2
    cores ran at about half speed (measured at subdivision 1, 6 warm states at tol 1e-3:
    9.7 s in 2 processes with the default, 6.1 s with one BLAS thread; one process 10.5
    and 10.9 s)."""
    from contextlib import nullcontext

    if threads is None:
        return nullcontext()
    try:
        from threadpoolctl import threadpool_limits
    except ImportError:  # pragma: no cover - a dependency; keep solving without it
        return nullcontext()
    return threadpool_limits(limits=threads, user_api="blas")


def solve_serial(model: SimModel, design: np.ndarray, states, warm, options: SolverOptions) -> list[StateResult]:
    """Solve ``states`` one by one for ``design`` (m,) from ``warm`` (per state (N, 3) or None)."""
    linsolver = None
    if options.method == "newton":
        linsolver = SparseCholesky.shared(model.pattern, use_cholmod=options.use_cholmod, mode=options.factorization)
    results = []
    for state, w in zip(states, warm):
        prob = prepare_state(model, design, state, options)
        x0 = prob.initial_positions() if w is None else w
        if prob.friction_on:
            x, rec = _with_friction(prob, x0, options, linsolver)
        else:
            x, rec = _solve(prob, x0, options, linsolver)
        log.info("state %s: %s %s in %d iterations, %.3f s, residual %.3g (tol %.3g), max force %.3g N",
                 state.name, options.method, "converged" if rec.converged else "NOT converged",
                 rec.iterations, rec.wall_time, rec.residual, rec.tolerance, rec.force_max)
        results.append(result_of(prob, x, rec))
    return results


def _solve(prob: StateProblem, x0: np.ndarray, options: SolverOptions, linsolver) -> tuple[np.ndarray, Convergence]:
    """One solve from x0 (N, 3), Newton with its rescue or L-BFGS."""
    if options.method != "newton":
        return lbfgs_solve(prob, x0, options)
    x, rec = newton_solve(prob, x0, options, linsolver)
    if not rec.converged and options.rescue_shifts > options.max_shifts:
        x, rec = _rescue(prob, x0, x, rec, options, linsolver)
    return x, rec


def _with_friction(prob: StateProblem, x0: np.ndarray, options: SolverOptions, linsolver):
    """Solve with skin-garment friction (``sim.friction``): the normal forces lagged from
    the start x0 (N, 3) (the pressure of the skin-tight garment, or of the warm start's
    equilibrium), then from each equilibrium, re-solving until no bound moved by more than
    ``FRICTION_SETTLED`` of the largest or ``options.friction_lags`` re-solves are done;
    iterations and time add up."""

    def lag(x):
        return prob.friction_lag(torch.as_tensor(np.asarray(x, dtype=np.float64), device=prob.device))

    bound, normal, along = lag(x0)
    prob.set_friction(bound, normal, along)
    x, rec = _solve(prob, x0, options, linsolver)
    for _ in range(options.friction_lags):
        new, normal, along = lag(x)
        if np.abs(new - bound).max(initial=0.0) <= FRICTION_SETTLED * max(new.max(initial=0.0), 1e-12):
            break
        bound = new
        prob.set_friction(bound, normal, along)
        x, rec2 = _solve(prob, x, options, linsolver)
        rec = _spent(rec2, rec, rec2)
    log.debug("state %s: friction bounds up to %.3g N over %d vertices", prob.name, bound.max(initial=0.0),
              int((bound > 0).sum()))
    return x, rec


def _rescue(prob, x0, x, rec, options, linsolver):
    """Solve again with larger Hessian shifts -- from x0 where the first solve stopped early
    (stalled, stuck), from where it stopped where it ran out of iterations (a slow slide,
    whose progress a new start would throw away) -- and keep the better of both solves
    (converged, else the lower residual); iterations and time add up.  Measured on the
    three-motion shirt at subdivision 1 (2026-11-28): its arms raise and bend forward OFF
    states, still sliding after 200 iterations, took 200 more from the start without
    converging, and converged in 47 and 71 from where they stopped."""
    ran_out = rec.iterations >= options.max_iter
    log.info("state %s: not converged (residual %.3g); going on %s with up to %d shift increases",
             prob.name, rec.residual, "from where it stopped" if ran_out else "from its start",
             options.rescue_shifts)
    x2, rec2 = newton_solve(prob, x if ran_out else x0, replace(options, max_shifts=options.rescue_shifts),
                            linsolver)
    best_x, best = (x2, rec2) if rec2.converged or rec2.residual < rec.residual else (x, rec)
    return best_x, _spent(best, rec, rec2)


def _spent(kept: Convergence, *solves: Convergence) -> Convergence:
    """The record ``kept`` with the iterations, time and evaluations of all ``solves``."""
    return replace(kept, iterations=sum(r.iterations for r in solves), wall_time=sum(r.wall_time for r in solves),
                   evaluations=sum(r.evaluations for r in solves))
