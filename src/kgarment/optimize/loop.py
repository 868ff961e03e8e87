"""The BESO design loop over simulated states, split into pure steps.

One iteration (:func:`iterate`) is four steps, each a function of the frozen
:class:`~kgarment.optimize.setup.DesignSetup` and the immutable :class:`LoopState`:

1. :func:`solve`: every state (motion x activation) for the current design, warm started
   from the previous iteration's equilibria (the last converged one per state; see
   ``WARM_MAX_RESIDUAL``) and, with ``skin_start``, also from the evaluator's two starts, the
   skin-tight garment and the fully reinforced garment's equilibrium (``FULL``; all starts in
   one batch of solves; the lower-energy equilibrium kept) -> :class:`Solved`
   (equilibria, stored energies);
2. :func:`metrics_row`: the iteration's metrics (area, objective and each motion's term
   of it, rho per state, islands, clutch ends, the tension each clutch carries in each ON
   state, solver effort);
3. :func:`sensitivities`: element energy densities -> sensitivities, combined by the
   objective (the motions weighted by ``[design] combine`` from the row's terms, once per
   iteration: :func:`combine_weights`), filtered, averaged with the previous iteration's;
4. :func:`advance`: the next state (a new design towards the next target area, repaired
   into one part holding every clutch end unless ``connected`` is off, or done); with
   ``[design] guard``, a step that broke a motion's load path is taken back
   (:mod:`kgarment.optimize.guard`).

An iteration in which a state did not converge records its metrics (flagged in
``unconverged_states``) but updates the design with the previous iteration's filtered
sensitivities (unless the previous iteration failed too: the same update would repeat the
same design and failure), and its objective does not count towards convergence.

Iteration 0 is the fully reinforced garment, so its energies are the references of the
relative energy density rho (docs/method/index.md, "The relative energy density") and of the objective.  It starts from the
garment as put on: the skin-tight garment, or on a subdivided garment of more than
``NESTED_VERTICES`` vertices its equilibria one subdivision level down
(:func:`kgarment.case.levels.put_on`).
"""

from __future__ import annotations

import dataclasses
import logging
import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from kgarment.case.keys import (
    ENERGY,
    GAIN,
    RHO,
    TENSION,
    TERM,
    Kind,
    Start,
    StateKey,
    is_started,
    motion_column,
    started,
    state_column,
)
from kgarment.case.levels import put_on
from kgarment.case.starts import MULTISTABLE, pick_equilibrium
from kgarment.case.values import design_values
from kgarment.evaluate.metrics import Stored, relative_energy_density, structure
from kgarment.optimize.beso import converged, next_target, settled_ar, update_design
from kgarment.optimize.connect import connect_design
from kgarment.optimize.guard import (
    REJECTED,
    blinding,
    boosted,
    guard_step,
    last_accepted,
    paths_of,
    terms_of,
)
from kgarment.optimize.objective import (
    combine_sensitivities,
    combined_objective,
    motion_sensitivities,
    motion_weights,
    objective_terms,
)
from kgarment.optimize.setup import DesignSetup
from kgarment.sim import (
    SimState,
    SolverOptions,
    StateResult,
    clutch_tensions,
    log_stiffness_derivative,
)

log = logging.getLogger(__name__)

# The next iteration starts a state from this iteration's solution of it when that
# converged, or when it did not but its scaled residual is at most this; otherwise from the
# state's last accepted solution.  0 (the default): converged solutions only (why:
# docs/notes/code.md, "kgarment.optimize.loop").
WARM_MAX_RESIDUAL = 0.0

# With ``skin_start`` the loop state's ``warm`` also keeps iteration 0's (the fully reinforced
# garment's) equilibrium of each state under its name + FULL: every iteration solves from
# it too, the evaluator's second start (kgarment.evaluate.evaluator).
FULL = started("", Start.FULL)  # the suffix of those names


