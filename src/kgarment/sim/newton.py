"""Newton's method with sparse Cholesky, Hessian modification and Armijo backtracking.

Each iteration assembles the Hessian into the fixed CSC pattern, factorises it with a
sparse Cholesky (MKL PARDISO or CHOLMOD, ``assembly.SparseCholesky``: symbolic analysis
once per model, numeric factorisation per iteration), caps the step to ``max_step`` mean
edge lengths per vertex and backtracks (Armijo).

Hessian (``SolverOptions.hessian``):

* ``"shifted"`` (default): the *exact* Hessian (no projection, full contact term) plus a
  diagonal shift ``tau * s_v`` on every DOF (s_v: the local membrane stiffness ``Y t``),
  increased x10 from 1e-3 until the Cholesky factorisation succeeds (Nocedal & Wright,
  alg. 3.3), lowered x10 after each full step (unless that level failed in the last 3
  iterations), raised after a poor one.  After ``max_shifts`` failed tries (default 3, i.e. up to 1e-2) the
  iteration uses the element-wise projected Hessian instead: a larger shift would
  freeze everything else.  The garment's energy is genuinely non-convex (compressed
  clutch strips, triangles just inside the normal branch of the wrinkling rule,
  membranes without bending); the exact curvature, shifted only as much as needed,
  follows it best (fewer iterations than element-wise projection, lower-energy equilibria:
  docs/notes/solver.md);
* ``"adaptive"``: per-element PSD projection (see ``membrane``; contact Gauss-Newton),
  switching to the exact Hessian after every full step;
* ``"projected"``: always the projected Hessian (linear convergence wherever the
  projection discards compressive stiffness: rates 0.5-0.9 measured);
* ``"auto"``: ``"adaptive"`` on garments of more than ``ADAPTIVE_VERTICES`` vertices,
  else ``"shifted"`` (``SolverOptions.strategy``; the evaluations' choice,
  ``kgarment.problem.build.solver_options``).  The shift that makes the exact Hessian
  positive definite, ``tau (Y t)_v`` with tau mostly 1e-3 to 1e-2, also stiffens the
  garment's soft modes -- the cloth sliding round the body, whose own stiffness falls with
  the square of their wavelength in edges -- so each shifted step moves them by a fraction
  ``kappa / (kappa + tau s)`` of the way: a slide that crawls, the longer the finer the
  mesh.  The element-wise projection leaves them alone (measurements: docs/notes/solver.md).

A shift relative to the *local* stiffness matters: with a uniform one, a negative
curvature of the 3 GPa clutch forces a shift that freezes the 0.5 MPa cloth.  A floor of
``damping_min * (Y t)_cloth`` keeps directions without any stiffness (slack cloth
hovering off the body) determinate.

Contact anticipation (``_anticipate``): see there; ``SolverOptions.passes`` re-solves
(1 at the design loop's tolerances, 3 below 1e-3).  Extrapolation: after a full step that
lowered the energy by more than 3/4 of the linear prediction (negative curvature along
the step: the garment sliding or buckling), step lengths 2, 4, ... 64 are tried while the
energy keeps falling.

Where the shifted exact Hessian gets stuck -- its shift escalated to ``STUCK_SHIFT`` (100 x
the local stiffness: converging solves stay at or below 1, measured on the shirt at
subdivision 0) or the energy stopped falling -- the solve goes on from where it is with
the adaptive Hessian (docs/notes/solver.md, "Where the shifted Hessian gets stuck").
A solve whose energy has not decreased beyond round-off (1e-11 |E|) over 10 iterations
with the adaptive or projected Hessian stops unconverged ("stalled");
:func:`kgarment.sim.solve.solve_states` then retries it with larger shifts
(``rescue_shifts``).

The full step's trial point is evaluated with its gradient and Hessian (of the kind the
next iteration uses): where it is accepted without extrapolation -- most iterations -- the
next iteration starts from that evaluation instead of evaluating the same point again.  The
iterates are the same as with a value-only trial (the same point, the same arithmetic).

Near the solution energy differences fall below float64 round-off of the total energy;
the Armijo test therefore allows an increase of ``1e-12 |E|`` (round-off), so a full
Newton step is not rejected for noise.
"""

from __future__ import annotations

import logging
import time

import numpy as np
import scipy.sparse as sp
import torch

from kgarment.sim.assembly import NotPositiveDefinite, SparseCholesky
from kgarment.sim.energy import StateProblem
from kgarment.sim.options import Convergence, SolverOptions

