"""The solvable problem on a body: the garment and clutches as a simulator model, the
motions, the states they are solved in, and the equilibria's store.

A :class:`Case` is built once (:func:`case_from_problem` for a problem, :meth:`Case.build`
from parts) and only read afterwards: the evaluator (:mod:`kgarment.evaluate`) measures
designs of it, the optimiser (:mod:`kgarment.optimize`) adds its own settings beside it.
"""

from __future__ import annotations

import dataclasses
import functools
import logging
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp

from kgarment import constants
from kgarment.case.keys import Kind, StateKey, format_label
from kgarment.case.levels import Coarser, level_problem, vertex_map
from kgarment.case.states import LOCK, SOLO, states_needed
from kgarment.case.store import shared_store
from kgarment.case.wearers import ClutchEnds, Wearer, clutch_ends, wearer_motions
from kgarment.errors import KgarmentError
from kgarment.garment import Garment
from kgarment.garment.topology import face_adjacency, triangle_areas
from kgarment.problem import (
    Problem,
    build_clutches,
    build_garment,
    build_model,
    solver_options,
)
from kgarment.problem.spec import balance_weight
from kgarment.sim import Motion, SimModel, SimState, SolverOptions, garment_motions, solve_states

log = logging.getLogger(__name__)

__all__ = ["LOCK", "SOLO", "Case", "StateKey", "activation_vectors", "case_from_problem", "protected_faces"]


