"""Automatic design (BESO) from the page into a normal run folder, and scrubbing runs.

An optimisation is the one run driver's (:func:`kgarment.design.open_run` +
:func:`kgarment.design.finish`, as ``kgarment design``) on the studio's posed body, its
garment with the painted attachments and its clutches; the driver writes them into the run
folder (problem.toml, clutches.toml, attachments.npz), so ``kgarment design --resume RUN``,
``kgarment evaluate RUN@K`` and ``kgarment simulate --design RUN@K`` work on it and a
resumed run holds the same attachments.  The page follows the iterations live through the
driver's progress callback (the loop's state after every iteration).

:class:`Optimiser` also opens any run folder that fits the studio's garment, scrubs its
iterations, and loads or exports one.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from kgarment.body import Body
from kgarment.clutch import ClutchSpec
from kgarment.design import DesignRun, finish, open_run
from kgarment.errors import KgarmentError
from kgarment.garment import Garment
from kgarment.optimize import LoopState
from kgarment.problem import Problem, override
from kgarment.studio.jobs import Job
from kgarment.studio.page import Page
from kgarment.studio.runs import RunHistory, check_compatible, read_run
from kgarment.studio.session import export_design, studio_path
from kgarment.studio.simulations import Simulations
from kgarment.studio.state import StudioState

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class RunInputs:
    """A frozen copy of what an optimisation needs, taken from the studio state at start.

    problem : Problem (the budget as edited; ``max_iterations`` as asked);  body : the posed
    Body;  garment : Garment with the painted attachments;  clutches : the clutch specs.
    """

    problem: Problem
    body: Body
    garment: Garment
    clutches: tuple[ClutchSpec, ...]

    @classmethod
    def of(cls, state: StudioState, max_iterations: int | None = None) -> RunInputs:
        """The state's inputs; ``max_iterations`` (None or 0: the problem's) overrides the
        problem's (validated like the problem file's field)."""
        with state.lock:
            problem, body, garment, clutches = state.problem, state.body, state.garment, tuple(state.clutches)
        if max_iterations:
            problem = override(problem, max_iterations=int(max_iterations))
        return cls(problem, body, garment, clutches)


def run_design(inputs: RunInputs, folder: Path, *, device: str = "cpu",
               progress: Callable[[LoopState], None] | None = None,
               cancelled: Callable[[], bool] | None = None) -> DesignRun:
    """Run BESO for ``inputs`` into the new run folder ``folder`` to the end (final design
    and renders included): progress(state) after every iteration, cancelled() checked after
    every iteration (raises kgarment.errors.Cancelled; the folder stays resumable)."""
    dr = open_run(inputs.problem, folder, device=device, body=inputs.body, garment=inputs.garment,
                  clutches=list(inputs.clutches))
    return finish(dr, progress=progress, cancelled=cancelled)


class Optimiser:
    """Optimisations and runs in the page (see the module docstring).

    run : the run shown (None: none open);  k : its iteration shown;  follow : while an
    optimisation runs, show each new iteration;  job : the last optimisation;  runs_root :
    where a run folder goes when none is named.
    """

    def __init__(self, page: Page, sims: Simulations, runs_root: Path):
        self.page = page
        self.sims = sims
        self.runs_root = Path(runs_root)
        self.run: RunHistory | None = None
        self.k = 0
        self.follow = True
        self.job: Job[DesignRun] | None = None

    @property
    def running(self) -> bool:
        return self.job is not None and self.job.running

    def close(self) -> None:
        """Show no run (another problem was opened)."""
        self.run, self.k = None, 0

    # ----- optimisation -----------------------------------------------------------------
    def optimise(self, folder: str | None = None, max_iterations: int | None = None) -> Job[DesignRun]:
        """Start BESO from the current problem, clutches and attachments into a run folder
        (default: a new one under ``runs_root``); the run is opened in the page and follows
        the iterations live. Returns the Job."""
        page = self.page
        if self.running:
            raise KgarmentError("an optimisation is running; stop it first")
        name = folder if folder and folder.strip() else time.strftime("studio-%Y%m%d-%H%M%S")
        run = studio_path(self.runs_root, name, "run folder")
        if run.exists() and any(run.iterdir()):
            raise KgarmentError(f"run folder {run} exists and is not empty; choose another")
        inputs = RunInputs.of(page.state, max_iterations)
        with page.lock:
            self.run, self.k = RunHistory.empty(run, inputs.problem, inputs.garment.n_faces), 0

        def progress(st: LoopState) -> None:
            with page.lock:
                if self.run is not None and self.run.folder == run:
                    self.run = self.run.following(st)
                    if self.follow:
                        self.k = self.run.n_iterations - 1
            page.refresh(run=True, scene=page.settings.mode == "run")

        def work(job: Job[DesignRun]) -> DesignRun:
            return run_design(inputs, run, device=page.device, progress=progress, cancelled=lambda: job.cancelled)

        def done(dr: DesignRun) -> None:
            page.say(f"optimisation finished after {len(dr.state.metrics)} iterations; run folder {run}", notify=True)

        job = Job("optimisation", work, on_done=done, on_error=lambda msg: page.say(msg, error=True),
                  on_report=lambda text: page.show_progress("optimisation", text),
                  on_cancel=lambda: page.say(f"optimisation stopped; resume with: kgarment design --resume {run}",
                                             notify=True))
        page.settings.mode = "run"
        page.refresh(settings=True, run=True)
        page.say(f"optimisation started into {run}")
        self.job = job.start()
        return job

    def stop(self) -> None:
        if not self.running:
            raise KgarmentError("no optimisation is running")
        self.job.cancel()
        self.page.say("stopping the optimisation after the current iteration ...")

    # ----- runs -------------------------------------------------------------------------
    def open(self, folder) -> None:
        """Open a run folder for scrubbing (it must fit the studio's body and garment)."""
        page = self.page
        run = read_run(page.folders.inside(folder, "run folder"))
        check_compatible(run, page.state.problem, page.state.n_faces)
        with page.lock:
            self.run = run
            self.k = max(run.n_iterations - 1, 0)
            page.settings.mode = "run"
        page.refresh(settings=True, run=True)
        page.say(f"run {run.folder} opened: {run.n_iterations} iterations")
        page.refresh(scene=True)

    def show_iteration(self, k: int) -> None:
        if self.run is None:
            raise KgarmentError("no run is open")
        self.run.design(k)
        self.k = int(k)
        self.page.refresh(run=True, scene=self.page.settings.mode == "run")

    def shown_design(self) -> np.ndarray:
        """(m,) bool design of the iteration shown."""
        if self.run is None:
            raise KgarmentError("no run is open (Optimise tab: open a run folder or start an optimisation)")
        return self.run.design(self.k)

    def use_iteration(self, as_b: bool = False) -> None:
        """Copy the shown iteration into design A (undoable) or make it design B."""
        d = self.shown_design()
        label = f"{self.run.folder.name}@{self.k}"
        if as_b:
            self.sims.set_b(label, d)
            self.page.say(f"design B is now {label}")
        else:
            self.page.state.set_layer("design", d)
            self.page.say(f"design A is now {label} (undo restores the previous one)")
        self.page.refresh(scene=True)

    def export_iteration(self, name: str) -> Path | None:
        """Write the shown iteration as a design NPZ (``kgarment simulate --design`` reads it)
        named ``name`` under ``RUNS/exports``; None when an existing file awaits confirmation."""
        out = studio_path(self.runs_root / "exports", name, "export name", ".npz")
        if not self.page.confirm_write(out):
            return None
        out = export_design(out, self.shown_design(), self.page.state.base_garment, iteration=self.k)
        self.page.say(f"iteration {self.k} written to {out}", notify=True)
        return out
