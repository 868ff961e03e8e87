"""The paper's design experiments, their resolutions, and the runs behind them.

Every experiment is one example problem under ``examples/`` (its budget from the paper; docs/method/index.md)
with the paper's numbers beside it.  A resolution overrides the garment subdivision and,
for the quick ones, the BESO step sizes:

* ``tiny``: subdivision 0, 3 BESO iterations with 20% steps, 2 random seeds (the test
  suite's smoke run; the designs are not converged and mean nothing);
* ``preview``: subdivision 0, evolution ratio 3% (the paper's 1.5% doubled, so about 65
  iterations to a 15% budget) with the paper's 1.5% of faces added per iteration, at most
  120 iterations, 10 random seeds;
* ``default``: the example files as they are (subdivision 1, the paper's 1.5% steps).

Design runs live in ``OUT/runs/<experiment>`` (ours), ``OUT/runs/<experiment>-compliance``
(the compliance baseline) and, for an experiment with activation sets, ``OUT/runs/<experiment>-all-on``
(the same problem with every clutch ON: :func:`all_on_problem`): ordinary run folders, resumed
where they stopped, reused when finished.
"""

from __future__ import annotations

import dataclasses
import json
import logging
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from kgarment.case.values import design_values
from kgarment.design import finish, load_design_history, open_run, run_status
from kgarment.design.run import best_iteration, final_iteration
from kgarment.errors import KgarmentError
from kgarment.optimize.beso import expected_iterations
from kgarment.problem import Problem, example_path, load_problem, override
from kgarment.reproduce.catalog import (
    BY_NAME,
    DATA,
    EXPERIMENTS,
    MULTI_OF_GROUP,
    PAPER_SHIRT_MATRIX,
    RESOLUTIONS,
    Experiment,
    Resolution,
    select,
)

__all__ = ["BY_NAME", "DATA", "EXPERIMENTS", "MULTI_OF_GROUP", "PAPER_SHIRT_MATRIX", "RESOLUTIONS", "Experiment",
           "Resolution", "RunOutcome", "all_on_problem", "best_iteration", "design_run", "experiment_problem",
           "select"]
log = logging.getLogger(__name__)


PAPER_BUCKLE = False  # the paper's clutch strips resist being shortened as stiffly as being stretched
PAPER_CLUTCH_MODEL = "locked"  # the paper's ON clutches never slip


def experiment_problem(exp: Experiment, res: Resolution, objective: str = "active",
                       overrides: dict | None = None) -> Problem:
    """The example problem of ``exp`` at resolution ``res`` (and with ``objective``, and the
    problem ``overrides`` of :func:`kgarment.problem.override` -- the material ``preset``,
    the ``clutch_model``, the ``holding_force``, ``buckle``, ``channel`` -- where given; the balance term
    belongs to the active objective and is dropped for the others).  The clutch strips of
    the paper's experiments are the paper's (:data:`PAPER_BUCKLE`) unless the overrides say
    ``buckle``: the example files' buckling strips are for designing garments, the
    reproduction reproduces the paper's model (README, "Clutches that buckle"); so are their
    clutches (:data:`PAPER_CLUTCH_MODEL`) where an example file names another model and the
    overrides give no clutch model or holding force.  An experiment of ours
    (``exp.papers_model`` False: the selective sleeve) keeps its example's clutches and
    strips unless the overrides name them: the paper has no such experiment to compare
    with, and its target (no motion locked by another motion's clutch) is about what a real
    clutch does, which a band that resists being shortened does not."""
    overrides = dict(overrides or {})
    source = load_problem(example_path(exp.name))
    if exp.papers_model and overrides.get("buckle") is None:
        overrides["buckle"] = PAPER_BUCKLE
    if (exp.papers_model and overrides.get("clutch_model") is None and overrides.get("holding_force") is None
            and source.clutch_spec().hardware.model != PAPER_CLUTCH_MODEL):
        overrides["clutch_model"] = PAPER_CLUTCH_MODEL
    p = override(source, **overrides)
    g, d = p.garment, p.design
    if res.subdivision is not None:
        g = dataclasses.replace(g, subdivision=res.subdivision)
    changes = {}
    if res.er is not None:
        changes.update(er=res.er, ar_max=res.er if res.ar_max is None else res.ar_max)
    if res.max_iterations is not None:
        changes["max_iterations"] = res.max_iterations
    if res.window is not None:
        changes["window"] = res.window
    beso = dataclasses.replace(d.beso, **changes)
    balance = d.balance if objective == "active" else 0.0
    return dataclasses.replace(p, garment=g, design=dataclasses.replace(d, objective=objective, beso=beso,
                                                                        balance=balance))