@dataclass(frozen=True, kw_only=True)
class Case:
    """A garment with its clutches on a body, its motions and the states they are solved in.

    model : SimModel (garment + clutches);  motions : {name: Motion};  objective : which
    states each motion is solved in ("active": ON and OFF, "compliance": ON, "passive":
    none; :func:`kgarment.case.states.states_needed`);  solver : SolverOptions of its solves;
    areas : (m,) rest face areas, m^2;  adjacency : (m, m) CSR face adjacency;  ends : one
    ClutchEnds per clutch;  clutch_area : total rest area of the clutches, m^2 (0 for the
    passive objective);  attached : (a,) attachment faces;  skin_start : also solve from the
    skin-tight start (``SolverSpec.skin_start``);  activation : {motion: (K,) activation in
    [0, 1] of its ON state} ([motions.activation]; a motion not in it switches every clutch
    on);  lockout : > 0 adds, for every motion, the motion under each other motion's set
    (``lock:`` states);  balance : one number for every motion, or {motion: weight} (a motion
    not in it: 0): > 0 adds, for a set of two clutches or more, the motion with each clutch
    of its set alone ON (``solo:`` states);  wearers : {motion: Wearer} of a multi-body case
    (every motion ``MOTION@BODY``; {} for one body: ``model`` and ``areas`` serve all);
    store : an EquilibriumStore (:mod:`kgarment.case.store`) or None;  coarser : () -> the
    same case one subdivision level down (:class:`kgarment.case.levels.Coarser`) or None.
    """

    model: SimModel
    motions: dict[str, Motion]
    objective: str
    solver: SolverOptions
    areas: np.ndarray = field(repr=False)
    adjacency: sp.csr_matrix = field(repr=False)
    ends: tuple[ClutchEnds, ...] = ()
    clutch_area: float = 0.0
    attached: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64), repr=False)
    skin_start: bool = False
    activation: dict[str, np.ndarray] = field(default_factory=dict, repr=False)
    lockout: float = 0.0
    balance: float | dict[str, float] = 0.0
    wearers: dict[str, Wearer] = field(default_factory=dict, repr=False)
    store: object = field(default=None, repr=False, compare=False)  # EquilibriumStore (case.store) or None
    coarser: Callable[[], Coarser | None] | None = field(default=None, repr=False, compare=False)

    @classmethod
    def build(cls, model: SimModel, motions: dict[str, Motion], objective: str, solver: SolverOptions, *,
              skin_start: bool = False, activation: dict[str, np.ndarray] | None = None, lockout: float = 0.0,
              balance: float | dict[str, float] = 0.0, wearers: dict[str, Wearer] | None = None) -> Case:
        """Precompute areas, adjacency and clutch ends for ``model`` (the garment on the body
        it is cut from; ``wearers``: a multi-body case's, see the class doc)."""
        X, F = model.garment_rest, model.garment_faces
        clutch_area = sum(float(triangle_areas(c.vertices, c.faces).sum()) for c in model.clutches)
        attached = np.unique(np.concatenate([np.asarray(m.attach_faces) for m in motions.values()] or [[]]))
        return cls(model=model, motions=dict(motions), objective=objective, solver=solver,
                   areas=triangle_areas(X, F), adjacency=face_adjacency(F), ends=tuple(clutch_ends(model)),
                   clutch_area=clutch_area if objective != "passive" else 0.0, attached=attached.astype(np.int64),
                   skin_start=skin_start,
                   activation={m: np.asarray(g, dtype=np.float64) for m, g in (activation or {}).items()},
                   lockout=float(lockout),
                   balance=dict(balance) if isinstance(balance, dict) else float(balance),
                   wearers=dict(wearers or {}))

    def model_of(self, motion: str) -> SimModel:
        """The SimModel ``motion`` is solved on (its wearer's garment)."""
        w = self.wearers.get(motion)
        return self.model if w is None else w.model

    def areas_of(self, motion: str) -> np.ndarray:
        """(m,) rest face areas of ``motion``'s wearer, m^2 (rho's normalisation)."""
        w = self.wearers.get(motion)
        return self.areas if w is None else w.areas

    def clutch_area_of(self, motion: str) -> float:
        """Total rest area of ``motion``'s wearer's clutches, m^2 (rho's normalisation)."""
        w = self.wearers.get(motion)
        return self.clutch_area if w is None else w.clutch_area

    def solve(self, design: np.ndarray, states, warm_start=None, options: SolverOptions | None = None) -> list:
        """:func:`kgarment.sim.solve_states` of ``states`` (SimState list; warm_start and
        options as there, options default ``self.solver``), each on its motion's wearer's model;
        through ``store`` where there is one (a solve done before is read back, not repeated);
        the fully reinforced garment's also through the machine's shared store
        (:func:`kgarment.case.store.shared_store`: every run of the same problem needs them)."""
        options = self.solver if options is None else options
        shared = None
        if np.all(np.asarray(design) == 1.0):  # the fully reinforced garment: the same in every run
            shared = shared_store()
        if self.store is not None:
            return self.store.solve(self, design, list(states), warm_start, options, also=shared)
        if shared is not None:
            return shared.solve(self, design, list(states), warm_start, options)
        return self.solve_now(design, states, warm_start, options)

    def go_on(self, design: np.ndarray, states, stopped, options: SolverOptions | None = None) -> list:
        """:meth:`solve` of ``states`` (SimState list) from where their unconverged solutions
        ``stopped`` (StateResult list) ended, for as many iterations again: a garment still
        sliding keeps its progress (measured, ``benchmarks/README.md``); logged."""
        states = list(states)
        log.info("%d state(s) go on from where they stopped: %s", len(states), ", ".join(s.name for s in states))
        return self.solve(design, states, warm_start=[r.x for r in stopped], options=options)

    def solve_now(self, design: np.ndarray, states, warm_start, options: SolverOptions) -> list:
        """:meth:`solve` without the store."""
        models = [self.model_of(s.motion.name) for s in states]
        return solve_states(models if self.wearers else self.model, design, states, warm_start=warm_start,
                            options=options)

    @property
    def n_clutches(self) -> int:
        return len(self.model.clutches)

    @property
    def end_faces(self) -> list[tuple[np.ndarray, np.ndarray]]:
        """[(faces under end A, faces under end B)] per clutch (the metrics' links)."""
        return [(e.a, e.b) for e in self.ends]

    def wearer_end_faces(self) -> dict[str, list[tuple[np.ndarray, np.ndarray]]]:
        """{wearer: :attr:`end_faces` on that wearer's body} ({"": end_faces} for one body)."""
        if not self.wearers:
            return {"": self.end_faces}
        out: dict = {}
        for w in self.wearers.values():
            out.setdefault(w.name, [(e.a, e.b) for e in w.ends])
        return out

    @property
    def all_end_faces(self) -> list[tuple[np.ndarray, np.ndarray]]:
        """Every wearer's clutch ends (the connected update keeps each on reinforcement)."""
        return [e for ends in self.wearer_end_faces().values() for e in ends]

    def end_partners(self) -> list[np.ndarray] | None:
        """Per entry of :attr:`all_end_faces`, the entries whose clutches are switched on
        together with it in some motion's ON set, on the same wearer (the only clutches the
        connected update may pass between its ends and an anchor: an OFF clutch is
        compliant); None when every motion switches every clutch on (all of them)."""
        if not self.selective():
            return None
        on = np.array([self.on_activation(m) > 0 for m in self.motions])  # (motions, K)
        together = (on[:, :, None] & on[:, None, :]).any(axis=0)
        np.fill_diagonal(together, False)
        k = self.n_clutches
        return [w * k + np.flatnonzero(together[j]) for w in range(len(self.all_end_faces) // max(k, 1))
                for j in range(k)]

    def on_activation(self, motion: str) -> np.ndarray:
        """(K,) the activation of ``motion``'s ON state: its set, or every clutch."""
        g = self.activation.get(motion)
        return np.ones(self.n_clutches) if g is None else g

    def selective(self) -> bool:
        """Whether some motion switches on other clutches than all."""
        return any(not np.all(self.on_activation(m) == 1.0) for m in self.motions)

    def states(self, motions=None) -> list[tuple[StateKey, SimState]]:
        """[((motion, state), SimState)] the objective needs, for ``motions`` (default all):
        ON (the motion's activation set), OFF, or none; with a lockout, the motion under
        every other set than its own, each set once, named by the first motion that has it
        (``lock:OTHER``: ``[design] early`` poses share their motion's set); with a balance
        and a set of two clutches or more, the motion with each clutch of its set alone ON at
        its set's value (``solo:CLUTCH``)."""
        out = []
        for name in motions or self.motions:
            for s in states_needed(self.objective):
                key = StateKey(name, s)
                g = self.on_activation(name) if key.kind is Kind.ON else np.zeros(self.n_clutches)
                out.append((key, SimState.create(self.motions[name], g, name=key.name)))
            if self.objective == "active" and self.lockout > 0:
                seen = [self.on_activation(name)]  # each other set once (an early pose shares its motion's)
                for other in self.motions:
                    g = self.on_activation(other)
                    if not any(np.array_equal(g, h) for h in seen) and self._same_wearer(name, other):
                        seen.append(g)
                        key = StateKey.lock(name, other)
                        out.append((key, SimState.create(self.motions[name], g, name=key.name)))
            for label, g in self.solo_activations(name):
                key = StateKey(name, label)
                out.append((key, SimState.create(self.motions[name], g, name=key.name)))
        return out

    def _same_wearer(self, a: str, b: str) -> bool:
        wa, wb = self.wearers.get(a), self.wearers.get(b)
        return wa is None or wb is None or wa.name == wb.name

    def solo_activations(self, motion: str) -> list[tuple[str, np.ndarray]]:
        """[(``solo:CLUTCH``, (K,) activation)] for the balance reward of ``motion``: each
        clutch of its set alone ON; none without a balance or with fewer than two clutches."""
        own = self.on_activation(motion)
        on = np.flatnonzero(own > 0)
        if self.objective != "active" or balance_weight(self.balance, motion) <= 0 or len(on) < 2:
            return []
        out = []
        for k in on:
            g = np.zeros(self.n_clutches)
            g[k] = own[k]
            out.append((format_label(Kind.SOLO, self.model.clutches[k].name), g))
        return out

def case_from_problem(problem: Problem, body, garment: Garment, strips, *, solver: str = "evaluate",
                      early: bool = False, device: str = "cpu", objective: str | None = None,
                      specs=None) -> Case:
    """The case of ``problem`` on a built body, garment (its attachments are held) and clutch
    strips, for the problem's motions; with ``[body] phenotypes``, for every wearer's
    (:mod:`kgarment.case.wearers`; ``specs``: the clutch specs the strips were built from,
    default the problem's).

    solver : which of the problem's solver options its solves use
    (:func:`kgarment.problem.solver_options`: "evaluate", ``min(tol, EVALUATION_TOL)``,
    for measuring designs; "design", ``[solver] tol``, for a design run's iteration 0);
    early : add the beginnings of motions that ``[design] early`` names (more states of a
    design run's objective);  objective : overrides the problem's (the reproduction
    evaluates every design ON and OFF).
    """
    if objective is not None and objective != problem.design.objective:
        problem = dataclasses.replace(problem, design=dataclasses.replace(problem.design, objective=objective))
    d = problem.design
    model = build_model(problem, garment, strips)
    options = solver_options(problem, solver, device)
    motions = garment_motions(body, garment, problem.motions)
    activation = activation_vectors(problem, [c.name for c in model.clutches])
    wearers = None
    if problem.body.phenotypes:
        motions, activation, wearers = wearer_motions(problem, body, garment, strips, model, motions,
                                                      activation=activation, specs=specs)
    if early and d.early:  # the beginnings of motions: more states of the objective
        from kgarment.case.frames import early_motions, early_name

        motions = {**motions, **early_motions(problem)}
        activation = {**activation, **{early_name(m, t): activation[m] for m, t in d.early if m in activation}}
    active = d.objective == "active"
    case = Case.build(model, motions, d.objective, options, skin_start=problem.solver.skin_start,
                      activation=activation, wearers=wearers, lockout=d.lockout if active else 0.0,
                      balance={m: d.balance_of(m) for m in motions} if active else 0.0)
    if problem.garment.subdivision > 0 and not wearers and model.n_garment > constants.NESTED_VERTICES:
        case = dataclasses.replace(case, coarser=functools.cache(functools.partial(
            _coarser, problem, body, case.model, solver=solver, early=early, device=device, objective=objective)))
    return case


def _coarser(problem: Problem, body, model: SimModel, *, solver: str, early: bool, device: str,
             objective: str | None) -> Coarser | None:
    """``problem``'s case one subdivision level below its garment's (built on ``body``; its
    own coarser level with it), and the map up to ``model``'s garment; None where the coarse
    garment cannot carry the clutches (logged)."""
    level = problem.garment.subdivision - 1
    low = level_problem(problem, level)
    garment = build_garment(low, body)
    try:
        strips = build_clutches(low, body, garment)
    except KgarmentError as exc:
        log.info("no coarser start at subdivision %d: %s", level, exc)
        return None
    case = case_from_problem(low, body, garment, strips, solver=solver, early=early, device=device,
                             objective=objective)
    return Coarser(level, case, vertex_map(garment.faces, garment.n_vertices, model.n_faces))


def activation_vectors(problem: Problem, names: list[str]) -> dict[str, np.ndarray]:
    """{motion: (K,) activation} from ``problem``'s [motions.activation], the clutches in the
    order ``names``; a clutch the file does not name stays off.  An unknown clutch name ->
    KgarmentError naming the motion and the clutches there are."""
    out = {}
    for motion in problem.motions:
        v = problem.activation_of(motion)
        if v is None:
            continue
        if not names:
            raise KgarmentError(f"[motions.activation] {motion}: the problem has no clutches to switch")
        bad = [n for n in v if n not in names]
        if bad:
            raise KgarmentError(f"[motions.activation] {motion}: unknown clutch {bad[0]!r}; "
                                f"the clutches are: {', '.join(names)}")
        out[motion] = np.array([v.get(n, 0.0) for n in names])
    return out


def protected_faces(garment: Garment, strips, attachments: bool, margin: float) -> np.ndarray | None:
    """(m,) bool faces kept reinforced: attachment rings and/or faces whose centroid is
    within ``margin`` metres of a clutch anchor; None when nothing is protected."""
    keep = garment.attached.copy() if attachments else np.zeros(garment.n_faces, bool)
    if margin > 0 and strips:
        cent = garment.rest_vertices[garment.faces].mean(axis=1)
        anchors = np.concatenate([c.vertices[c.anchors] for c in strips])
        d = np.linalg.norm(cent[:, None, :] - anchors[None, :, :], axis=2).min(axis=1)
        keep |= d <= margin
    return keep if keep.any() else None