log = logging.getLogger(__name__)
STALL = 10  # iterations without any energy decrease (beyond round-off) that end a solve
LAG_SLACK = 1e-5  # mean edges: how far outside the surface a lagged vertex may end before it counts as pulled in
STUCK_SHIFT = 100.0  # a shift (relative to the local stiffness) at which the exact Hessian has got stuck


def newton_solve(prob: StateProblem, x0: np.ndarray, opts: SolverOptions,
                 linsolver: SparseCholesky | None = None) -> tuple[np.ndarray, Convergence]:
    """Minimise the state's energy from x0 (N, 3).  Returns x (N, 3) and the record."""
    t0 = time.perf_counter()
    model = prob.model
    if linsolver is None:
        linsolver = SparseCholesky.shared(model.pattern, use_cholmod=opts.use_cholmod, mode=opts.factorization)
    k_ref = model.preset.cloth_stiffness
    tol_f = opts.tol
    max_move = opts.max_step * model.mean_edge
    mu = opts.damping_min
    ev0 = prob.n_evals
    x = torch.as_tensor(np.asarray(x0, dtype=np.float64), device=prob.device).clone()
    strategy = opts.strategy(model.n_garment)
    exact = strategy == "shifted"
    tau = 0.0  # shift of the exact Hessian, relative to the local stiffness
    failed = (-1.0, -10)  # (largest shift that failed recently, iteration)
    scale = prob.dof_stiffness  # (3N,) local membrane stiffness Y t, N/m
    floor = opts.damping_min * k_ref
    E, g, H = prob.evaluate(x, order=2, exact=exact)
    hover = np.zeros(0, np.int64)  # vertices the last step's anticipation brought onto the surface
    history: list[float] = []
    converged = False
    it = 0
    energies: list[float] = []
    for it in range(opts.max_iter + 1):
        fmax = prob.residual(g)
        history.append(fmax)
        energies.append(E)
        if fmax <= tol_f:
            converged = True
            break
        if it == opts.max_iter:
            break
        stalled = len(energies) > STALL and energies[-1 - STALL] - E <= 1e-11 * abs(E)
        if strategy == "shifted" and (stalled or tau >= STUCK_SHIFT):
            # the exact curvature is stuck where elements switch branches: go on adaptive
            log.debug("newton %s: %s at residual %.3e; going on with the adaptive Hessian", prob.name,
                      "stalled" if stalled else f"shift {tau:.0e}", fmax)
            strategy, exact, energies = "adaptive", False, []  # the stall window starts again here
            E, g, H = prob.evaluate(x, order=2)
            continue
        if stalled:
            log.debug("newton %s: stalled at residual %.3e (energy unchanged over %d iterations)", prob.name,
                      fmax, STALL)
            break
        rhs = g.reshape(-1).cpu().numpy()
        lin = prob.contact_linearization(x) if opts.passes > 0 else None
        lagged = _lagged(prob, hover, lin, H, rhs) if opts.lagged else None
        Hs, rhs_s = (H, rhs) if lagged is None else lagged[1:]
        dx = None
        if exact:  # exact Hessian, shifted until positive definite (Nocedal-Wright 3.3)
            t = tau
            for _ in range(opts.max_shifts):
                dx = _solve(linsolver, Hs, rhs_s, t * scale + floor)
                if dx is not None:
                    break
                failed = (max(failed[0], t), it)
                t = max(10.0 * t, 1e-3)
            if dx is None:
                exact = False
                E, g, H = prob.evaluate(x, order=2)
            else:
                tau = t
        if dx is None:
            for _ in range(20):
                dx = _solve(linsolver, Hs, rhs_s, mu * scale + floor)
                if dx is not None:
                    break
                mu = max(mu * 10.0, 1e-6)
            else:
                break
        dx, hover = _anticipate(prob, x, Hs, rhs, dx, linsolver, opts.passes, lin,
                                None if lagged is None else lagged[0], rhs_s)
        if dx is None:  # the lagged contact set did not hold: the step without it
            shift = (tau if exact else mu) * scale + floor
            dx = _solve(linsolver, H, rhs, shift)
            if dx is None:
                continue
            dx, hover = _anticipate(prob, x, H, rhs, dx, linsolver, opts.passes, lin)
        move = np.sqrt((dx.reshape(-1, 3) ** 2).sum(1).max())
        if move > max_move:
            dx *= max_move / move
        dxt = torch.as_tensor(dx.reshape(-1, 3), device=prob.device)
        slope = float((g * dxt).sum())
        alpha, accepted, ahead = 1.0, False, None
        if slope < 0.0:
            slack = 1e-12 * abs(E)
            for _ in range(opts.max_backtracks):
                xt = x + alpha * dxt
                if alpha == 1.0:  # the full step, usually taken: its derivatives come with it
                    Et, gt, Ht = prob.evaluate(xt, order=2, check=False, exact=strategy != "projected")
                    ahead = (Et, gt, Ht)
                else:
                    Et, _, _ = prob.evaluate(xt, order=0, check=False)
                if Et <= E + opts.armijo * alpha * slope + slack:
                    accepted = True
                    break
                alpha *= 0.5
        if accepted and alpha == 1.0 and opts.extrapolate and E - Et > 0.75 * -slope:
            # more decrease than a convex quadratic model allows: negative curvature along
            # dx (sliding, buckling); try longer steps while the energy keeps falling
            room = max_move / max(float(torch.linalg.vector_norm(dxt, dim=1).max()), 1e-300)
            while 2.0 * alpha <= min(room, 64.0):
                E2, _, _ = prob.evaluate(x + 2.0 * alpha * dxt, order=0, check=False)
                if not E2 < Et:
                    break
                alpha, Et = 2.0 * alpha, E2
            xt = x + alpha * dxt
        exact_next = strategy == "shifted" or (strategy == "adaptive" and alpha >= 1.0)
        nxt = None
        if accepted:
            nxt = ahead if alpha == 1.0 and _finite(ahead) else prob.evaluate(xt, order=2, check=False,
                                                                              exact=exact_next)
            if not _derivatives_finite(nxt):  # finite energy but its derivatives blow up there (an element
                accepted = False  # degenerating): a shorter, more damped step instead
        log.debug("newton %s it %d: E %.12g alpha %g shift %.1e exact %d residual %.3e", prob.name, it,
                  E, alpha if accepted else 0.0, tau if exact else mu, exact, fmax)
        if not accepted:
            if exact:
                tau = max(tau * 100.0, 1e-2)
            else:
                mu = max(mu * 100.0, 1e-4)
            continue
        if exact:
            lower = tau * 0.1 if tau > 1e-6 else 0.0
            if it - failed[1] > 2:  # forget failed shifts after 3 iterations
                failed = (-1.0, -10)
            if lower <= failed[0]:  # known to be indefinite: don't pay a failed factorisation
                lower = tau
            tau = lower if alpha >= 1.0 else (max(tau * 10.0, 1e-3) if alpha < 0.125 else tau)
        elif alpha >= 1.0:
            mu = max(mu * 0.1, opts.damping_min)
        elif alpha < 0.125:
            mu = mu * 10.0
        exact = exact_next
        x = xt
        E, g, H = nxt  # the accepted point's derivatives (the Hessian kind of the next step)
    rec = Convergence(
        converged=converged, iterations=it, residual=history[-1], tolerance=tol_f,
        force_max=prob.max_force(g), grad_norm=float(torch.linalg.vector_norm(g)),
        wall_time=time.perf_counter() - t0, evaluations=prob.n_evals - ev0, method="newton",
        history=tuple(history))
    return x.cpu().numpy(), rec