@dataclass(frozen=True, kw_only=True)
class LoopState:
    """Where a run stands: what a checkpoint holds, enough to continue bit-identically.

    iteration : the next iteration to run;  design : (m,) its design in {x_min, 1};
    target : its target area share;  alpha_prev : (m,) the last filtered sensitivities or
    None;  warm : {state name: (N, 3) start positions, m};  objectives : per finished
    iteration, NaN where it does not count towards convergence;  reference : {StateKey:
    energy J of the fully reinforced garment (iteration 0)};  reference_stored : {StateKey:
    Stored};  designs : per finished iteration its (m,) bool design;  metrics : per finished
    iteration its metrics row;  done : converged or out of iterations;  guarded : (m,) bool
    faces kept by the step guard (:mod:`kgarment.optimize.guard`), or None;  accepted_alpha :
    {motion: (m,) its sensitivities at the last accepted iteration whose states all
    converged} (the guard's ranking of the faces a rejected step removed; None without it).
    """

    iteration: int
    design: np.ndarray
    target: float
    alpha_prev: np.ndarray | None
    warm: dict[str, np.ndarray]
    objectives: tuple[float, ...]
    reference: dict[StateKey, float]
    reference_stored: dict[StateKey, Stored]
    designs: tuple[np.ndarray, ...]
    metrics: tuple[dict, ...]
    done: bool = False
    guarded: np.ndarray | None = None
    accepted_alpha: dict[str, np.ndarray] | None = None


@dataclass(frozen=True, kw_only=True)
class Solved:
    """Step 1's result: the equilibria of every state for the iteration's design.

    keys : StateKey per state;  states : SimState per state;  results : StateResult per
    state;  options : the solver options used;
    unconverged : names of the states that did not converge;  energy : {StateKey: J stored
    in the reinforced faces (and clutches)};  stored : {StateKey: Stored};  alpha : {StateKey:
    (m,) element sensitivities};  newton_iterations : of every solve, both starts with
    ``skin_start`` (not the motion from rest's);  path_checked : the ON states were also solved
    over their motion from rest (``path_start``);  path_moved : the motions whose ON state
    that check replaced (the guard does not judge such an iteration: the drop is the
    measurement's, not the step's; it becomes the guard's reference).
    """

    keys: list[StateKey]
    states: list[SimState]
    results: list[StateResult]
    options: SolverOptions
    unconverged: list[str]
    energy: dict[StateKey, float]
    stored: dict[StateKey, Stored]
    alpha: dict[StateKey, np.ndarray]
    newton_iterations: int
    path_checked: bool = False
    path_moved: tuple[str, ...] = ()


def initial_state(setup: DesignSetup) -> LoopState:
    """Iteration 0: the fully reinforced garment."""
    return LoopState(iteration=0, design=np.ones(setup.case.model.n_faces), target=1.0, alpha_prev=None, warm={},
                     objectives=(), reference={}, reference_stored={}, designs=(), metrics=())


def solve(setup: DesignSetup, st: LoopState) -> Solved:
    """Step 1: solve every state for ``st.design``, warm started."""
    keyed = setup.case.states()
    states = [s for _, s in keyed]
    opts = setup.options(st.iteration)
    warm = [st.warm.get(s.name) for s in states]
    if not st.warm:  # iteration 0: the garment as put on (on a large subdivided garment solved one level down first)
        warm = put_on(setup.case, st.design, states)
    starts = None  # with skin_start: per state the better of the evaluator's two starts
    if setup.case.skin_start and st.warm:
        n = len(states)
        full = [st.warm.get(started(s.name, Start.FULL)) for s in states]  # the evaluator's second start (FULL)
        has = [i for i, x in enumerate(full) if x is not None]
        extra = [dataclasses.replace(s, name=started(s.name, Start.SKIN_TIGHT)) for s in states] + \
            [dataclasses.replace(states[i], name=started(states[i].name, Start.FULL)) for i in has]
        both = setup.case.solve(st.design, states + extra, warm_start=warm + [None] * n + [full[i] for i in has],
                           options=opts)  # one batch: the workers share the solves
        starts = [dataclasses.replace(c, name=s.name) for s, c in zip(states, both[n:2 * n])]
        results = [pick_equilibrium(w, c).result for w, c in zip(both[:n], starts)]
        for j, i in enumerate(has):
            f = dataclasses.replace(both[2 * n + j], name=states[i].name)
            results[i] = pick_equilibrium(results[i], f).result
            starts[i] = pick_equilibrium(starts[i], f).result
        others = list(enumerate(both[n:2 * n])) + [(i, both[2 * n + j]) for j, i in enumerate(has)]
        results, more = _continue_lower(setup, st.design, states, results, others, opts)
        both = both + more
    else:
        results = both = setup.case.solve(st.design, states, warm_start=warm, options=opts)
    moved: list[str] = []
    checked = bool(setup.beso.path_start) and st.iteration > 0 and st.iteration % setup.beso.path_start == 0
    if checked:
        from kgarment.optimize.motion_start import motion_ends

        results, moved = motion_ends(setup, st.design, keyed, results, starts)
    factor = log_stiffness_derivative(st.design, setup.case.model.preset) / setup.case.model.preset.penal
    alpha, energy, stored = {}, {}, {}
    for (key, _), r in zip(keyed, results):
        alpha[key] = r.garment_density * factor
        s = Stored.of(r, setup.case.objective != "passive")
        stored[key] = s
        energy[key] = float(s.face_energy[st.design > 0.5].sum() + s.clutch_energy)
    return Solved(keys=[k for k, _ in keyed], states=states, results=results, options=opts,
                  unconverged=[r.name for r in results if not r.converged], energy=energy, stored=stored, alpha=alpha,
                  newton_iterations=int(sum(r.convergence.iterations for r in both)), path_checked=checked,
                  path_moved=tuple(moved))


