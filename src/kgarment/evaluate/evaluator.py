"""The one design evaluator: rho, stored energies and structural metrics of any design.

:class:`Evaluator` holds a :class:`~kgarment.case.Case` built for
evaluation (solver tolerance ``min(tol, EVALUATION_TOL)``), solves the fully reinforced
garment once per state (the reference of rho, docs/method/index.md, "The relative energy density") and evaluates designs
of that garment.  ``kgarment evaluate``, ``kgarment simulate --design``'s report, the
studio, ``kgarment reproduce`` and ``kgarment fabricate`` all evaluate through it, so they
give the same numbers for the same design.

A design's equilibrium in a state (:meth:`Evaluator.solve_design`) is solved from two
starts: the skin-tight garment on the posed body (the garment as put on, like a design
run's first iteration) and the fully reinforced garment's equilibrium (where a design run's
warm-started path begins).  On a subdivided garment of more than
:data:`~kgarment.constants.NESTED_VERTICES` vertices both starts are taken one subdivision
level down, where the cloth's slide round the body costs a fraction of the Newton
iterations, and mapped up (nested iteration, :mod:`kgarment.case.levels`): the garment as
put on is the state's equilibrium there from its own put-on start (:func:`put_on`), the
start along the run's path the design's equilibrium there from that level's start along
the path (:meth:`Evaluator.from_full`); the load states start from theirs
(:func:`kgarment.evaluate.loads.coarse_starts`).  A membrane without bending on a frictionless body can have
several equilibria (the garment settles in different places), and the two starts can
end in different ones: the converged solution of lower total energy, the more stable one,
is kept, and the other is reported when the two differ by more than ``MULTISTABLE``.  A
state that converges from neither start goes on from the end nearer convergence for as
many iterations again; a clutched state that has not converged
then either is solved by :func:`activation_continuation`.  Equilibria found otherwise --
the end of the motion solved from rest (``kgarment evaluate --path``,
:func:`kgarment.evaluate.path.path_forces`), the one a wearer reaches -- compete with the two starts' (``known``): the lowest is kept
and marked ``from_path``.  The measurements behind the two starts: docs/notes/code.md.
"""

from __future__ import annotations

import dataclasses
import functools
from collections import OrderedDict
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from kgarment.case.continuation import activation_continuation
from kgarment.case.keys import Kind, Start, StateKey, key_of
from kgarment.case.levels import prolong, put_on, restrict, states_down
from kgarment.case.setup import Case, case_from_problem
from kgarment.case.starts import (
    Equilibrium,
    pick_equilibrium,
    solve_two_starts,
    with_known,
)
from kgarment.case.store import design_digest, state_digest
from kgarment.errors import Cancelled, KgarmentError, unknown
from kgarment.evaluate.loads import LoadReport, clutch_loads
from kgarment.evaluate.metrics import Stored, relative_energy_density, structure
from kgarment.problem import Problem, build_body, build_clutches, build_garment
from kgarment.sim import SimState, StateResult

KEPT = 64  # design equilibria an Evaluator keeps (the most recently used; :meth:`Evaluator.solve_design`)


@dataclass(frozen=True, kw_only=True)
class StateEvaluation:
    """One (motion, state) of a design.

    motion, state : the key ("on", "off" or "none");  rho : relative energy density;
    energy : J stored in the design's reinforced faces and the clutches;  energy_full : the
    fully reinforced garment's, J;  converged : both equilibria converged;  other_rho : rho
    of a second equilibrium of higher total energy found from another start (None: the
    starts agree);  from_path : the kept equilibrium is the end of the motion from rest
    (``known``), below the two starts';  result : the design's equilibrium (StateResult);
    reference : the full garment's.
    """

    motion: str
    state: str
    rho: float
    energy: float
    energy_full: float
    converged: bool
    other_rho: float | None = None
    from_path: bool = False
    result: StateResult = field(default=None, repr=False, compare=False)
    reference: StateResult = field(default=None, repr=False, compare=False)

    @property
    def key(self) -> StateKey:
        return StateKey(self.motion, self.state)

    @property
    def multistable(self) -> bool:
        return self.other_rho is not None

    def row(self) -> dict:
        """The JSON-ready numbers (no equilibria)."""
        return {"motion": self.motion, "state": self.state, "rho": self.rho, "energy": self.energy,
                "energy_full": self.energy_full, "converged": self.converged, "other_rho": self.other_rho,
                "from_path": self.from_path}


