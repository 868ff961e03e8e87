"""The motion from rest solved until its frame count no longer matters
(kgarment.evaluate.path_converge, ``evaluate --path K --converge``)."""

from __future__ import annotations

import tomllib

import numpy as np
import pytest
from tiny_problems import TINY_SLEEVE

from kgarment.evaluate.evaluator import Evaluator
from kgarment.evaluate.path import PathFrame, PathReport, path_forces
from kgarment.evaluate.path_converge import FrameCheck, converged_path, frame_gap, merged
from kgarment.problem import build_clutches, build_garment, parse_problem


def _report(motion: str, on: list[float], off: list[float], hold: float = 100.0) -> PathReport:
    """A report of ``motion`` with rest and len(on) frames at t = k / len(on), one clutch."""
    n = len(on)
    frames = []
    for s, energies in (("on", on), ("off", off)):
        frames.append(PathFrame(motion, s, 0.0, 1.0, (0.0,), True))
        frames += [PathFrame(motion, s, (k + 1) / n, e, (10.0 * e,), True) for k, e in enumerate(energies)]
    return PathReport(("c",), tuple(frames), ((motion, (hold,)),), {(motion, "on"): n, (motion, "off"): -n})


def test_the_gap_is_the_largest_change_at_the_coarse_frames_over_the_on_energy_at_the_target():
    coarse = _report("m", [2.0, 10.0], [1.0, 1.5])
    # at t = 0.5 ON 2.0 -> 2.5, OFF 1.0 -> 1.2; at t = 1: ON 10 -> 8, OFF 1.5 -> 1.5
    fine = _report("m", [1.5, 2.5, 5.0, 8.0], [1.1, 1.2, 1.4, 1.5])
    assert frame_gap(coarse, fine, "m") == pytest.approx(2.0 / 8.0)
    assert frame_gap(fine, fine, "m") == 0.0
    with pytest.raises(ValueError, match="not a frame"):  # t = 1/4 is not one of the coarse path's
        frame_gap(fine, coarse, "m")


def test_a_merged_report_keeps_each_motions_own_frames_holding_forces_and_ends():
    a, b = _report("a", [1.0, 2.0], [0.1, 0.2], hold=50.0), _report("b", [3.0, 4.0, 5.0, 6.0], [0.1] * 4)
    both = merged({"a": a, "b": b})
    assert both.motions == ["a", "b"]
    assert [f.t for f in both.curve("a", "on")] == [0.0, 0.5, 1.0]
    assert [f.energy_J for f in both.curve("b", "on")] == [1.0, 3.0, 4.0, 5.0, 6.0]
    assert dict(both.holding_N) == {"a": (50.0,), "b": (100.0,)}
    assert both.ends == {("a", "on"): 2, ("a", "off"): -2, ("b", "on"): 4, ("b", "off"): -4}
    check = FrameCheck("a", (10, 20, 40), (0.3, 0.04), 0.05)
    assert check.converged and "10 -> 20 -> 40" in check.line() and "30.0%, 4.0%" in check.line()
    assert not FrameCheck("a", (10, 20), (0.3,), 0.05).converged
    assert not FrameCheck("a", (10,), (), 0.05).converged  # nothing compared yet


@pytest.fixture(scope="module")
def sleeve(anny_body):
    p = parse_problem(tomllib.loads(TINY_SLEEVE + "[solver]\nworkers = 1\n"))
    g = build_garment(p, anny_body)
    return p, Evaluator.from_problem(p, body=anny_body, garment=g, strips=build_clutches(p, anny_body, g))


def test_the_converged_path_is_the_finest_path_and_its_gap_the_one_between_the_counts(sleeve):
    """Two frames, then four: the report is the four-frame path as path_forces solves it,
    and the check's gap is frame_gap of the two paths solved on their own."""
    p, ev = sleeve
    design = np.where(np.arange(ev.n_faces) % 3 == 0, 1e-3, 1.0)
    lines: list[str] = []
    report, (check,) = converged_path(ev, design, p, frames=2, tol=0.0, max_frames=4, report=lines.append)
    two, four = (path_forces(ev, design, p, frames=k) for k in (2, 4))
    assert check.motion == "arm_flexion.right" and check.frames == (2, 4)
    assert check.gaps[0] == pytest.approx(frame_gap(two, four, check.motion), rel=1e-6, abs=1e-9)
    assert [f.t for f in report.curve(check.motion, "on")] == pytest.approx([0.0, 0.25, 0.5, 0.75, 1.0])
    for a, b in zip(report.frames, four.frames):
        assert (a.motion, a.state, a.t) == (b.motion, b.state, b.t)
        assert a.energy_J == pytest.approx(b.energy_J, rel=1e-6)
    assert lines[0] == "2 frames: arm_flexion.right" and "4 frames: arm_flexion.right" in lines
    # a tolerance the first doubling meets stops there; one it cannot meet stops at max_frames
    assert check.converged == (check.gaps[0] <= 0.0)
    _, (loose,) = converged_path(ev, design, p, frames=2, tol=10.0, max_frames=8)
    assert loose.frames == (2, 4) and loose.converged
    with pytest.raises(ValueError, match="max_frames"):
        converged_path(ev, design, p, frames=4, max_frames=6)