def _finite(ahead) -> bool:
    """Whether the full step's trial evaluation (E, g, H) is usable as the next iterate's
    (else the accepted point is evaluated again)."""
    return ahead is not None and _derivatives_finite(ahead)


def _derivatives_finite(e) -> bool:
    """Whether an evaluation (E, g, H)'s gradient and Hessian are finite."""
    return bool(torch.isfinite(e[1]).all()) and bool(np.isfinite(e[2]).all())


def _solve(linsolver: SparseCholesky, H: np.ndarray, rhs: np.ndarray, shift: np.ndarray) -> np.ndarray | None:
    """Newton direction ``-(H + diag(shift))^-1 rhs``, or None if not positive definite."""
    try:
        data = H.copy()
        data[linsolver.pattern.diag_pos] += shift
        linsolver.factorize(data, beta=0.0)
        dx = -linsolver.solve(rhs)
    except NotPositiveDefinite:
        return None
    return dx if np.all(np.isfinite(dx)) else None


def _lagged(prob: StateProblem, hover: np.ndarray, lin, H: np.ndarray, rhs: np.ndarray):
    """The contact model of the last step's anticipated vertices that are not in contact
    now (``hover`` (a,), e.g. on the surface to round-off, just outside it): (their ids,
    Hessian values with the penalty's Gauss-Newton block, right-hand side with its gradient
    term), or None where there are none.  See :func:`_anticipate`."""
    if lin is None or len(hover) == 0:
        return None
    f, gf = lin
    idx = hover[f[hover] >= 0.0]
    if len(idx) == 0:
        return None
    rhs2 = rhs.copy()
    r = rhs2.reshape(-1, 3)
    r[idx] += (2.0 * prob.model_k_contact[idx] * f[idx])[:, None] * gf[idx]
    return idx, prob.add_contact_stiffness(H, idx, gf[idx]), rhs2


