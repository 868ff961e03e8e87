"""The one run driver: a problem to a finished run folder, for the CLI, the studio and
``reproduce``.

:func:`open_run` prepares (or reopens) the run folder, writes the resolved problem, the
clutch file and (for a garment with its own attachments, e.g. painted in the studio)
``attachments.npz``, builds body, garment, clutches and the loop's setup, and loads the
checkpoint when resuming; :func:`finish` runs the loop to the end with a checkpoint after
every iteration, then writes the final design and its renders.  A resumed run rebuilds
exactly what the first call built (attachments and clutches included).
"""

from __future__ import annotations

import dataclasses
import json
import logging
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import tomli_w

from kgarment.body import Body
from kgarment.case.setup import case_from_problem
from kgarment.case.store import run_store
from kgarment.case.values import design_values
from kgarment.clutch import ClutchSpec, ClutchStrip, save_clutches
from kgarment.clutch.landmarks import body_landmarks
from kgarment.design.coarse import run_coarse
from kgarment.design.report import finish_run
from kgarment.design.reported import Reported, select_reported
from kgarment.design.run import (
    best_iteration,
    check_model,
    check_run_folder,
    load_checkpoint,
    save_checkpoint,
    write_history,
)
from kgarment.errors import Cancelled, KgarmentError
from kgarment.evaluate.control import Control, control_check
from kgarment.evaluate.evaluator import DesignEvaluation, Evaluator
from kgarment.evaluate.loads import load_chart
from kgarment.evaluate.path import path_forces
from kgarment.garment import Garment
from kgarment.io import atomic_save_npz, atomic_write_text, json_text, replace_folder
from kgarment.optimize.loop import LoopState, initial_state, iterate, run_loop
from kgarment.optimize.refine import coarse_levels, transfer
from kgarment.optimize.setup import DesignSetup, setup_from_problem
from kgarment.problem import (
    Problem,
    build_body,
    build_clutches,
    build_garment,
    clutch_specs,
    load_problem,
    problem_to_dict,
)

log = logging.getLogger(__name__)
ATTACHMENTS = "attachments.npz"


@dataclass(frozen=True, kw_only=True)
class DesignRun:
    """An open run: its folder, the problem and everything built from it.

    run : folder;  problem : Problem;  body : Body;  garment : Garment (its attachments are
    the run's);  strips : the clutch strips;  setup : DesignSetup;  state : LoopState (the
    next iteration, or the final state after :func:`finish`);  paths : files written by
    :func:`finish`;  evaluation : the final design's evaluation and selection : how it was
    chosen (:func:`evaluate_final`; None without one).
    """

    run: Path
    problem: Problem
    body: Body
    garment: Garment
    strips: tuple[ClutchStrip, ...]
    setup: DesignSetup
    state: LoopState
    paths: tuple[Path, ...] = ()
    evaluation: DesignEvaluation | None = None
    selection: Reported | None = None


def open_run(problem: Problem | None, run, *, resume: bool = False, force: bool = False, device: str = "cpu",
             body: Body | None = None, garment: Garment | None = None,
             clutches: list[ClutchSpec] | None = None) -> DesignRun:
    """Prepare a run folder for ``problem`` (or reopen it with ``resume``; the problem is
    then read from the folder and the argument may be None).

    body, garment, clutches : already built parts to use instead of building them from the
    problem (the studio passes its posed body, its garment with painted attachments and its
    clutch specs); they are written into the folder so that a resume rebuilds the same.

    A new run is written beside an existing folder and swapped in only once its problem is
    built (``force`` replaces only a kgarment run folder): nothing is lost when it fails.
    """
    run = check_run_folder(run, force=force, resume=resume)
    if resume:
        problem = load_problem(run / "problem.toml")
        resumed = load_checkpoint(run)  # a damaged checkpoint is reported before the slow build
        check_model(run)
    custom_garment = garment is not None and not resume
    body = build_body(problem) if body is None else body
    garment = build_garment(problem, body) if garment is None else garment
    if resume and (run / ATTACHMENTS).is_file():
        garment = _with_attachments(garment, run / ATTACHMENTS)
    specs = clutch_specs(problem, body) if clutches is None or resume else list(clutches)
    strips = tuple(build_clutches(problem, body, garment, specs))
    setup = setup_from_problem(problem, body, garment, strips, device)
    if not resume:
        replace_folder(run, lambda tmp: write_inputs(tmp, problem, body, garment, specs, custom_garment),
                       "run")
    st = resumed if resume else initial_state(setup)
    return DesignRun(run=run, problem=problem, body=body, garment=garment, strips=strips, setup=setup, state=st)