def _continue_lower(setup: DesignSetup, design: np.ndarray, states: list[SimState], results: list[StateResult],
                    others: list[tuple[int, StateResult]], opts) -> tuple[list[StateResult], list[StateResult]]:
    """A start whose solve ran out of iterations below the kept equilibrium's energy (by more
    than MULTISTABLE; Newton only descends, so a lower basin is there) is solved on from
    where it stopped, and kept if it converges lower: the evaluator, at its tolerance and
    with its rescues, finds that basin, so the run must not keep the higher equilibrium.
    ``others``: (state index, its solve from another
    start).  Returns the results and the extra solves."""
    best: dict[int, StateResult] = {}
    for i, r in others:
        if r.converged or not results[i].converged:
            continue
        if r.total_energy < results[i].total_energy * (1 - MULTISTABLE) and \
                (i not in best or r.total_energy < best[i].total_energy):
            best[i] = r
    if not best:
        return results, []
    todo = sorted(best)
    more = setup.case.solve(design, [dataclasses.replace(states[i], name=started(states[i].name, Start.CONTINUED)) for i in todo],
                       warm_start=[best[i].x for i in todo], options=opts)
    out = list(results)
    for i, r in zip(todo, more):
        out[i] = pick_equilibrium(out[i], dataclasses.replace(r, name=states[i].name)).result
    return out, list(more)


def sensitivities(setup: DesignSetup, st: LoopState, solved: Solved,
                  weights: dict[str, float] | None = None) -> np.ndarray:
    """Step 3: (m,) filtered sensitivities of this iteration (higher = more useful as
    reinforcement): combined by the objective (each motion's scaled by ``weights``, from
    :func:`combine_weights`; None: 1), filtered, averaged with the previous iteration's;
    the previous ones when a state did not converge (not twice in a row); protected faces
    on top."""
    filt = setup.beso.filter_matrix @ combine_sensitivities(
        setup.case.objective, solved.alpha, list(setup.case.motions), lockout=setup.case.lockout,
        balance=setup.case.balance, energy=solved.energy, weights=weights)
    if setup.beso.params.history and st.alpha_prev is not None:
        filt = 0.5 * (filt + st.alpha_prev)
    bad = solved.unconverged
    repeated = bool(st.metrics) and bool(st.metrics[-1]["unconverged_states"])
    if bad and st.alpha_prev is not None and not repeated:
        # an unconverged state's energies are not an equilibrium's: never used silently.
        # The update goes on with the previous iteration's sensitivities.
        log.warning("iteration %d: %s did not converge; its sensitivities are not used (the previous "
                    "iteration's are)", st.iteration, ", ".join(bad))
        filt = st.alpha_prev
    elif bad:
        # twice in a row: the previous sensitivities would give the same design (and the same
        # failure) forever; use this iteration's, flagged in the metrics
        log.warning("iteration %d: %s did not converge again; using its sensitivities", st.iteration, ", ".join(bad))
    if setup.beso.protected is not None:
        filt = np.where(setup.beso.protected, filt.max() + 1.0, filt)
    return filt


