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