def run_inputs(run, problem: Problem | None = None) -> tuple[Problem, Body, Garment, tuple[ClutchStrip, ...]]:
    """The problem, body, garment (with the run's own attachments) and clutch strips of a
    run folder, as the run used them; ``problem`` replaces the folder's problem.toml (e.g.
    with other motions)."""
    run = Path(run)
    problem = load_problem(run / "problem.toml") if problem is None else problem
    body = build_body(problem)
    garment = build_garment(problem, body)
    if (run / ATTACHMENTS).is_file():
        garment = _with_attachments(garment, run / ATTACHMENTS)
    return problem, body, garment, tuple(build_clutches(problem, body, garment))


def write_inputs(run: Path, problem: Problem, body: Body, garment: Garment, specs, custom_garment: bool) -> None:
    """problem.toml (+ problem.txt, problem.source.toml), clutches.toml and, for a garment
    given by the caller, attachments.npz of a new run folder ``run`` (problem.toml refers to
    its clutch file by a path relative to itself, so the run folder can be moved or copied)."""
    if specs:
        marks = body_landmarks(body) if body.rigged else None
        save_clutches(run / "clutches.toml", specs, garment.rest_vertices, garment.faces, landmarks=marks)
    doc = problem_to_dict(problem, Path("clutches.toml") if specs else None)  # beside it: the folder can move
    if not specs:
        doc.setdefault("clutches", {})["clutch"] = []  # no clutches, not the garment's default layout
    if problem.source and Path(problem.source).is_file():
        atomic_write_text(run / "problem.source.toml", Path(problem.source).read_text())
    atomic_write_text(run / "problem.toml", tomli_w.dumps(doc))
    atomic_write_text(run / "problem.txt", problem.describe() + "\n")
    if custom_garment:
        atomic_save_npz(run / ATTACHMENTS, attached=garment.attached)


def _with_attachments(garment: Garment, path: Path) -> Garment:
    with np.load(path) as z:
        attached = np.asarray(z["attached"], bool)
    if attached.shape != (garment.n_faces,):
        raise KgarmentError(f"{path} holds {attached.size} faces, the run's garment {garment.n_faces}")
    return dataclasses.replace(garment, attached=attached)


def finish(dr: DesignRun, progress: Callable[[LoopState], None] | None = None,
           cancelled: Callable[[], bool] | None = None, final: bool = True, evaluate: bool = True,
           evaluator: Evaluator | None = None, path_frames: int = 0) -> DesignRun:
    """Iterate to the end (checkpoint after every iteration), then (``final``) write the
    final design and its renders into ``dr.run / "final"``: with ``evaluate`` the best
    iteration at the target area that the one design evaluator reproduces, evaluated
    (:func:`evaluate_final`; ``evaluator``: the Evaluator to use, e.g. the reproduction's with
    its shared store; default: one with the run's store; ``path_frames``: judged over the
    motion from rest in this many frames, as the reproduction's report judges it), else the
    best iteration at the target area (:func:`kgarment.design.run.best_iteration`).

    progress(state) after every iteration (its checkpoint is already written);
    cancelled() is checked after every iteration and raises :class:`Cancelled` (the run
    folder stays resumable).  Returns the run with its final state, written paths and
    evaluation."""
    def after(st: LoopState) -> None:
        if len(st.metrics) == 1 and dr.setup.case.objective == "active" and not coarse_levels(dr.problem):
            check_control(dr, st)  # coarse-to-fine: at the coarsest level (start_from_coarse)
        if progress is not None:
            progress(st)
        if cancelled is not None and not st.done and cancelled():
            raise Cancelled()

    if dr.state.done:  # a finished run resumed: its history files again, from the checkpoint
        write_history(dr.run, dr.state)
    if coarse_levels(dr.problem) and dr.state.iteration == 0:
        dr = start_from_coarse(dr, after, cancelled)
    st = run_loop(dr.setup, dr.state, checkpoint=lambda s: save_checkpoint(dr.run, s), progress=after)
    dr = dataclasses.replace(dr, state=st)
    if not final:
        return dr
    p = dr.setup.beso.params
    if evaluate:
        selection, evaluation, paths = evaluate_final(dr, evaluator=evaluator, path_frames=path_frames)
        k = selection.iteration
    else:
        k, selection, evaluation, paths = best_iteration(st.metrics, p.target_area, p.er), None, None, []
    equilibria = None if evaluation is None else {s.key: s.result for s in evaluation.states}
    paths = finish_run(dr.run, dr.setup, st, dr.body, dr.garment, list(dr.strips), iteration=k, equilibria=equilibria) + paths
    return dataclasses.replace(dr, paths=tuple(paths), evaluation=evaluation, selection=selection)