def _anticipate(prob: StateProblem, x, H, rhs, dx, linsolver, passes: int, lin=None,
                lagged: np.ndarray | None = None, rhs_lagged: np.ndarray | None = None):
    """Re-solve with the contact stiffness the step is about to meet.

    The Hessian has contact stiffness only where a vertex already penetrates; a step that
    pushes free vertices into the body then overshoots by orders of magnitude (the
    penalty is 10x the membrane stiffness) and the line search crawls.  We predict
    ``f + grad f . dx`` per vertex and, for vertices predicted inside, add the penalty's
    quadratic model ``k (f + grad f . dx)^2`` (Hessian ``2 k grad f grad f^T``, gradient
    ``2 k f grad f``) and re-solve (up to ``passes`` times): the step then brings them to
    the surface instead of through it (a semismooth Newton step for the active set the
    step predicts).  Vertices moving outward are left free.  The result is used only if
    it is a descent direction of the true energy.  (Giving the stiffness without the
    gradient term, or to every vertex near the surface, stalls lift-off: measured.)

    The vertices a step brought onto the surface mostly end there to round-off, outside
    it as often as inside, and the next step presses them in again: one more
    factorisation (or Woodbury update) per iteration for the same vertices.  With
    ``SolverOptions.lagged`` the next iteration's first factorisation carries their
    quadratic model already (``lagged`` (a,), ``H`` and ``rhs_lagged`` with it, ``dx``
    solved with it; :func:`_lagged`).  Where the step would pull one of them *into*
    contact from outside (``f + grad f . dx > LAG_SLACK`` mean edges with the model on: it
    is lifting off), it is not lagged again, so it lifts off one step later; where the
    direction is not a descent direction of the true energy, the result is None and the
    caller solves without the lagged set.  ``rhs`` is always the true gradient.  (Solving
    again without the set wherever one vertex lifts off cost a factorisation in a quarter
    of the iterations and saved less: measured.)

    Returns the direction (or None) and the vertices its contact model holds (for the next
    iteration's ``lagged``).
    """
    none = np.zeros(0, np.int64)
    if passes <= 0:
        return dx, none
    f, gf = prob.contact_linearization(x) if lin is None else lin
    added = f < 0
    rhs2 = rhs.copy() if lagged is None else rhs_lagged.copy()
    held = []
    if lagged is not None:
        if not float(rhs @ dx) < 0.0:
            return None, none
        pred = f[lagged] + (gf[lagged] * dx.reshape(-1, 3)[lagged]).sum(1)
        added[lagged] = True
        held.append(lagged[pred <= LAG_SLACK * prob.model.mean_edge])  # the others lift off next
    best = dx
    for _ in range(passes):
        pred = f + (gf * dx.reshape(-1, 3)).sum(1)
        new = ~added & (pred < 0)
        if not new.any():
            break
        added |= new
        idx = np.nonzero(new)[0]
        held.append(idx)
        H = prob.add_contact_stiffness(H, idx, gf[idx])
        k2 = 2.0 * prob.model_k_contact[idx]
        r = rhs2.reshape(-1, 3)
        r[idx] += (k2 * f[idx])[:, None] * gf[idx]
        rows = (3 * idx[:, None] + np.arange(3)).ravel()
        vals = (np.sqrt(k2)[:, None] * gf[idx]).ravel()
        cols = sp.csc_matrix((vals, (rows, np.repeat(np.arange(len(idx)), 3))), shape=(len(rhs), len(idx)))
        try:
            linsolver.add_outer(cols)
            d2 = linsolver.solve(rhs2)
        except NotPositiveDefinite:
            break
        if not np.all(np.isfinite(d2)):
            break
        dx = -d2
        if float(rhs @ dx) < 0.0:
            best = dx
    return best, (np.concatenate(held) if held else none)
