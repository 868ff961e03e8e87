"""Quasi-static garment simulator: membrane + wrinkling, IMLS body contact, springs.

Build once per garment, solve per design::

    from kgarment.sim import build_model, Motion, SimState, solve_states

    model = build_model(garment_rest, garment_faces, clutches, preset="paper")
    motion = Motion.create("raise", garment_x0, body_v, body_n, attach_faces, attach_targets)
    states = [SimState.create(motion, [1, 1, 1]), SimState.create(motion, [0, 0, 0])]
    results = solve_states(model, design, states, warm_start=previous_results)

All arrays are float64 SI (m, Pa, J, N).  See the module docstrings of ``materials``
(presets, interpolation), ``membrane`` (energy, wrinkling), ``contact`` (IMLS),
``model`` (penalty scaling), ``options`` (convergence test) and ``newton``.
"""

from kgarment.sim.assembly import HessianPattern, SparseCholesky
from kgarment.sim.contact import ImplicitBody, NeighborCache, update_neighbors
from kgarment.sim.energy import TERMS, SimulationError, StateProblem, state_materials
from kgarment.sim.forces import clutch_tensions
from kgarment.sim.lbfgs import lbfgs_solve
from kgarment.sim.materials import (
    PAPER,
    PRESETS,
    REFERENCE,
    MaterialPreset,
    clutch_material,
    garment_material,
    get_preset,
    lame_plane_stress,
    log_stiffness_derivative,
)
from kgarment.sim.membrane import TriangleElements
from kgarment.sim.model import (
    Motion,
    PenaltyParams,
    SimModel,
    SimState,
    build_model,
    garment_motions,
)
from kgarment.sim.newton import newton_solve
from kgarment.sim.options import Convergence, SolverOptions
from kgarment.sim.solve import (
    ConvergenceError,
    StateResult,
    evaluate_state,
    held_after,
    prepare_state,
    solve_states,
)

__all__ = [
    "PAPER",
    "PRESETS",
    "REFERENCE",
    "TERMS",
    "Convergence",
    "ConvergenceError",
    "HessianPattern",
    "ImplicitBody",
    "MaterialPreset",
    "Motion",
    "NeighborCache",
    "PenaltyParams",
    "SimModel",
    "SimState",
    "SimulationError",
    "SolverOptions",
    "SparseCholesky",
    "StateProblem",
    "StateResult",
    "TriangleElements",
    "build_model",
    "clutch_material",
    "clutch_tensions",
    "evaluate_state",
    "garment_material",
    "garment_motions",
    "get_preset",
    "held_after",
    "lame_plane_stress",
    "lbfgs_solve",
    "log_stiffness_derivative",
    "newton_solve",
    "prepare_state",
    "solve_states",
    "state_materials",
    "update_neighbors",
]
