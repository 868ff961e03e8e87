"""Which iteration a run reports: the best objective at the target area that the one design
evaluator reproduces.

A design run reads every iteration's states warm from the iteration before, to the design
tolerance (``[solver] evolution_tol``).  Where a state has several equilibria -- a sleeve that
holds against the bent elbow or turns about the arm -- that continuation can hold one the
evaluator, solving the design from the garment as put on and from the fully reinforced
garment's equilibrium to :data:`~kgarment.constants.EVALUATION_TOL`, does not reach: the
run's best objective is then a number no user measures.

:func:`select_reported` walks the iterations at the target area whose states all converged
in order of objective (:func:`kgarment.design.run.ranked_iterations`), evaluates each, and
reports the first whose every motion keeps at least (1 - :data:`UNREACHED`) of the run's rho
ON as evaluated (:func:`along_run`).  After :data:`CANDIDATES` without one it reports the
candidate of the highest objective as evaluated (:func:`evaluated_objective`).  A run whose
best iteration the evaluator reproduces -- the usual case -- costs nothing more: that
evaluation is the final one.
"""

from __future__ import annotations

import logging
from collections.abc import Callable
from dataclasses import dataclass

from kgarment.case.keys import RHO, Kind, StateKey, state_column
from kgarment.design.run import ranked_iterations
from kgarment.optimize.objective import combined_objective, objective_terms

log = logging.getLogger(__name__)

UNREACHED = 0.2  # a motion's rho ON evaluated this much (relative) below the run's own is not reproduced
CANDIDATES = 4  # iterations at the target area evaluated at most before the best evaluated one is reported


def along_run(row: dict, res) -> dict[str, dict]:
    """Per motion of ``res`` (DesignEvaluation) whose ON state the run's metrics ``row``
    also holds: {"run": rho ON along the run, "evaluated": the evaluator's, "reached": the
    evaluated one is at least (1 - :data:`UNREACHED`) of the run's}."""
    out = {}
    for s in res.states:
        key = state_column(RHO, StateKey.on(s.motion))
        if s.key.kind is Kind.ON and key in row:
            out[s.motion] = {"run": float(row[key]), "evaluated": float(s.rho),
                             "reached": bool(s.rho >= (1.0 - UNREACHED) * float(row[key]))}
    return out


def evaluated_objective(setup, res) -> float:
    """The run's objective (``setup``: its DesignSetup) from the evaluated energies of
    ``res`` (DesignEvaluation): its motions only (not ``[design] early``'s poses, which the
    evaluator does not solve), without ``balance`` (no ``solo:`` states), each counting equally."""
    energy = {(s.motion, s.state): s.energy for s in res.states}
    reference = {(s.motion, s.state): s.energy_full for s in res.states}
    motions = list(dict.fromkeys(s.motion for s in res.states))
    terms = objective_terms(setup.case.objective, energy, reference, motions, setup.case.lockout, 0.0)
    return float(combined_objective(setup.beso.combine, terms))


@dataclass(frozen=True)
class Reported:
    """The reported iteration and how it was chosen.

    iteration : the reported one;  evaluation : its DesignEvaluation (without loads);  tried :
    per candidate evaluated, in order, {"iteration", "objective" (the run's),
    "evaluated_objective", "along_run" (:func:`along_run`), "reached"};  reproduced : the
    reported one was reached (False: none of the candidates was; the best evaluated is
    reported).
    """

    iteration: int
    evaluation: object
    tried: tuple[dict, ...]
    reproduced: bool

    @property
    def along_run(self) -> dict[str, dict]:
        """:func:`along_run` of the reported iteration."""
        return next(t["along_run"] for t in self.tried if t["iteration"] == self.iteration)

    def to_json(self) -> dict:
        return {"iteration": self.iteration, "reproduced": self.reproduced, "candidates": list(self.tried)}


def select_reported(rows: list[dict], target: float, er: float, setup,
                    evaluate: Callable[[int], object], candidates: int = CANDIDATES) -> Reported:
    """The iteration to report among the run's metrics ``rows`` (target area ``target``,
    BESO's ``er``), ``evaluate(k)`` giving iteration k's DesignEvaluation; ``setup`` the run's DesignSetup (for the evaluated objective).
    A run with no iteration at the target reports its last one, evaluated, as before."""
    by_iteration = {int(r["iteration"]): r for r in rows}
    ranked = ranked_iterations(rows, target, er)[:max(1, candidates)] or [int(rows[-1]["iteration"])]
    tried, results = [], {}
    for k in ranked:
        results[k] = res = evaluate(k)
        run = along_run(by_iteration[k], res)
        reached = all(v["reached"] for v in run.values())
        tried.append({"iteration": k, "objective": float(by_iteration[k]["objective"]),
                      "evaluated_objective": evaluated_objective(setup, res), "along_run": run, "reached": reached})
        if reached:
            return Reported(k, res, tuple(tried), True)
        lost = ", ".join(f"{m} {v['evaluated']:.3g} (run {v['run']:.3g})" for m, v in run.items() if not v["reached"])
        log.warning("iteration %d: the evaluator does not reach the run's equilibrium: rho ON %s", k, lost)
    best = max(tried, key=lambda t: t["evaluated_objective"])
    log.warning("none of the %d best iterations at the target area is reproduced by the evaluator; reporting "
                "iteration %d, the highest objective as evaluated (%.4g)", len(tried), best["iteration"],
                best["evaluated_objective"])
    return Reported(best["iteration"], results[best["iteration"]], tuple(tried), False)