@dataclass(frozen=True, kw_only=True)
class DesignEvaluation:
    """A design on some motions: one StateEvaluation per (motion, state), and its shape.

    design : (m,) bool;  area : reinforced share of the rest area;  islands : parts of the
    reinforcement;  islands_with_clutches : parts when each clutch joins the parts its ends
    sit on;  clutch_ends_supported / clutch_ends : clutch ends on reinforcement / all (over
    every wearer of a multi-body design);  by_wearer : a multi-body design's {wearer:
    {islands_with_clutches, clutch_ends_supported, clutch_ends}} (None for one body).
    """

    design: np.ndarray = field(repr=False)
    states: tuple[StateEvaluation, ...]
    area: float
    islands: int
    islands_with_clutches: int
    clutch_ends_supported: int
    clutch_ends: int
    loads: LoadReport | None = None
    by_wearer: dict | None = None

    @property
    def converged(self) -> bool:
        return all(s.converged for s in self.states)

    def get(self, motion: str, state: str) -> StateEvaluation | None:
        return next((s for s in self.states if s.motion == motion and s.state == state), None)

    def rho(self) -> dict[str, dict[str, float]]:
        """{motion: {state: rho}}."""
        out: dict = {}
        for s in self.states:
            out.setdefault(s.motion, {})[s.state] = s.rho
        return out

    def to_json(self) -> dict:
        return {"rho": self.rho(), "rows": [s.row() for s in self.states], "area": self.area,
                "islands": self.islands, "islands_with_clutches": self.islands_with_clutches,
                "clutch_ends_supported": self.clutch_ends_supported, "clutch_ends": self.clutch_ends,
                "converged": self.converged, **({"by_wearer": self.by_wearer} if self.by_wearer else {}),
                **(self.loads.to_json() if self.loads is not None else {})}


