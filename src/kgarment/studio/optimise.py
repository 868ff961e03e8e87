"""Automatic design (BESO) started from the studio, into a normal run folder.

The run folder is what ``kgarment design`` writes (problem.toml, clutches.toml,
checkpoint.npz after every iteration, designs.npz, metrics, progress.png, final/), so
``kgarment design --resume RUN``, ``kgarment evaluate RUN@K`` and ``kgarment simulate
--design RUN@K`` work on it. The studio's clutches are written to the run's clutches.toml;
painted attachments, which problem files cannot express, go to attachments.npz (the
studio reads them back; the command line uses the problem's attachment rings).
"""

from __future__ import annotations

import logging
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import tomli_w

from kgarment.studio.evaluate import Cancelled

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class RunInputs:
    """A frozen copy of what an optimisation needs (taken from the studio state at start).

    problem : Problem; body : Body; garment : Garment (with the painted attachments);
    clutches : ClutchSpec tuple; strips : ClutchStrip tuple; topology, landmarks: to save
    the clutch file; custom_attachments : True when attachments differ from the template.
    """

    problem: object
    body: object
    garment: object
    clutches: tuple
    strips: tuple
    topology: object
    landmarks: object
    custom_attachments: bool


def inputs_from_state(state) -> RunInputs:
    with state.lock:
        g = state.garment
        return RunInputs(state.problem, state.body, g, tuple(state.clutches), tuple(state.strips()),
                         state.topology, state.landmarks,
                         bool((state.attached != state.base_garment.attached).any()))


def write_run_inputs(run: Path, inp: RunInputs) -> None:
    """problem.toml (+ problem.txt), clutches.toml and attachments.npz of a new run folder."""
    from kgarment.clutch import save_clutches
    from kgarment.design.run import atomic_write_text
    from kgarment.paths import atomic_save_npz
    from kgarment.problem import problem_to_dict

    g = inp.garment
    if inp.clutches:
        save_clutches(run / "clutches.toml", list(inp.clutches), g.rest_vertices, g.faces,
                      topology=inp.topology, landmarks=inp.landmarks)
    doc = problem_to_dict(inp.problem, run / "clutches.toml" if inp.clutches else None)
    if not inp.clutches:
        doc["clutches"] = {"clutch": []}
    atomic_write_text(run / "problem.toml", tomli_w.dumps(doc))
    atomic_write_text(run / "problem.txt", inp.problem.describe() + "\n")
    if inp.custom_attachments:
        atomic_save_npz(run / "attachments.npz", attached=g.attached)


def run_optimisation(inp: RunInputs, run, *, device: str = "cpu", force: bool = False,
                     on_iteration: Callable[[dict, np.ndarray], None] | None = None,
                     cancelled: Callable[[], bool] | None = None, finish: bool = True):
    """Run BESO to convergence (or ``problem.design.max_iterations``) into folder ``run``.

    on_iteration(row, design (m,) bool) after every iteration (its checkpoint is already
    written); cancelled() is checked after every iteration: then Cancelled is raised and
    the run folder stays resumable (``kgarment design --resume RUN``). ``finish`` writes
    final/ (design files, renders) at the end. Returns the LoopState.
    """
    from kgarment.design.driver import build_setup
    from kgarment.design.loop import initial_state, run_loop
    from kgarment.design.run import prepare_run_folder, save_checkpoint

    folder = prepare_run_folder(run, force=force)
    write_run_inputs(folder, inp)
    from kgarment.studio.evaluate import posed_only

    garment = posed_only(inp.garment, inp.problem.motions)
    setup = build_setup(inp.problem, inp.body, garment, list(inp.strips), device)
    st = initial_state(setup)

    def progress(row):
        if on_iteration is not None:
            on_iteration(row, st.designs[-1].copy())
        if cancelled is not None and cancelled() and not st.done:
            raise Cancelled()

    run_loop(setup, st, checkpoint=lambda s: save_checkpoint(folder, s), progress=progress)
    if finish:
        from kgarment.design.report import finish_run

        finish_run(folder, setup, st, inp.body, garment, list(inp.strips))
    return st
