"""The motion from rest solved until its frame count no longer matters (``evaluate --path K --converge``).

With skin friction the state at the end of a motion depends on the path taken, and the
path is solved in frames (:func:`kgarment.evaluate.path.path_forces`): a frame holds the
garment where the frame before left it, so a coarse step can carry a held equilibrium past
the point where, moved on more gently, the garment slips (measured: docs/notes/selective.md,
"Frames of the motion from rest").

:func:`converged_path` therefore solves each motion over ``frames`` frames, then twice as
many, and so on, until two frame counts in a row agree: at every frame the coarser path
has (its ``t`` is a frame of the finer one too), ON and OFF, the garment's energy differs
by at most ``tol`` times the motion's ON energy at the target pose (the scale of what rho
reads; OFF energies are a hundredth of it).  Each motion stops doubling on its own; the
report keeps every motion's finest path.
"""

from __future__ import annotations

import logging
from collections.abc import Callable
from dataclasses import dataclass

from kgarment.constants import PATH_CONVERGE_TOL, PATH_FRAMES, PATH_MAX_FRAMES
from kgarment.evaluate.path import STATES, PathReport, path_forces

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class FrameCheck:
    """One motion's frame counts solved, oldest first (``frames`` (n,)), the largest energy
    change from each count to the next (``gaps`` (n - 1,), relative to the finer path's ON
    energy at the target, :func:`frame_gap`), and whether the last change is within ``tol``."""

    motion: str
    frames: tuple[int, ...]
    gaps: tuple[float, ...]
    tol: float

    @property
    def converged(self) -> bool:
        return bool(self.gaps) and self.gaps[-1] <= self.tol

    def to_json(self) -> dict:
        return {"motion": self.motion, "frames": list(self.frames), "gaps": list(self.gaps), "tol": self.tol,
                "converged": self.converged}

    def line(self) -> str:
        steps = " -> ".join(str(f) for f in self.frames)
        gaps = ", ".join(f"{100 * g:.1f}%" for g in self.gaps)
        verdict = (f"converged (within {100 * self.tol:.0f}%)" if self.converged else
                   f"NOT converged at {self.frames[-1]} frames (the tolerance is {100 * self.tol:.0f}%)")
        return f"{self.motion}: frames {steps}: largest energy change {gaps}; {verdict}"


def frame_gap(coarse: PathReport, fine: PathReport, motion: str) -> float:
    """The largest change of the garment's energy (ON and OFF) at the frames of ``coarse``
    (rest excluded) from ``coarse`` to ``fine`` in ``motion``, relative to ``fine``'s ON
    energy at the target pose; every ``t`` of ``coarse`` must be one of ``fine``'s."""
    on = fine.curve(motion, "on")
    scale = abs(on[-1].energy_J) if on else 0.0
    gap = 0.0
    for s in STATES:
        at = {round(f.t, 9): f.energy_J for f in fine.curve(motion, s)}
        for f in coarse.curve(motion, s):
            if f.t == 0.0:
                continue
            e = at.get(round(f.t, 9))
            if e is None:
                raise ValueError(f"frame_gap: t = {f.t} of the coarser path is not a frame of the finer one")
            gap = max(gap, abs(e - f.energy_J))
    return gap / scale if scale > 0.0 else (0.0 if gap == 0.0 else float("inf"))


def merged(reports: dict[str, PathReport]) -> PathReport:
    """One PathReport of each motion's own report, ``reports`` {motion: report} (in order)."""
    first = next(iter(reports.values()))
    frames = tuple(f for m, r in reports.items() for f in r.frames if f.motion == m)
    hold = tuple((m, h) for m, r in reports.items() for mm, h in r.holding_N if mm == m)
    ends = {k: v for m, r in reports.items() for k, v in r.ends.items() if k[0] == m}
    return PathReport(first.clutches, frames, hold, ends)


def converged_path(evaluator, design, problem, motions=None, frames: int = PATH_FRAMES, *,
                   tol: float = PATH_CONVERGE_TOL, max_frames: int = PATH_MAX_FRAMES,
                   report: Callable[[str], None] | None = None, attached=None
                   ) -> tuple[PathReport, list[FrameCheck]]:
    """The path of ``design`` (m,) over each motion of ``motions`` (default: the
    evaluator's) at ``frames``, 2 ``frames``, ... frames until two counts in a row agree
    within ``tol`` (module doc) or the next count would pass ``max_frames``; arguments as
    :func:`kgarment.evaluate.path.path_forces`.  Returns (the report of every motion's finest
    path, one FrameCheck per motion)."""
    motions = evaluator.motion_names(motions)
    if frames < 1 or max_frames < 2 * frames:
        raise ValueError(f"converged_path: frames {frames} and max_frames {max_frames}: give 1 <= 2 frames "
                         "<= max_frames")

    def solve(ms: list[str], k: int) -> PathReport:
        if report is not None:
            report(f"{k} frames: {', '.join(ms)}")
        return path_forces(evaluator, design, problem, ms, k, report=report, attached=attached)

    reports = dict.fromkeys(motions, solve(motions, frames))
    counts = {m: [frames] for m in motions}
    gaps: dict[str, list[float]] = {m: [] for m in motions}
    pending, k = list(motions), frames
    while pending and 2 * k <= max_frames:
        k *= 2
        fine = solve(pending, k)
        still = []
        for m in pending:
            gap = frame_gap(reports[m], fine, m)
            reports[m] = fine
            counts[m].append(k)
            gaps[m].append(gap)
            log.info("%s: %d frames: the energy changed by %.1f%% of its ON energy at the target", m, k, 100 * gap)
            if gap > tol:
                still.append(m)
        pending = still
    checks = [FrameCheck(m, tuple(counts[m]), tuple(gaps[m]), tol) for m in motions]
    return merged({m: reports[m] for m in motions}), checks