class Evaluator:
    """Evaluates designs of one garment (see the module docstring).

    case : the Case it measures designs of (:func:`kgarment.case.case_from_problem`'s,
    with the evaluation's solver options; ``from_problem`` builds one);
    the fully reinforced equilibria are solved on first need and kept per state, and the
    last :data:`KEPT` design equilibria from the two starts are kept too (by design and
    state content: ``kgarment evaluate --path`` solves the target's equilibria for the
    force over the motion and evaluates the same design there next).
    """

    def __init__(self, case: Case, store=None):
        self.case = case if store is None else dataclasses.replace(case, store=store)
        self._reference: dict[StateKey, StateResult] = {}
        self._kept: OrderedDict[tuple, Equilibrium] = OrderedDict()

    @classmethod
    def from_problem(cls, problem: Problem, *, body=None, garment=None, strips=None, device: str = "cpu",
                     objective: str | None = None, store=None) -> Evaluator:
        """An evaluator of ``problem`` (body, garment and clutches built unless given; the
        garment's ``attached`` faces are held); ``objective`` overrides the problem's
        (``"active"``: every design ON and OFF); ``store``: an EquilibriumStore to keep its
        equilibria in and take them from (``kgarment.case.store``)."""
        body = build_body(problem) if body is None else body
        garment = build_garment(problem, body) if garment is None else garment
        strips = build_clutches(problem, body, garment) if strips is None else strips
        return cls(case_from_problem(problem, body, garment, strips, device=device, objective=objective), store)

    @property
    def motions(self) -> list[str]:
        return list(self.case.motions)

    @property
    def n_faces(self) -> int:
        return self.case.model.n_faces

    def motion_names(self, motions=None) -> list[str]:
        """``motions`` (default: all of the case's), each checked to be one of them; in a
        multi-body design a problem's motion name stands for it on every wearer."""
        out = []
        for m in motions or self.case.motions:
            if m in self.case.motions:
                out.append(m)
                continue
            on_wearers = [k for k, w in self.case.wearers.items() if w.motion == m]
            if not on_wearers:
                raise unknown("motion", m, self.case.motions)
            out += on_wearers
        return list(dict.fromkeys(out))

    def keyed(self, motions=None) -> list[tuple[StateKey, SimState]]:
        """The states of the objective for ``motions`` (default: all)."""
        return self.case.states(self.motion_names(motions))

    def activation_states(self, activation, motions=None, label: str = "") -> list[tuple[StateKey, SimState]]:
        """States of ``motions`` (default: all) under one clutch activation (K,) in [0, 1],
        keyed (motion, ``label``) (default: the values joined by commas)."""
        g = tuple(float(a) for a in activation)
        if len(g) != self.case.n_clutches:
            raise KgarmentError(f"clutch activation has {len(g)} values for {self.case.n_clutches} clutches")
        label = label or ",".join(f"{a:g}" for a in g)
        keys = [StateKey(m, label) for m in self.motion_names(motions)]
        return [(k, SimState.create(self.case.motions[k.motion], g, name=k.name)) for k in keys]

    @functools.cached_property
    def coarser(self) -> Evaluator | None:
        """The evaluator of the same problem one subdivision level down (the case's
        ``coarser``; the same store), or None: its equilibria start this one's (nested
        iteration, :mod:`kgarment.case.levels`)."""
        c = self.case.coarser() if self.case.coarser is not None else None
        return None if c is None else Evaluator(c.case, self.case.store)

    def down(self, design: np.ndarray, keyed: list[tuple[StateKey, SimState]],
             start: Start | None = None) -> tuple[list[int], np.ndarray, list[tuple[StateKey, SimState]]]:
        """``keyed`` states one level down: (the indices of those the coarser evaluator has,
        ``design`` (m,) restricted to its garment, those states keyed there the same way).
        Only with a :attr:`coarser` evaluator; ``start``: the tag of their names there."""
        idx, down = states_down(self.case.coarser(), [s for _, s in keyed], start)
        return idx, restrict(design, self.coarser.n_faces), [(keyed[i][0], s) for i, s in zip(idx, down)]

    def up(self, x: np.ndarray) -> np.ndarray:
        """An equilibrium (N_coarse, 3) of the :attr:`coarser` evaluator's garment as a start
        (N, 3) here."""
        return prolong(self.case, self.case.coarser(), x)

    def from_full(self, design: np.ndarray, keyed: list[tuple[StateKey, SimState]]) -> list[np.ndarray]:
        """Per state the start of ``design``'s solve along a design run's path, which begins at
        the fully reinforced garment: its equilibrium (:meth:`reference`); on a subdivided
        garment the design's equilibrium one level down reached the same way, prolongated
        (nested iteration, :mod:`kgarment.case.levels`; a state the level below lacks: the
        reference)."""
        starts: list = [None] * len(keyed)
        if self.coarser is not None:
            idx, d, low = self.down(design, keyed, Start.FROM_FULL)
            if idx:
                solved = self.coarser.case.solve(d, [s for _, s in low], warm_start=self.coarser.from_full(d, low))
                for i, r in zip(idx, solved):
                    starts[i] = self.up(r.x)
        rest = [i for i, x in enumerate(starts) if x is None]
        for i, r in zip(rest, self.reference([keyed[i] for i in rest]) if rest else []):
            starts[i] = r.x
        return starts

    def reference(self, keyed: list[tuple[StateKey, SimState]]) -> list[StateResult]:
        """The fully reinforced garment's equilibria in ``keyed`` states (solved once each):
        from the garment as put on (:func:`put_on`), and a clutched state also from its motion's OFF
        equilibrium (the garment put on, then the clutches switched on) where that is known;
        the second replaces the first where it is lower by more than :data:`MULTISTABLE`
        (rho's denominator is then the stabler equilibrium, as the design's numerator is)."""
        full = np.ones(self.n_faces)
        todo = [(k, s) for k, s in keyed if k not in self._reference]
        if todo:  # with the OFF states the clutched ones start from (one state at a time: the studio)
            known = set(self._reference) | {k for k, _ in todo}
            offs = {StateKey.off(k[0]) for k, s in todo if s.clutched} - known
            todo += [(k, s) for k, s in self.case.states() if k in offs]
            states = [s for _, s in todo]
            done = self.case.solve(full, states, warm_start=put_on(self.case, full, states))
            self._reference.update({k: r for (k, _), r in zip(todo, done)})
            off = {k[0]: self._reference[k] for k in self._reference if key_of(k).kind is Kind.OFF and self._reference[k].converged}
            again = [(k, s) for k, s in todo if s.clutched and k[0] in off]
            if again:
                second = self.case.solve(full, [s for _, s in again], warm_start=[off[k[0]].x for k, _ in again])
                for (k, _), r in zip(again, second):
                    self._reference[k] = with_known(Equilibrium(self._reference[k]), r).result
        return [self._reference[k] for k, _ in keyed]

    def solve_design(self, design: np.ndarray, keyed: list[tuple[StateKey, SimState]],
                     starts: list[np.ndarray] | None = None) -> list[Equilibrium]:
        """Equilibria of ``design`` (m,) in ``keyed`` states from two starts (module
        docstring): the garment as put on and ``starts`` (per state (N, 3) positions;
        default: :meth:`from_full`, the fully reinforced garment's equilibria on a garment
        without a coarser level).  A fully reinforced design
        returns the reference equilibria.  With the default starts, a state this evaluator
        has solved for the same design (the same values, pose, attachments and activation)
        is not solved again."""
        if starts is not None or np.all(design > 0.5):
            return self._solve_design(design, keyed, starts)
        d = design_digest(design)
        ids = [(d, k, state_digest(s)) for k, s in keyed]
        todo = [i for i, key in enumerate(ids) if key not in self._kept]
        if todo:
            for i, e in zip(todo, self._solve_design(design, [keyed[i] for i in todo])):
                self._kept[ids[i]] = e
        for key in ids:
            self._kept.move_to_end(key)
        out = [dataclasses.replace(self._kept[key], result=dataclasses.replace(self._kept[key].result, name=s.name))
               for key, (_, s) in zip(ids, keyed)]  # under this call's state names
        while len(self._kept) > KEPT:
            self._kept.popitem(last=False)
        return out

    def _solve_design(self, design: np.ndarray, keyed: list[tuple[StateKey, SimState]],
                      starts: list[np.ndarray] | None = None) -> list[Equilibrium]:
        if np.all(design > 0.5):
            return [Equilibrium(r) for r in self.reference(keyed)]
        states = [s for _, s in keyed]
        case = self.case
        starts = self.from_full(design, keyed) if starts is None else list(starts)
        from_starts, cold = solve_two_starts(case, design, states, starts)
        out = [pick_equilibrium(a, b) for a, b in zip(cold, from_starts)]
        slow = [i for i, e in enumerate(out) if not e.result.converged]
        if slow:  # converged from neither start: on from the nearer end, once (a slow slide, measured)
            again = case.go_on(design, [states[i] for i in slow], [out[i].result for i in slow])
            for i, r in zip(slow, again):
                if r.converged or r.convergence.residual < out[i].result.convergence.residual:
                    out[i] = Equilibrium(r)
        todo = [i for i, e in enumerate(out) if not e.result.converged and states[i].clutched]
        if todo:  # the continuation's first step is the motion's OFF state from skin-tight: solved already
            off = {s.motion.name: r for s, r in zip(states, cold) if not s.clutched}
            redone = activation_continuation(case, design, [states[i] for i in todo],
                                             [off.get(states[i].motion.name) for i in todo])
            for i, r in zip(todo, redone):
                if r.converged or r.convergence.residual < out[i].result.convergence.residual:
                    out[i] = pick_equilibrium(r, out[i].result)
        return out

    def equilibria(self, design: np.ndarray, keyed: list[tuple[StateKey, SimState]],
                   starts: list[np.ndarray] | None = None) -> list[StateResult]:
        """The kept equilibrium of :meth:`solve_design` per state."""
        return [e.result for e in self.solve_design(design, keyed, starts)]

    def evaluate(self, design: np.ndarray, motions=None, *, loads: bool = False,
                 report: Callable[[str], None] | None = None,
                 cancelled: Callable[[], bool] | None = None,
                 known: dict[StateKey, StateResult] | None = None) -> DesignEvaluation:
        """Evaluate ``design`` (m,) (> 0.5 = reinforced) on ``motions`` (default: all).

        All states are solved together (in worker processes when the solver has them);
        with ``report`` or ``cancelled`` (the studio) one state at a time instead:
        ``report(text)`` before each solve, ``cancelled()`` checked between solves (raises
        :class:`Cancelled`).  The numbers are the same either way.  ``loads``: also the
        per-clutch load report (:func:`kgarment.evaluate.loads.clutch_loads`; clutched
        objectives only).  ``known``: {(motion, state): StateResult} equilibria of this design
        found otherwise (the last frames of :func:`kgarment.evaluate.path.path_forces`), kept
        where they are lower than the two starts' (module docstring).
        """
        design = np.asarray(design, dtype=np.float64)
        if design.shape != (self.n_faces,):
            raise KgarmentError(f"the design has {design.size} faces, the garment {self.n_faces}")
        keyed = self.keyed(motions)
        if report is None and cancelled is None:
            pairs = list(zip(self.reference(keyed), self.solve_design(design, keyed)))
        else:
            pairs = [self._one(design, k, i, len(keyed), report, cancelled) for i, k in enumerate(keyed)]
        known = known or {}
        pairs = [(rf, with_known(eq, known.get(k))) for (k, _), (rf, eq) in zip(keyed, pairs)]
        ev = self._summarise(design, keyed, pairs)
        return self.with_loads(ev, design) if loads else ev

    def with_loads(self, ev: DesignEvaluation, design: np.ndarray) -> DesignEvaluation:
        """``ev``, this evaluator's evaluation of ``design`` (m,), with the per-clutch load
        report (:func:`kgarment.evaluate.loads.clutch_loads`, from its ON and OFF equilibria;
        clutched objectives only, else ``ev`` as it is)."""
        if not self.case.n_clutches or self.case.objective == "passive":
            return ev
        known = {s.key: s.result for s in ev.states if s.key.kind in (Kind.ON, Kind.OFF)}
        motions = list(dict.fromkeys(s.motion for s in ev.states))
        return dataclasses.replace(ev, loads=clutch_loads(self, np.asarray(design, dtype=np.float64), motions, known))

    def _one(self, design, keyed_state, i: int, n: int, report, cancelled) -> tuple[StateResult, Equilibrium]:
        """The reference and the design's equilibrium of one state, reporting and checking
        for a stop request before each solve."""
        (motion, state), _ = keyed_state
        for k, what in enumerate(("fully reinforced garment", "design")):
            if cancelled is not None and cancelled():
                raise Cancelled()
            if report is not None:
                report(f"{what}, {motion} {state} ({2 * i + 1 + k}/{2 * n})")
            if k == 0:
                full = self.reference([keyed_state])[0]
        return full, self.solve_design(design, [keyed_state])[0]

    def _summarise(self, design, keyed, pairs) -> DesignEvaluation:
        case = self.case
        clutched = case.objective != "passive"
        solid = design > 0.5
        rows = []
        for ((motion, state), _), (rf, eq) in zip(keyed, pairs):
            sf, sd = Stored.of(rf, clutched), Stored.of(eq.result, clutched)
            areas, c_area = case.areas_of(motion), case.clutch_area_of(motion)
            rho = relative_energy_density(design, areas, sd, sf, c_area)
            other = None if eq.other is None else \
                relative_energy_density(design, areas, Stored.of(eq.other, clutched), sf, c_area)
            rows.append(StateEvaluation(
                motion=motion, state=state, rho=rho, energy=float(sd.face_energy[solid].sum() + sd.clutch_energy),
                energy_full=float(sf.face_energy.sum() + sf.clutch_energy),
                converged=bool(rf.converged and eq.result.converged), other_rho=other, from_path=eq.from_path,
                result=eq.result, reference=rf))
        shape = structure(case, design)
        return DesignEvaluation(
            design=solid, states=tuple(rows), area=float(case.areas[solid].sum() / case.areas.sum()),
            islands=shape["islands"], islands_with_clutches=shape["islands_with_clutches"],
            clutch_ends_supported=shape["clutch_ends_supported"], clutch_ends=shape["clutch_ends"],
            by_wearer=shape.get("by_wearer"))