def all_on_problem(problem: Problem) -> Problem:
    """``problem`` with every clutch ON in every motion: its ``[motions.activation]`` sets
    and their ``lockout`` dropped (the design a selective one is compared with, made with
    the same clutches)."""
    return dataclasses.replace(problem, activation=(), design=dataclasses.replace(problem.design, lockout=0.0))


@dataclass
class RunOutcome:
    """A finished design run: folder, chosen design (m,) and its iteration, the last
    iteration's design (m,), metrics rows, wall time (s)."""

    run: Path
    design: np.ndarray
    iteration: int
    last: np.ndarray
    metrics: list
    seconds: float


def design_run(problem: Problem, folder: Path, device: str = "cpu",
               progress: Callable[[str, dict, int], None] | None = None, evaluator=None,
               path_frames: int = 0) -> RunOutcome:
    """Run (or resume, or reuse) the design of ``problem`` in ``folder``; ``progress(run folder's
    name, metrics row, expected iterations)`` after every iteration.  With ``evaluator`` (an
    Evaluator of the problem) the run ends as ``kgarment design`` does: its final design the
    best iteration at the target area that the evaluator reproduces, evaluated
    (:func:`kgarment.design.driver.evaluate_final`; over the motion from rest in ``path_frames``
    frames, as the report judges it, where given); without, the best iteration at the target."""
    status = run_status(folder)
    if status != "new":
        _check_same_problem(problem, folder)
    evaluated = (folder / "final" / "evaluation.json").is_file()
    if status != "finished" or (evaluator is not None and not evaluated):  # finished without: its final design chosen
        if status != "new":
            log.info("resuming %s", folder)
            dr = open_run(None, folder, resume=True, device=device)
        else:  # nothing computed yet: a partial folder without a checkpoint holds nothing to lose
            dr = open_run(problem, folder, force=True, device=device)
        expected = expected_iterations(problem.design.beso)
        finish(dr, progress=(lambda st: progress(folder.name, st.metrics[-1], expected)) if progress else None,
               evaluate=evaluator is not None, evaluator=evaluator, path_frames=path_frames)
    rows = json.loads((folder / "metrics.json").read_text())
    hist = load_design_history(folder)
    beso = problem.design.beso
    evaluated = (folder / "final" / "evaluation.json").is_file()
    k = final_iteration(folder) if evaluated else best_iteration(rows, beso.target_area, beso.er)
    return RunOutcome(folder, design_values(hist[k]), k, design_values(hist[-1]), rows,
                      float(sum(r["seconds"] for r in rows)))


def _check_same_problem(problem: Problem, folder: Path) -> None:
    """Refuse to reuse a run folder made for another problem (materials, resolution, BESO)."""
    old = load_problem(folder / "problem.toml")
    for what, a, b in (("materials", old.materials, problem.materials), ("design", old.design, problem.design),
                       ("clutch hardware", old.clutch_spec().hardware, problem.clutch_spec().hardware),
                       ("garment subdivision", old.garment.subdivision, problem.garment.subdivision)):
        if a != b:
            raise KgarmentError(f"{folder} was designed with other {what} ({a} instead of {b}); "
                                "give the reproduction another --out")
