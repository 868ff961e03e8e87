"""A design run from a problem to a finished run folder, for the CLI and ``reproduce``.

:func:`open_run` prepares (or reopens) the run folder, writes the resolved problem and
clutch files, builds body, garment, clutches and the loop's setup, and loads the
checkpoint when resuming; :func:`finish` runs the loop to the end with a checkpoint
after every iteration, then writes the final design and its renders.
"""

from __future__ import annotations

import dataclasses
import logging
import os
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

log = logging.getLogger(__name__)

# Solver tolerance of evaluations (rho of a finished design), tighter than the design
# iterations' default 1e-3 (why: kgarment.problem.SolverSpec)
EVALUATION_TOL = 1e-4


@dataclass
class DesignRun:
    """An open run: its folder, the problem and everything built from it.

    run : folder;  problem : kgarment.problem.Problem;  body, garment, strips : as built;
    setup : kgarment.design.loop.DesignSetup;  state : kgarment.design.loop.LoopState;
    paths : files written by :func:`finish`.
    """

    run: Path
    problem: object
    body: object
    garment: object
    strips: list
    setup: object
    state: object
    paths: list = dataclasses.field(default_factory=list)


def run_status(run) -> str:
    """"new" (no checkpoint), "unfinished" or "finished" (final design written)."""
    run = Path(run)
    ck = run / "checkpoint.npz"
    if not ck.is_file():
        return "new"
    with np.load(ck) as z:
        done = bool(z["done"])
    return "finished" if done and (run / "final" / "design.npz").is_file() else "unfinished"


def build_setup(problem, body, garment, strips, device: str = "cpu", evaluation: bool = False):
    """The design loop's precomputed setup for a problem (model, motions, filter, ...).

    ``evaluation``: the setup measures designs rather than iterating on one; it solves to
    ``min([solver] tol, EVALUATION_TOL)`` (see ``kgarment.problem.SolverSpec``)."""
    from kgarment.design import BesoParams
    from kgarment.design.loop import DesignSetup
    from kgarment.sim import SolverOptions, build_model
    from kgarment.simulate import sim_motions

    d = problem.design
    params = BesoParams(**{k: v for k, v in dataclasses.asdict(d).items()
                           if k not in ("objective", "protect_attachments", "protect_clutch_margin")})
    use_clutches = strips if d.objective != "passive" else []
    model = build_model(garment.rest_vertices, garment.faces, use_clutches, preset=problem.solver.preset)
    s = problem.solver
    tol = min(s.tol, EVALUATION_TOL) if evaluation else s.tol
    opts = SolverOptions(method=s.method, tol=tol, max_iter=s.max_iter, device=device,
                         workers=s.workers or min(os.cpu_count() or 1, 8))
    evolution = dataclasses.replace(opts, tol=max(tol, s.evolution_tol))
    return DesignSetup(model, sim_motions(body, garment), d.objective, params, opts,
                       evolution_solver=evolution,
                       protected=protected_faces(garment, use_clutches, d.protect_attachments, d.protect_clutch_margin))


def protected_faces(garment, strips, attachments: bool, margin: float):
    """(m,) bool faces kept reinforced: attachment rings and/or faces whose centroid is
    within ``margin`` metres of a clutch anchor; None when nothing is protected."""
    keep = garment.attached.copy() if attachments else np.zeros(garment.n_faces, bool)
    if margin > 0 and strips:
        cent = garment.rest_vertices[garment.faces].mean(axis=1)
        anchors = np.concatenate([c.vertices[c.anchors] for c in strips])
        d = np.linalg.norm(cent[:, None, :] - anchors[None, :, :], axis=2).min(axis=1)
        keep |= d <= margin
    return keep if keep.any() else None


def open_run(problem, run, *, resume: bool = False, force: bool = False, device: str = "cpu") -> DesignRun:
    """Prepare a run folder for ``problem`` (or reopen it with ``resume``; the problem is
    then read from the folder and the argument may be None)."""
    import tomli_w

    from kgarment.clutch import save_clutches
    from kgarment.design.loop import initial_state
    from kgarment.design.run import load_checkpoint, prepare_run_folder
    from kgarment.problem import (
        build_body,
        build_clutches,
        build_garment,
        clutch_specs,
        load_problem,
        problem_to_dict,
    )

    run = prepare_run_folder(run, force=force, resume=resume)
    if resume:
        problem = load_problem(run / "problem.toml")
    body = build_body(problem)
    garment = build_garment(problem, body)
    strips = build_clutches(problem, body, garment)
    if not resume:
        specs = clutch_specs(problem, body)
        if specs:
            save_clutches(run / "clutches.toml", specs, garment.rest_vertices, garment.faces)
        if problem.source:
            (run / "problem.source.toml").write_text(Path(problem.source).read_text())
        clutch_file = run / "clutches.toml" if specs else None
        (run / "problem.toml").write_text(tomli_w.dumps(problem_to_dict(problem, clutch_file)))
        (run / "problem.txt").write_text(problem.describe() + "\n")
    setup = build_setup(problem, body, garment, strips, device)
    st = load_checkpoint(run) if resume else initial_state(setup)
    return DesignRun(run, problem, body, garment, strips, setup, st)