def combine_weights(setup: DesignSetup, row: dict) -> dict[str, float] | None:
    """The motions' weights of ``[design] combine`` from the terms in this iteration's
    metrics ``row`` and the setup's shares (:func:`kgarment.optimize.objective.motion_weights`;
    None for "sum" without shares)."""
    return motion_weights(setup.beso.combine, terms_of(row), setup.beso.shares)


def metrics_row(setup: DesignSetup, st: LoopState, solved: Solved, reference: dict[StateKey, float],
                reference_stored: dict[StateKey, Stored]) -> dict:
    """Step 2: the metrics of this iteration (``seconds`` is filled in by :func:`iterate`)."""
    areas, design = setup.case.areas, st.design
    frac = float(areas[design > 0.5].sum() / areas.sum())
    terms = objective_terms(setup.case.objective, solved.energy, reference, list(setup.case.motions), setup.case.lockout,
                            setup.case.balance)
    obj = combined_objective(setup.beso.combine, terms, setup.beso.shares)
    shape = structure(setup.case, design)
    row = {
        "iteration": st.iteration, "area": frac, "target": st.target, "objective": obj,
        **{k: shape[k] for k in ("islands", "islands_with_clutches", "clutch_ends_supported", "clutch_ends")},
        "unconverged_states": ";".join(solved.unconverged), "seconds": 0.0,
        "newton_iterations": solved.newton_iterations,
        "solver_tol": solved.options.tol,
        **({"path_checked": solved.path_checked, "path_moved": ",".join(solved.path_moved)}
           if setup.beso.path_start else {}),
    }
    row.update({motion_column(TERM, m): v for m, v in terms.items()})
    if setup.case.lockout > 0 and setup.case.objective == "active":  # the guard's reading (kgarment.optimize.guard)
        gains = objective_terms(setup.case.objective, solved.energy, reference, list(setup.case.motions), 0.0, setup.case.balance)
        row.update({motion_column(GAIN, m): v for m, v in gains.items()})
    row.update({state_column(RHO, k): relative_energy_density(design, setup.case.areas_of(k[0]), solved.stored[k],
                                                              reference_stored[k], setup.case.clutch_area_of(k[0]))
                for k in solved.stored})
    row.update({state_column(ENERGY, k): v for k, v in solved.energy.items()})
    row.update(tension_columns(setup, st.design, solved))
    return row


def tension_columns(setup: DesignSetup, design: np.ndarray, solved: Solved) -> dict[str, float]:
    """``tension[motion:clutch]``: N carried along each clutch in each motion's ON state
    (:func:`kgarment.sim.clutch_tensions`; cheap, from the equilibria already solved)."""
    out = {}
    names = [c.name for c in setup.case.model.clutches]
    for key, state, r in zip(solved.keys, solved.states, solved.results):
        if StateKey(*key).kind is Kind.ON and names:
            t = clutch_tensions(setup.case.model_of(key[0]), design, state, r.x, solved.options)
            out.update({state_column(TENSION, (key[0], n)): float(v) for n, v in zip(names, t)})
    return out