def start_from_coarse(dr: DesignRun, after: Callable[[LoopState], None],
                      cancelled: Callable[[], bool] | None = None) -> DesignRun:
    """Coarse-to-fine (:mod:`kgarment.optimize.refine`): the coarse levels in their own run
    folders (``RUN/level<L>``, resumed where they stopped), then this run's iteration 0 and
    the coarse run's state transferred to this level; checkpointed.  The control screen
    (:func:`check_control`) runs once, after the coarsest level's iteration 0, into this
    run's ``control.json``: it judges gains of 0.5% against the paper's 1-4%, which the
    level hardly changes (the three-motion shirt's arms forward, arms raise and bend forward:
    1.74 / 1.47 / 4.28% at subdivision 0, 1.87 / 1.41 / 3.93% at 1, 1.72 / 1.47 / 3.73% at
    2), and at the garment's level it took most of the 9.3 min before the first fine
    iteration at subdivision 2 (benchmarks/README.md)."""
    if not (dr.run / "checkpoint.npz").is_file():
        save_checkpoint(dr.run, dr.state)  # resumable while the coarse levels run
    device = dr.setup.case.solver.device

    def open_level(problem: Problem, folder: Path, resume: bool) -> DesignRun:
        return open_run(problem, folder, resume=resume, force=not resume, device=device, body=dr.body)

    def first(level_run: DesignRun, st: LoopState) -> None:
        if level_run.setup.case.objective == "active":
            check_control(level_run, st, folder=dr.run)

    coarse_setup, coarse = run_coarse(dr.run, dr.problem, open_level, cancelled=cancelled, first=first)
    st = iterate(dr.setup, dr.state)  # the fully reinforced garment at this level: the references
    st = transfer(coarse_setup, coarse, dr.setup, st)
    save_checkpoint(dr.run, st)
    after(st)
    return dataclasses.replace(dr, state=st)


def check_control(dr: DesignRun, st: LoopState, folder: Path | None = None) -> list[Control]:
    """After iteration 0: which motions the clutches can control at all
    (:mod:`kgarment.evaluate.control`), written to ``control.json`` in ``folder`` (default:
    the run's; each row with the garment's subdivision level it was solved at); a warning
    with what to change for each one they cannot."""
    controls = control_check(dr.setup.case, st.warm)
    if controls:
        level = dr.problem.garment.subdivision
        atomic_write_text((folder or dr.run) / "control.json",
                          json.dumps([{**c.to_json(), "subdivision": level} for c in controls], indent=1))
    for c in controls:
        if not c.controllable:
            log.warning("%s", c.advice())
    return controls


def evaluate_final(dr: DesignRun, evaluator: Evaluator | None = None,
                   path_frames: int = 0) -> tuple[Reported, DesignEvaluation, list[Path]]:
    """The final design evaluated like ``kgarment evaluate RUN`` (the one design evaluator,
    per-clutch loads included): the best iteration at the target area that the evaluator
    reproduces (:func:`kgarment.design.reported.select_reported`), written with how it was
    chosen to ``final/evaluation.json`` (``iteration``, ``along_run``: each motion's rho ON
    along the run beside the evaluator's, ``selection``: the candidates evaluated) and
    ``final/clutch_loads.png``.  These, not the metrics rows (solved warm along the run's
    path, to the design tolerance), are the run's final numbers.  A run with ``[solver]
    path_start`` is evaluated like ``kgarment evaluate RUN --path F`` (F: ``[solver]
    path_frames``; the motion's end a start; its force over the motion under ``path`` in the
    JSON), and with ``path_frames`` like ``--path path_frames`` (the candidates too).  Returns (how the iteration was chosen,
    its evaluation, the files written)."""
    ev = evaluator or Evaluator(case_from_problem(dr.problem, dr.body, dr.garment, dr.strips,
                                                  device=dr.setup.case.solver.device),
                                run_store(dr.run))  # kgarment evaluate / plan RUN take them from there
    paths_of: dict[int, object] = {}
    # a run that designs against the motion is judged by it: --path's numbers
    frames = path_frames or (dr.problem.solver.path_frames if dr.setup.beso.path_start else 0)

    def candidate(k: int) -> DesignEvaluation:
        design = design_values(dr.state.designs[k])
        path = None
        if frames:
            path = paths_of[k] = path_forces(ev, design, dr.problem, frames=frames)
        return ev.evaluate(design, loads=False, known=None if path is None else path.ends)

    p = dr.setup.beso.params
    chosen = select_reported(dr.state.metrics, p.target_area, p.er, dr.setup, candidate)
    k, path = chosen.iteration, paths_of.get(chosen.iteration)
    res = ev.with_loads(chosen.evaluation, design_values(dr.state.designs[k]))
    doc = {"run": str(dr.run), "iteration": k, **res.to_json(), "along_run": chosen.along_run,
           "selection": chosen.to_json(),
           **({} if path is None else {"path": path.to_json()})}
    paths = [atomic_write_text(dr.run / "final" / "evaluation.json", json_text(doc))]
    if res.loads is not None:
        paths.append(load_chart(res.loads, dr.run / "final" / "clutch_loads.png",
                                f"{dr.garment.name}: clutch loads of the final design"))
    return chosen, res, paths

