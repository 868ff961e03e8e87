"""The optimiser's settings beside the case it designs: BESO's parameters, the sensitivity
filter, the faces kept reinforced, the step guard, how the motions' terms combine, the
checks over the motion from rest and the solver options of the evolving iterations.

:func:`setup_from_problem` builds a :class:`DesignSetup` for a design run; the loop
(:mod:`kgarment.optimize.loop`) and the run's final report only read it.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp

from kgarment.case.setup import Case, case_from_problem, protected_faces
from kgarment.case.wearers import Wearer
from kgarment.errors import KgarmentError
from kgarment.garment import Garment
from kgarment.garment.topology import boundary_loops
from kgarment.optimize.beso import one_ring_filter, radius_filter
from kgarment.problem import BesoParams, Problem, solver_options
from kgarment.sim import Motion, SimModel, SolverOptions

__all__ = ["BesoSetup", "DesignSetup", "setup_from_problem"]


@dataclass(frozen=True, kw_only=True)
class BesoSetup:
    """The optimiser's settings, precomputed once for one case.

    params : BesoParams;  filter_matrix : (m, m) CSR sensitivity filter;  evolution_solver :
    the solver options of every iteration after the first (None: the case's; see
    ``kgarment.problem.SolverSpec``);  protected : (m,) bool faces kept reinforced, or None;
    loop_faces : per boundary loop of the garment, the faces touching it
    (:func:`kgarment.optimize.connect.connect_design`);  guard : the step guard's share
    (:mod:`kgarment.optimize.guard`; 0: off);  combine : "sum" or "product" of the motions'
    terms (:mod:`kgarment.optimize.objective`);  path_start : every this many iterations the
    ON states are also solved over their motion from rest (``SolverSpec.path_start``; 0:
    never);  path_frames : for ``path_start``, the evaluator's frames of the motions ({frame:
    Motion} with the rest pose, [(frame, motion, t)]:
    :func:`kgarment.case.frames.frame_motions`), else ();  shares : {motion: its share of
    the objective} (a motion not in it: 1): a motion and the early poses ``[design] early``
    adds for it split one, times the motion's ``[design] weights``.
    """

    params: BesoParams
    filter_matrix: sp.csr_matrix = field(repr=False)
    evolution_solver: SolverOptions | None = None
    protected: np.ndarray | None = None
    loop_faces: tuple[np.ndarray, ...] = field(default=(), repr=False)
    guard: float = 0.0
    combine: str = "sum"
    path_start: int = 0
    path_frames: tuple = field(default=(), repr=False)
    shares: dict[str, float] = field(default_factory=dict)

    @classmethod
    def build(cls, case: Case, params: BesoParams, *, evolution_solver: SolverOptions | None = None,
              protected: np.ndarray | None = None, guard: float = 0.0, combine: str = "sum",
              path_start: int = 0, path_frames: tuple = (), shares: dict[str, float] | None = None) -> BesoSetup:
        """The filter and the boundary loops' faces of ``case``'s garment, with the settings."""
        X, F = case.model.garment_rest, case.model.garment_faces
        if params.filter == "radius":
            filt = radius_filter(X[F].mean(1), case.areas, params.radius)
        else:
            filt = one_ring_filter(F, case.areas, len(X))
        on_vertex = sp.csr_matrix((np.ones(F.size), (F.ravel(), np.repeat(np.arange(len(F)), 3))),
                                  shape=(len(X), len(F)))
        loops = tuple(np.unique(on_vertex[loop].indices) for loop in boundary_loops(F))
        return cls(params=params, filter_matrix=filt, evolution_solver=evolution_solver, protected=protected,
                   loop_faces=loops, guard=float(guard), combine=combine, path_start=int(path_start),
                   path_frames=tuple(path_frames), shares=dict(shares or {}))


@dataclass(frozen=True)
class DesignSetup:
    """A design run's case (the physics: :class:`kgarment.case.Case`) and the optimiser's
    settings (:class:`BesoSetup`)."""

    case: Case
    beso: BesoSetup

    @classmethod
    def build(cls, model: SimModel, motions: dict[str, Motion], objective: str, params: BesoParams,
              solver: SolverOptions, *, evolution_solver: SolverOptions | None = None,
              protected: np.ndarray | None = None, skin_start: bool = False,
              activation: dict[str, np.ndarray] | None = None, lockout: float = 0.0,
              balance: float | dict[str, float] = 0.0, guard: float = 0.0, combine: str = "sum",
              wearers: dict[str, Wearer] | None = None, path_start: int = 0, path_frames: tuple = (),
              shares: dict[str, float] | None = None) -> DesignSetup:
        """:meth:`Case.build` and :meth:`BesoSetup.build` from parts (the fields as there)."""
        case = Case.build(model, motions, objective, solver, skin_start=skin_start, activation=activation,
                          lockout=lockout, balance=balance, wearers=wearers)
        return cls(case, BesoSetup.build(case, params, evolution_solver=evolution_solver, protected=protected,
                                         guard=guard, combine=combine, path_start=path_start,
                                         path_frames=path_frames, shares=shares))

    def with_store(self, store) -> DesignSetup:
        """This setup with its case's equilibria kept in ``store`` (an EquilibriumStore)."""
        return dataclasses.replace(self, case=dataclasses.replace(self.case, store=store))

    def options(self, iteration: int) -> SolverOptions:
        """The solver options of an iteration: the case's for iteration 0 (the fully
        reinforced garment, the reference of rho and of the objective), ``evolution_solver``
        from iteration 1 on, at the target area too (None: the case's; see
        ``kgarment.problem.SolverSpec``)."""
        if self.beso.evolution_solver is not None and iteration > 0:
            return self.beso.evolution_solver
        return self.case.solver

    def judged(self, iteration: int, target: float) -> bool:
        """Whether an iteration's objective counts towards convergence: iteration 0 and every
        iteration at the target area A*; every iteration without an ``evolution_solver``."""
        return self.beso.evolution_solver is None or iteration == 0 or target == self.beso.params.target_area


def setup_from_problem(problem: Problem, body, garment: Garment, strips, device: str = "cpu",
                       specs=None) -> DesignSetup:
    """The design run's setup of ``problem`` on a built body, garment (its attachments are
    held) and clutch strips: its case with the run's solver options (``[solver] tol``; the
    early poses of ``[design] early`` among the motions; :func:`kgarment.case.case_from_problem`,
    ``specs`` as there) and the optimiser's settings (``evolution_tol`` while the target
    shrinks)."""
    case = case_from_problem(problem, body, garment, strips, solver="design", early=True, device=device,
                             specs=specs)
    d = problem.design
    shares = {}
    if d.early or d.weights:
        from kgarment.case.frames import objective_shares

        shares = objective_shares(d.early, d.weights)
    path_start = problem.solver.path_start if d.objective != "passive" else 0
    path_frames: tuple = ()
    if path_start:
        from kgarment.case.frames import frame_motions

        if case.wearers:
            raise KgarmentError("[solver] path_start: the motion from rest is solved on one body; a multi-body "
                                "design ([body] phenotypes) cannot use it")
        path_frames = frame_motions(problem, list(problem.motions), problem.solver.path_frames, rest=True)
    beso = BesoSetup.build(
        case, d.beso, evolution_solver=solver_options(problem, "evolution", device),
        protected=protected_faces(garment, list(case.model.clutches), d.protect_attachments,
                                  d.protect_clutch_margin),
        guard=d.guard, combine=d.combine if d.objective == "active" else "sum",
        path_start=path_start, path_frames=path_frames, shares=shares)
    return DesignSetup(case, beso)
