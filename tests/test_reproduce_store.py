"""An interrupted reproduction goes on from the solves it had done: the reproduction's
evaluator keeps every solve in ``OUT/runs/equilibria`` (kgarment.case.store), so an
evaluation or a force over the motion that did not reach the JSON cache is made again by
reading its solves back, to the last digit."""

from __future__ import annotations

import tomllib

import numpy as np
from tiny_problems import TINY_SLEEVE

from kgarment.problem import parse_problem
from kgarment.reproduce.evaluate import CachedEvaluator, EvaluationCache

PROBLEM = TINY_SLEEVE + "[solver]\nworkers = 1\n"


def test_a_path_made_again_reads_its_solves_back(tmp_path):
    problem = parse_problem(tomllib.loads(PROBLEM))
    first = CachedEvaluator(problem, "tiny", EvaluationCache(tmp_path / "evaluations.json"))
    design = np.ones(first.evaluator.n_faces)
    design[::3] = first.evaluator.case.model.preset.x_min
    made = first.path(design, 3)
    assert first.evaluator.case.store.hits == 0 and first.evaluator.case.store.misses > 0
    assert any((tmp_path / "runs" / "equilibria").glob("*.npz"))
    # the process stopped before the JSON cache was written: a new one finds none
    (tmp_path / "evaluations.json").unlink(missing_ok=True)
    again = CachedEvaluator(problem, "tiny", EvaluationCache(tmp_path / "evaluations.json"))
    assert again.path(design, 3) == made
    store = again.evaluator.case.store
    assert store.misses == 0 and store.hits == first.evaluator.case.store.misses