def finish(dr: DesignRun, progress: Callable[[dict], None] | None = None) -> DesignRun:
    """Iterate to the end (checkpoint after every iteration), then write the final design
    and its renders into ``dr.run / "final"``."""
    from kgarment.design.loop import run_loop
    from kgarment.design.report import finish_run
    from kgarment.design.run import save_checkpoint

    run_loop(dr.setup, dr.state, checkpoint=lambda s: save_checkpoint(dr.run, s), progress=progress)
    dr.paths = finish_run(dr.run, dr.setup, dr.state, dr.body, dr.garment, dr.strips)
    return dr


def design_equilibria(setup, design: np.ndarray, reference: Callable[[], list], states=None) -> list:
    """Equilibria of ``design`` (m,) in ``states`` (SimState list; default every state of
    ``setup``, a ``DesignSetup``).

    ``reference()`` is the fully reinforced garment's equilibria, computed only when needed:
    a fully reinforced ``design`` returns them.  Otherwise solved from the skin-tight start
    (like a design run's first iteration); states that do not converge are retried from the
    reference equilibria and the converged, else lower-residual, solution is kept; clutched
    states that still fail are solved by :func:`activation_continuation`.  The full
    garment's equilibrium alone is a poor start for a sparse design: measured, 200 Newton
    iterations without converging where the cold start needed 76.
    """
    from kgarment.sim import solve_states

    if np.all(design > 0.5):
        return list(reference())
    states = [s for _, s in setup.states()] if states is None else list(states)
    cold = solve_states(setup.model, design, states, options=setup.solver)
    bad = [i for i, r in enumerate(cold) if not r.converged]
    if not bad:
        return cold
    ref = reference()
    retry = solve_states(setup.model, design, [states[i] for i in bad], warm_start=[ref[i].x for i in bad],
                         options=setup.solver)
    for i, r in zip(bad, retry):
        if r.converged or r.convergence.residual < cold[i].convergence.residual:
            cold[i] = r
    for i in [i for i in bad if not cold[i].converged and any(a > 0 for a in states[i].activation)]:
        r = activation_continuation(setup, design, states[i])
        if r.converged or r.convergence.residual < cold[i].convergence.residual:
            cold[i] = r
    return cold


CONTINUATION = (0.0, 0.25, 0.5, 0.75, 1.0)


def activation_continuation(setup, design: np.ndarray, state):
    """Solve ``state`` by switching its clutches on in steps: the equilibrium with the
    clutches off (from the skin-tight start), then activations ``CONTINUATION`` times the
    state's, each from the previous equilibrium.  Returns the last step's StateResult
    (named as ``state``; iterations and time of all steps added up).

    For states whose stiff ON clutches make the direct solve slow: on the long sleeve's
    bend-forward state (preview resolution, its iteration-117 design) the direct cold
    solve did not converge in 400 iterations; off, then 0.25, 0.5, 0.75, 1 converged in
    125 + 143 + 52 + 66 + 34 iterations, at a lower energy (5.96 J against 6.06 J).
    """
    from dataclasses import replace

    from kgarment.sim import SimState, solve_states

    log.info("state %s: switching the clutches on in steps %s", state.name, CONTINUATION)
    g = np.asarray(state.activation, dtype=np.float64)
    x, iters, secs, r = None, 0, 0.0, None
    for k, f in enumerate(CONTINUATION):
        step = state if f == 1.0 else SimState.create(state.motion, f * g, name=f"{state.name}@{f:g}")
        r = solve_states(setup.model, design, [step], warm_start=None if x is None else [x],
                         options=setup.solver)[0]
        iters += r.convergence.iterations
        secs += r.convergence.wall_time
        if not r.converged and k < len(CONTINUATION) - 1:
            log.info("state %s: step %g did not converge (residual %.3g); going on", state.name, f,
                     r.convergence.residual)
        x = r.x
    return replace(r, convergence=replace(r.convergence, iterations=iters, wall_time=secs))
