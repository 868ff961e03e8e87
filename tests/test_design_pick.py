"""Which of two solutions of a state the evaluator (and a skin-start design loop) keeps."""

from __future__ import annotations

import numpy as np

from kgarment.design.evaluate import MULTISTABLE, pick_equilibrium
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
    from kgarment.design.evaluate import Equilibrium, with_known

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


def test_a_final_design_whose_run_equilibrium_the_evaluator_does_not_reach_is_flagged():
    """``along_run``: per motion, the run's rho ON at the reported iteration against the
    evaluator's; "reached" where the evaluated one is at least (1 - UNREACHED) of the run's
    (the selective sleeve's flexion: 1.093 along the run, 0.563 evaluated).  OFF and lock
    states, and motions the row does not hold, are left out."""
    from kgarment.design.driver import UNREACHED, along_run
    from kgarment.design.evaluate import DesignEvaluation, StateEvaluation

    def state(motion, kind, rho):
        return StateEvaluation(motion, kind, rho, rho, 1.0, True)

    res = DesignEvaluation(np.ones(4, bool), (
        state("flex", "on", 0.563), state("flex", "off", 0.01), state("flex", "lock:ext", 0.04),
        state("ext", "on", (1 - UNREACHED) * 1.066 + 1e-9), state("ext", "off", 0.01),
        state("raise", "on", 2.0)), 0.2, 3, 1, 4, 4)
    row = {"rho[flex:on]": 1.093, "rho[flex:off]": 0.009, "rho[ext:on]": 1.066}
    out = along_run(row, res)
    assert set(out) == {"flex", "ext"}
    assert out["flex"] == {"run": 1.093, "evaluated": 0.563, "reached": False}
    assert out["ext"]["reached"] and out["ext"]["run"] == 1.066
    assert along_run(row, res)["ext"]["reached"] and not along_run({"rho[ext:on]": 1.3}, res)["ext"]["reached"]
