"""Simulating designs from the page: design A (the edited one) and design B, in the background.

Every simulation goes through the one design evaluator, :class:`kgarment.design.Evaluator`
(the numbers of ``kgarment evaluate``), on the studio's own garment (its painted
attachments) and clutches, one state at a time so the page shows progress and a stop
request is honoured between solves.  An evaluator solves the fully reinforced garment once
per state and keeps it, so :class:`Simulations` keeps one evaluator per configuration
(clutches, attachments, motions, solver, materials, objective, device): simulating again
after editing only the design solves only the design.
"""

from __future__ import annotations

import dataclasses
import logging
import threading
import time
from collections import OrderedDict
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from kgarment.body import Body
from kgarment.case.values import design_values
from kgarment.clutch import ClutchSpec, ClutchStrip
from kgarment.design import load_design
from kgarment.errors import Cancelled, KgarmentError
from kgarment.evaluate import Evaluator
from kgarment.evaluate.path import PATH_FRAMES, PathReport, path_forces
from kgarment.garment import Garment
from kgarment.problem import Problem
from kgarment.studio.forces import force_table
from kgarment.studio.jobs import Job
from kgarment.studio.page import Page
from kgarment.studio.results import SimResult, results_table
from kgarment.studio.runs import check_compatible, read_run
from kgarment.studio.session import DesignB
from kgarment.studio.state import StudioState

log = logging.getLogger(__name__)
EVALUATORS_KEPT = 8  # configurations whose fully reinforced equilibria are kept
MAX_PATH_FRAMES = 40  # frames from rest the page allows (each one solve per motion and state)


@dataclass(frozen=True)
class SimInputs:
    """A frozen copy of what a simulation needs, taken from the studio state at start.

    problem : Problem (motions, solver, materials, objective);  body : Body;  garment :
    Garment with the painted attachments;  clutches : the clutch specs;  strips : their
    ClutchStrips on the garment.
    """

    problem: Problem
    body: Body
    garment: Garment
    clutches: tuple[ClutchSpec, ...]
    strips: tuple[ClutchStrip, ...]

    @classmethod
    def of(cls, state: StudioState) -> SimInputs:
        with state.lock:
            return cls(state.problem, state.body, state.garment, tuple(state.clutches), tuple(state.strips()))

    def key(self, device: str) -> tuple:
        """What the fully reinforced equilibria depend on (the budget does not count)."""
        p = self.problem
        return (p.body, p.garment, p.motions, p.activation, self.clutches, self.garment.attached.tobytes(), p.solver,
                p.materials, p.design.objective, p.clutch_spec().hardware, device)

    def evaluator(self, device: str = "cpu") -> Evaluator:
        return Evaluator.from_problem(self.problem, body=self.body, garment=self.garment, strips=list(self.strips),
                                      device=device)


def simulate_design(evaluator: Evaluator, design: np.ndarray, motions: Sequence[str], *, label: str = "A",
                    revision: int = 0, report: Callable[[str], None] | None = None,
                    cancelled: Callable[[], bool] | None = None) -> SimResult:
    """Simulate ``design`` (m,) bool (True = reinforced) on ``motions`` in the states of the
    problem's objective (ON and OFF for "active"), one state at a time: ``report(text)``
    before each solve, ``cancelled()`` between solves (raises kgarment.errors.Cancelled);
    then the load each clutch carries (one more solve per clutch and motion)."""
    if not motions:
        raise KgarmentError("pick at least one motion to simulate")
    ev = evaluator.evaluate(design_values(design), list(motions), loads=True,
                            report=None if report is None else (lambda text: report(f"{label}: {text}")),
                            cancelled=cancelled if cancelled is not None else (lambda: False))
    return SimResult.of(label, revision, ev, evaluator.case.model)


