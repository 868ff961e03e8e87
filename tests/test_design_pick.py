"""Which of two solutions of a state the evaluator (and a skin-start design loop) keeps."""

from __future__ import annotations

import numpy as np
import pytest

from kgarment.case.starts import MULTISTABLE, pick_equilibrium
from kgarment.sim import Convergence, StateResult


def result(energy: float, converged: bool = True, residual: float = 1e-5) -> StateResult:
    conv = Convergence(converged, 10, residual, 1e-4, 0.0, 0.0, 0.1, 11, "newton")
    return StateResult("s", np.zeros((3, 3)), np.zeros(1), np.zeros(1), [], [], {"membrane_garment": energy}, conv)


def test_the_lower_energy_of_two_converged_solutions_is_kept_and_the_other_reported():
    a, b = result(2.0), result(1.0)
    e = pick_equilibrium(a, b)
    assert e.result is b and e.other is a
    # equal to within MULTISTABLE: the first is kept, nothing reported
    c = result(1.0 * (1 + MULTISTABLE / 2))
    e = pick_equilibrium(c, b)
    assert e.result is b and e.other is None
    assert pick_equilibrium(b, result(1.0)).result is b  # a tie keeps the first


def test_a_converged_solution_beats_an_unconverged_one_whatever_its_energy():
    good, bad = result(5.0), result(1.0, converged=False, residual=0.3)
    assert pick_equilibrium(bad, good).result is good and pick_equilibrium(good, bad).result is good
    worse = result(0.5, converged=False, residual=0.9)
    assert pick_equilibrium(bad, worse).result is bad  # neither converged: the lower residual


def test_the_motion_from_rest_replaces_the_two_starts_only_where_clearly_lower():
    """``Evaluator.evaluate(known=...)``: the end of the motion solved from rest (what a
    wearer reaches) is kept where it is converged and lower by more than MULTISTABLE, with
    the two starts' equilibrium reported as the other; closer, higher or unconverged ones
    leave the evaluation as it was."""
    from kgarment.case.starts import Equilibrium, with_known

    starts = Equilibrium(result(24.9))
    e = with_known(starts, result(6.8))
    assert e.result.total_energy == 6.8 and e.other is starts.result and e.from_path
    assert with_known(starts, None) is starts
    assert with_known(starts, result(24.9 * (1 - MULTISTABLE / 2))) is starts  # round-off apart: unchanged
    assert with_known(starts, result(30.0)) is starts  # higher: the starts' stays
    assert with_known(starts, result(1.0, converged=False, residual=0.3)) is starts
    unconverged = Equilibrium(result(5.0, converged=False, residual=0.2))
    e = with_known(unconverged, result(9.0))
    assert e.result.total_energy == 9.0 and e.from_path and e.other is None



def _evaluation(rhos: dict[str, float], off: float = 0.01):
    """A DesignEvaluation with rho ON ``rhos[motion]`` and OFF ``off`` (energies = rho, full = 1)."""
    from kgarment.evaluate.evaluator import DesignEvaluation, StateEvaluation

    states = []
    for m, rho in rhos.items():
        states += [StateEvaluation(motion=m, state=s, rho=r, energy=r, energy_full=1.0, converged=True)
                   for s, r in (("on", rho), ("off", off))]
    return DesignEvaluation(design=np.ones(4, bool), states=tuple(states), area=0.2, islands=3, islands_with_clutches=1,
                            clutch_ends_supported=4, clutch_ends=4)


def test_a_final_design_whose_run_equilibrium_the_evaluator_does_not_reach_is_flagged():
    """``along_run``: per motion, the run's rho ON at the reported iteration against the
    evaluator's; "reached" where the evaluated one is at least (1 - UNREACHED) of the run's
    (the selective sleeve's flexion: 1.093 along the run, 0.563 evaluated).  OFF and lock
    states, and motions the row does not hold, are left out."""
    from kgarment.design.reported import UNREACHED, along_run

    res = _evaluation({"flex": 0.563, "ext": (1 - UNREACHED) * 1.066 + 1e-9, "raise": 2.0})
    row = {"rho[flex:on]": 1.093, "rho[flex:off]": 0.009, "rho[ext:on]": 1.066}
    out = along_run(row, res)
    assert set(out) == {"flex", "ext"}
    assert out["flex"] == {"run": 1.093, "evaluated": 0.563, "reached": False}
    assert out["ext"]["reached"] and out["ext"]["run"] == 1.066
    assert not along_run({"rho[ext:on]": 1.3}, res)["ext"]["reached"]


def _rows(objectives: dict[int, float], area: float = 0.2):
    """Metrics rows: iterations 0..n, the given ones at the target area (0.2) with these
    objectives and rho ON 1.0 in motion "m", the others above it."""
    n = max(objectives) + 1
    return [{"iteration": k, "area": area if k in objectives else 0.5, "objective": objectives.get(k, 9.0),
             "unconverged_states": "", "rho[m:on]": 1.0} for k in range(n)]


def test_the_reported_iteration_is_the_best_objective_the_evaluator_reproduces():
    """``select_reported``: candidates in order of the run's objective; the first whose
    evaluated rho ON keeps (1 - UNREACHED) of the run's is reported, after as many
    evaluations as it took; none of the first CANDIDATES reproduced: the best evaluated
    objective among them (an iteration above the target area is never a candidate)."""
    from types import SimpleNamespace

    from kgarment.design.reported import CANDIDATES, select_reported

    setup = SimpleNamespace(case=SimpleNamespace(objective="active", lockout=0.0), beso=SimpleNamespace(combine="sum"))
    rows = _rows({3: 0.50, 4: 0.49, 5: 0.48, 6: 0.47, 7: 0.46, 8: 0.45})
    asked = []

    def evaluate(rho_of):
        def ev(k):
            asked.append(k)
            return _evaluation({"m": rho_of.get(k, 1.0)})
        return ev

    # the best is reproduced: one evaluation, as before this check
    r = select_reported(rows, 0.2, 0.03, setup, evaluate({}))
    assert (r.iteration, r.reproduced, asked) == (3, True, [3])
    # the best two are not (0.56 of 1.0): the third is reported, after three evaluations
    asked.clear()
    r = select_reported(rows, 0.2, 0.03, setup, evaluate({3: 0.56, 4: 0.6}))
    assert (r.iteration, r.reproduced, asked) == (5, True, [3, 4, 5])
    assert [t["reached"] for t in r.tried] == [False, False, True]
    assert r.tried[0]["along_run"]["m"] == {"run": 1.0, "evaluated": 0.56, "reached": False}
    assert r.tried[0]["evaluated_objective"] == pytest.approx(0.56 - 0.01)  # (E_ON - E_OFF) / E_full
    # none of the first CANDIDATES is: the one of the highest evaluated objective
    asked.clear()
    low = {k: 0.3 + 0.01 * k for k in range(3, 9)}
    low[4] = 0.7
    r = select_reported(rows, 0.2, 0.03, setup, evaluate(low))
    assert asked == [3, 4, 5, 6][:CANDIDATES] and (r.iteration, r.reproduced) == (4, False)
    assert r.evaluation.get("m", "on").rho == 0.7
    # no iteration at the target area: the last one, evaluated
    asked.clear()
    r = select_reported(_rows({2: 0.5}, area=0.5), 0.2, 0.03, setup, evaluate({}))
    assert (r.iteration, asked) == (2, [2])