def advance(setup: DesignSetup, st: LoopState, solved: Solved, filt: np.ndarray, row: dict,
            reference: dict[StateKey, float], reference_stored: dict[StateKey, Stored]) -> LoopState:
    """Step 4: the next state: this iteration recorded; converged (or out of iterations), or
    the design updated towards the next target area -- or, when the step guard rejects this
    iteration's step, made again from the last accepted iteration (``row["rejected"]``
    names the motions whose load path it broke)."""
    p = setup.beso.params
    rejected, guarded, base, accepted = [], st.guarded, st.design, st.accepted_alpha
    a = last_accepted(st.metrics)
    if setup.beso.guard > 0 and a is not None and not blinding(solved.unconverged) and not solved.path_moved:
        removed = st.designs[a] & ~(st.design > 0.5)
        rejected, guarded = guard_step(st.metrics, paths_of(row), setup.beso.guard, removed, st.guarded,
                                       areas=setup.case.areas, target=st.target, accepted_alpha=st.accepted_alpha)
    if setup.beso.guard > 0 and not rejected and not solved.unconverged:
        accepted = motion_sensitivities(setup.case.objective, solved.alpha, list(setup.case.motions),
                                        lockout=setup.case.lockout, balance=setup.case.balance, energy=solved.energy,
                                        weights=combine_weights(setup, row))
    row[REJECTED] = ",".join(rejected)
    counts = setup.judged(st.iteration, st.target) and not (solved.unconverged or rejected)  # else NaN: not judged
    objectives = st.objectives + (row["objective"] if counts else float("nan"),)
    done = converged(list(objectives), p.reached(row["area"]), p) or st.iteration + 1 >= p.max_iterations
    target, design, alpha = st.target, st.design, filt
    if rejected:
        log.info("iteration %d: the step broke the load path of %s; made again from iteration %d", st.iteration,
                 ", ".join(rejected), a)
        base, alpha = design_values(st.designs[a]), st.alpha_prev
    if not done:
        if not rejected:
            target = next_target(st.target, p)
        rank = boosted(alpha, guarded)
        at_target = sum(1 for r in st.metrics + (row,) if p.reached(r["area"]))
        design = update_design(base, rank, setup.case.areas, target, p, settled_ar(p, at_target))
        if p.connected and setup.case.ends:
            design = design_values(connect_design(
                design > 0.5, alpha, setup.case.areas, target, setup.case.adjacency, setup.case.all_end_faces,
                attached=setup.case.attached, loop_faces=setup.beso.loop_faces, keep=guarded,
                partners=setup.case.end_partners()))
        if setup.beso.protected is not None:
            design[setup.beso.protected] = 1.0
    warm = st.warm if rejected else {
        **{k: x for k, x in st.warm.items() if is_started(k, Start.FULL)},
        **{s.name: r.x if r.converged or r.convergence.residual <= WARM_MAX_RESIDUAL or s.name not in st.warm
           else st.warm[s.name] for s, r in zip(solved.states, solved.results)}}
    if setup.case.skin_start and st.iteration == 0:  # the fully reinforced garment's equilibria: a start of every iteration
        warm.update({started(s.name, Start.FULL): r.x for s, r in zip(solved.states, solved.results) if r.converged})
    return LoopState(iteration=st.iteration + 1, design=design, target=target, alpha_prev=alpha, warm=warm,
                     objectives=objectives, reference=reference, reference_stored=reference_stored,
                     designs=st.designs + (st.design > 0.5,), metrics=st.metrics + (row,), done=done, guarded=guarded,
                     accepted_alpha=accepted)


def iterate(setup: DesignSetup, st: LoopState) -> LoopState:
    """One BESO iteration: solve, sensitivities, metrics, advance; returns the next state."""
    t0 = time.time()
    solved = solve(setup, st)
    reference, reference_stored = (solved.energy, solved.stored) if st.iteration == 0 else \
        (st.reference, st.reference_stored)
    row = metrics_row(setup, st, solved, reference, reference_stored)
    filt = sensitivities(setup, st, solved, combine_weights(setup, row))
    nxt = advance(setup, st, solved, filt, row, reference=reference, reference_stored=reference_stored)
    row["seconds"] = time.time() - t0
    log.debug("iteration %d: %s", row["iteration"], row)
    return nxt


def run_loop(setup: DesignSetup, st: LoopState, checkpoint: Callable[[LoopState], None] | None = None,
             progress: Callable[[LoopState], None] | None = None) -> LoopState:
    """Iterate until converged or ``max_iterations``; after each iteration
    ``checkpoint(state)`` then ``progress(state)`` (its last metrics row is
    ``state.metrics[-1]``). Returns the final state."""
    while not st.done:
        st = iterate(setup, st)
        if checkpoint is not None:
            checkpoint(st)
        if progress is not None:
            progress(st)
    return st