class Simulations:
    """Designs A and B simulated from the page (see the module docstring).

    a, b : the last results of design A and of design B (None: not simulated);
    design_b : the design compared with A (None: none yet);  job : the last simulation.
    """

    def __init__(self, page: Page, design_b: DesignB | None = None, kept: int = EVALUATORS_KEPT):
        self.page = page
        self.a: SimResult | None = None
        self.b: SimResult | None = None
        self.path: tuple[str, int, PathReport] | None = None  # (label, revision, report): the last force path
        self.design_b = design_b
        self.job: Job[SimResult] | None = None
        self._kept = kept
        self._evaluators: OrderedDict[tuple, Evaluator] = OrderedDict()
        self._evaluators_lock = threading.Lock()

    @property
    def running(self) -> bool:
        return self.job is not None and self.job.running

    def reset(self, design_b: DesignB | None = None) -> None:
        """Forget results and evaluators (another problem was opened)."""
        self.a = self.b = self.path = None
        self.design_b = design_b
        with self._evaluators_lock:
            self._evaluators.clear()

    def evaluator(self, inputs: SimInputs) -> Evaluator:
        """The evaluator of ``inputs``' configuration (built on first need, then kept)."""
        key = inputs.key(self.page.device)
        with self._evaluators_lock:
            ev = self._evaluators.get(key)
            if ev is not None:
                self._evaluators.move_to_end(key)
                return ev
        ev = inputs.evaluator(self.page.device)
        with self._evaluators_lock:
            self._evaluators[key] = ev
            while len(self._evaluators) > self._kept:
                self._evaluators.popitem(last=False)
        return ev

    def stale(self) -> bool:
        """Design A was simulated before the latest edits."""
        return self.a is not None and self.a.revision != self.page.state.revision

    def table(self) -> str:
        return results_table(self.a, self.b, self.stale())

    def to_json(self) -> dict:
        """The results as a session saves them (the force path of A under "path")."""
        out = {k: e.to_json() for k, e in (("A", self.a), ("B", self.b)) if e is not None}
        if self.path is not None:
            out["path"] = {"design": self.path[0], "revision": self.path[1], **self.path[2].to_json()}
        return out

    def _snapshot(self, which: str, motions: Sequence[str] | None):
        """(motions, SimInputs, design (m,) bool, revision) for a simulation of design
        ``which`` about to start; a one-line error while one runs or with no motion."""
        if self.running:
            raise KgarmentError("a simulation is running; wait for it or press Stop simulation")
        motions = list(motions or self.page.settings.sim_motions)
        if not motions:
            raise KgarmentError("tick at least one motion to simulate")
        st = self.page.state
        with st.lock:
            design = st.design.copy() if which == "A" else self.design_b.design.copy()
            return motions, SimInputs.of(st), design, st.revision

    def _start(self, work, done, stopped: str, starting: str) -> Job:
        """Start the simulation job ``work`` (then ``done(result)``), its progress, errors
        and stop shown in the page."""
        page = self.page

        def ended(then):  # the job's last progress line goes; the page says how it ended
            def call(*args):
                page.show_progress("simulation", "")
                then(*args)
            return call

        job = Job("simulation", work, on_done=ended(done), on_error=ended(lambda m: page.say(m, error=True)),
                  on_report=lambda text: page.show_progress("simulation", text),
                  on_cancel=ended(lambda: page.say(stopped, notify=True)))
        page.say(starting)
        self.job = job.start()
        return job

    # ----- actions ----------------------------------------------------------------------
    def simulate(self, which: str = "A", motions: Sequence[str] | None = None) -> Job[SimResult]:
        """Simulate design A (the edited one) or B on ``motions`` (default: the ticked ones)
        in the background; returns the Job."""
        page = self.page
        if which == "B" and self.design_b is None:
            raise KgarmentError("there is no design B yet (pin A as B, or load one)")
        motions, inputs, design, revision = self._snapshot(which, motions)
        label = "A" if which == "A" else f"B ({self.design_b.label})"

        def work(job: Job[SimResult]) -> SimResult:
            return simulate_design(self.evaluator(inputs), design, motions, label=label, revision=revision,
                                   report=job.report, cancelled=lambda: job.cancelled)

        def done(result: SimResult) -> None:
            if which == "A":
                self.a = result
            else:
                self.b = result
            page.say(f"simulated design {label} on {', '.join(motions)} in {time.time() - t0:.0f} s",
                     notify=True)
            page.refresh(results=True, scene=True)

        t0 = time.time()
        return self._start(work, done, "simulation stopped", f"simulating design {label} on {', '.join(motions)} ...")

    def force_path(self, frames: int = PATH_FRAMES, motions: Sequence[str] | None = None) -> Job[PathReport]:
        """The force over the motion of design A (``kgarment evaluate --path``: ``frames``
        frames from rest to each target pose of ``motions``, default the ticked ones, ON and
        OFF, on the studio's garment and attachments) in the background; returns the Job.
        Stopped between frames by Stop simulation."""
        page = self.page
        frames = int(frames)
        if not 1 <= frames <= MAX_PATH_FRAMES:
            raise KgarmentError(f"frames from rest: {frames}; give 1 to {MAX_PATH_FRAMES}")
        motions, inputs, design, revision = self._snapshot("A", motions)
        if inputs.problem.body.model != "anny":
            raise KgarmentError("the force over the motion needs a posable body (body model 'anny')")

        def work(job: Job[PathReport]) -> PathReport:
            def report(text: str) -> None:
                if job.cancelled:
                    raise Cancelled("force over the motion stopped")
                job.report(f"force over the motion of A: {text}")

            ev = self.evaluator(inputs)
            return path_forces(ev, design_values(design), inputs.problem, motions, frames, report=report,
                               attached=inputs.garment.attached)

        def done(result: PathReport) -> None:
            self.path = ("A", revision, result)
            page.say(f"force over the motion of design A ({frames} frame{'s' if frames != 1 else ''} from rest) "
                     f"in {time.time() - t0:.0f} s", notify=True)
            page.refresh(results=True)

        t0 = time.time()
        return self._start(work, done, "force over the motion stopped",
                           f"force over the motion of design A on {', '.join(motions)}, {frames} frames ...")

    def path_table(self) -> str:
        """Markdown of the last force path (marked when design A was edited since)."""
        if self.path is None:
            return ""
        label, revision, rep = self.path
        stale = " (before the latest edits)" if revision != self.page.state.revision else ""
        return force_table(rep, label + stale)

    def stop(self) -> None:
        if not self.running:
            raise KgarmentError("no simulation is running")
        self.job.cancel()
        self.page.say("stopping the simulation after the current solve ...")

    def pin_as_b(self) -> None:
        """Design A (and its results, if current) becomes design B for comparisons."""
        st = self.page.state
        with st.lock:
            self.design_b = DesignB(f"A at edit {st.revision}", st.design.copy())
            a = self.a
            current = a is not None and a.revision == st.revision
            self.b = dataclasses.replace(a, label=f"B ({self.design_b.label})") if current else None
        self.page.say(f"design A pinned as B ({self.design_b.label})")
        self.page.refresh(results=True, scene=True)

    def set_b(self, label: str, design: np.ndarray) -> None:
        """Make ``design`` (m,) bool design B (not simulated yet)."""
        self.design_b, self.b = DesignB(label, np.asarray(design, bool).copy()), None
        self.page.refresh(results=True)

    def load_b(self, source: str) -> None:
        """Design B from a design file (.npz/.npy/.txt) or RUN / RUN@K."""
        text = source.strip()
        if not text:
            raise KgarmentError("give a design file, a run folder or RUN@ITERATION")
        self.page.folders.inside(text, "design B")  # before anything there is looked at
        st = self.page.state
        run = Path(text.rpartition("@")[0] if "@" in text and not Path(text).exists() else text)
        if run.is_dir():
            check_compatible(read_run(run), st.problem, st.n_faces)
        d = load_design(text, st.n_faces) > 0.5
        self.set_b(Path(text).name or text, d)
        self.page.say(f"design B loaded from {text} ({100 * np.mean(d):.1f}% of faces reinforced)")
        self.page.refresh(scene=True)
