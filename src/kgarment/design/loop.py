"""The BESO design loop over simulated states, with checkpoints after every iteration.

One iteration: solve every state (motion x activation) for the current design, warm
started from the previous iteration's equilibria (the last converged one per state; see
``WARM_MAX_RESIDUAL``); turn element energy densities into
sensitivities; combine them by the objective; filter; average with the previous
iteration; record metrics; update the design towards the next target area.

An iteration in which a state did not converge records its metrics (flagged in
``unconverged_states``) but updates the design with the previous iteration's filtered
sensitivities (unless the previous iteration failed too: the same update would repeat the
same design and failure), and its objective does not count towards convergence.

Iteration 0 is the fully reinforced garment, so its energies are the references of the
relative energy density rho (method.md section 7) and of the objective.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from kgarment.design.beso import BesoParams, converged, next_target, one_ring_filter, radius_filter, update_design
from kgarment.design.metrics import Stored, clutch_end_support, islands, relative_energy_density
from kgarment.design.objective import combine_sensitivities, objective_value, states_needed
from kgarment.garment.topology import face_adjacency, triangle_areas

log = logging.getLogger(__name__)

# The next iteration starts a state from this iteration's solution of it when that
# converged, or when it did not but its scaled residual is at most this; otherwise from the
# state's last accepted solution.  0 (the default): converged solutions only.
#
# Measured (A/B at preview resolution, sub 0, ER 3%, whole `kgarment reproduce` runs): with
# 1.0 (unconverged solutions accepted as starts; Newton descends monotonically, so they
# are below their start in energy) the runs need fewer Newton iterations (arms raise
# -31%, bend forward -13%, sleeve -18%; arms raise 41 -> 3 iterations with an
# unconverged state) but the designs were no better and in places worse: evaluated rho ON
# arms raise 1.91 -> 1.29, arm flexion 0.23 -> 0.17, sleeve 0.26 / 1.49 -> 0.24 / 1.44,
# bend forward 1.85 -> 1.86, arms forward and arm extension identical.  Quality first:
# off by default.
WARM_MAX_RESIDUAL = 0.0


@dataclass
class DesignSetup:
    """Everything the loop needs, precomputed once.

    model : kgarment.sim.SimModel; motions : {name: kgarment.sim.Motion};
    objective : "active" | "passive" | "compliance"; params : BesoParams;
    solver : kgarment.sim.SolverOptions; evolution_solver : the options while the target
    area is still changing (None: ``solver``; see ``kgarment.problem.SolverSpec``);
    protected : (m,) bool faces kept reinforced.
    """

    model: object
    motions: dict
    objective: str
    params: BesoParams
    solver: object
    evolution_solver: object = None
    protected: np.ndarray | None = None
    filter_matrix: object = None
    areas: np.ndarray = field(default=None)
    adjacency: object = None
    end_faces: list = field(default_factory=list)

    def __post_init__(self):
        m = self.model
        X, F = m.garment_rest, m.garment_faces
        tri = X[F]
        self.areas = triangle_areas(X, F)
        if self.params.filter == "radius":
            self.filter_matrix = radius_filter(tri.mean(1), self.areas, self.params.radius)
        else:
            self.filter_matrix = one_ring_filter(F, self.areas, len(X))
        self.adjacency = face_adjacency(F)
        self.end_faces = []
        for c in m.clutches:
            a = np.asarray(c.anchors)
            self.end_faces.append((np.asarray(c.bind_face)[a[[0, 1, 2]]], np.asarray(c.bind_face)[a[[3, 4, 5]]]))

    def options(self, st: LoopState):
        """The solver options of iteration ``st``: ``evolution_solver`` from iteration 1 while
        the target area differs from A*, ``solver`` otherwise."""
        if self.evolution_solver is not None and evolving(self, st):
            return self.evolution_solver
        return self.solver

    @property
    def n_clutches(self) -> int:
        return len(self.model.clutches)

    def states(self):
        """[(key (motion, state), SimState)] for the objective."""
        from kgarment.sim import SimState

        out = []
        for name, motion in self.motions.items():
            for s in states_needed(self.objective):
                g = {"on": 1.0, "off": 0.0, "none": 0.0}[s] * np.ones(self.n_clutches)
                out.append(((name, s), SimState.create(motion, g, name=f"{name}[{s}]")))
        return out

    def clutch_area(self) -> float:
        total = sum(float(triangle_areas(c.vertices, c.faces).sum()) for c in self.model.clutches)
        return total if self.objective != "passive" else 0.0


@dataclass
class LoopState:
    """What a checkpoint holds: enough to continue bit-identically."""

    iteration: int
    design: np.ndarray
    target: float
    alpha_prev: np.ndarray | None
    warm: dict
    objectives: list
    reference: dict
    reference_stored: dict
    designs: list
    metrics: list
    done: bool = False


def evolving(setup: DesignSetup, st: LoopState) -> bool:
    """Iteration ``st`` is past the reference (0) and its target area is not yet A*."""
    return st.iteration > 0 and st.target != setup.params.target_area


def initial_state(setup: DesignSetup) -> LoopState:
    m = setup.model.n_faces
    return LoopState(0, np.ones(m), 1.0, None, {}, [], {}, {}, [], [])


def iterate(setup: DesignSetup, st: LoopState) -> LoopState:
    """Run one BESO iteration in place on ``st`` (and return it)."""
    from kgarment.sim import log_stiffness_derivative, solve_states

    t0 = time.time()
    keyed = setup.states()
    states = [s for _, s in keyed]
    warm = [st.warm.get(s.name) for s in states]
    opts = setup.options(st)
    coarse = opts is not setup.solver
    results = solve_states(setup.model, st.design, states, warm_start=warm, options=opts)
    bad = [r.name for r in results if not r.converged]
    factor = log_stiffness_derivative(st.design, setup.model.preset) / setup.model.preset.penal
    alpha, energy, stored = {}, {}, {}
    for (key, _), r in zip(keyed, results):
        alpha[key] = r.garment_density * factor
        s = Stored.of(r, setup.objective != "passive")
        stored[key] = s
        energy[key] = float(s.face_energy[st.design > 0.5].sum() + s.clutch_energy)
    if st.iteration == 0:
        st.reference = dict(energy)
        st.reference_stored = dict(stored)
    motions = list(setup.motions)
    raw = combine_sensitivities(setup.objective, alpha, motions)
    filt = setup.filter_matrix @ raw
    if setup.params.history and st.alpha_prev is not None:
        filt = 0.5 * (filt + st.alpha_prev)
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
    if setup.protected is not None:
        filt = np.where(setup.protected, filt.max() + 1.0, filt)
    obj = objective_value(setup.objective, energy, st.reference, motions)
    # NaN: no convergence judged on it (unconverged, or solved to the evolution tolerance)
    st.objectives.append(obj if not (bad or coarse) else float("nan"))
    areas = setup.areas
    frac = float(areas[st.design > 0.5].sum() / areas.sum())
    rho = {f"{k[0]}:{k[1]}": relative_energy_density(st.design, areas, stored[k], st.reference_stored[k],
                                                    setup.clutch_area()) for k in stored}
    links = setup.end_faces
    ends = clutch_end_support(st.design, links)
    row = {
        "iteration": st.iteration, "area": frac, "target": st.target, "objective": obj,
        "islands": islands(setup.model.garment_faces, st.design, adjacency=setup.adjacency),
        "islands_with_clutches": islands(setup.model.garment_faces, st.design, links=links, adjacency=setup.adjacency),
        "clutch_ends_supported": int(sum(a + b for a, b in ends)), "clutch_ends": 2 * len(ends),
        "unconverged_states": ";".join(bad), "seconds": 0.0,
        "newton_iterations": int(sum(r.convergence.iterations for r in results)), "solver_tol": opts.tol,
    }
    row.update({f"rho[{k}]": v for k, v in rho.items()})
    row.update({f"energy[{k[0]}:{k[1]}]": v for k, v in energy.items()})
    st.designs.append(st.design > 0.5)
    reached = abs(frac - setup.params.target_area) <= 0.005 + setup.params.er * setup.params.target_area
    st.done = converged(st.objectives, reached, setup.params) or st.iteration + 1 >= setup.params.max_iterations
    if not st.done:
        st.target = next_target(st.target, setup.params)
        st.design = update_design(st.design, filt, areas, st.target, setup.params)
        if setup.protected is not None:
            st.design[setup.protected] = 1.0
    st.alpha_prev = filt
    st.warm = {s.name: r.x if r.converged or r.convergence.residual <= WARM_MAX_RESIDUAL or s.name not in st.warm
               else st.warm[s.name] for s, r in zip(states, results)}
    st.iteration += 1
    row["seconds"] = time.time() - t0
    st.metrics.append(row)
    log.debug("iteration %d: %s", row["iteration"], row)
    return st


def run_loop(setup: DesignSetup, st: LoopState, checkpoint: Callable[[LoopState], None] | None = None,
             progress: Callable[[dict], None] | None = None) -> LoopState:
    """Iterate until converged or ``max_iterations``; ``checkpoint(st)`` after each iteration."""
    while not st.done:
        iterate(setup, st)
        if checkpoint is not None:
            checkpoint(st)
        if progress is not None:
            progress(st.metrics[-1])
    return st
