"""``[solver] path_start``: the design loop's ON states also solved over their motion from
rest as the evaluator solves them, that end kept where the evaluator would keep it
(kgarment.optimize.motion_start.motion_ends)."""

from __future__ import annotations

import dataclasses
import itertools
import tomllib

import numpy as np
import pytest
from tiny_problems import TINY_SLEEVE

from kgarment.case import case_from_problem
from kgarment.case.frames import REST
from kgarment.case.starts import MULTISTABLE
from kgarment.case.values import design_values
from kgarment.errors import KgarmentError
from kgarment.evaluate.evaluator import Evaluator
from kgarment.evaluate.path import PATH_FRAMES, path_forces
from kgarment.optimize.motion_start import motion_ends
from kgarment.optimize.setup import setup_from_problem
from kgarment.problem import build_clutches, build_garment, parse_problem

SLEEVE = TINY_SLEEVE + """[solver]
path_start = {every}
workers = 1
"""


@pytest.fixture(scope="module")
def parts(anny_body):
    p = parse_problem(tomllib.loads(SLEEVE.format(every=3)))
    g = build_garment(p, anny_body)
    return p, anny_body, g, build_clutches(p, anny_body, g)


@pytest.fixture(scope="module")
def setup(parts):
    return setup_from_problem(*parts)


def test_the_frames_are_the_evaluators_and_lead_to_the_target_pose(setup):
    frames, index = setup.beso.path_frames
    assert setup.beso.path_start == 3 and REST in frames
    assert [t for _, m, t in index] == pytest.approx([k / PATH_FRAMES for k in range(1, PATH_FRAMES + 1)])
    target = setup.case.motions["arm_flexion.right"].garment_x0
    # the body's pose moves towards the target frame by frame (the attached garment with it),
    # the last frame is the target pose
    gaps = [float(np.abs(frames[label].garment_x0 - target).max()) for label, _, _ in index]
    assert all(a > b for a, b in itertools.pairwise(gaps)) and gaps[-1] < 1e-9


def test_a_higher_equilibrium_is_replaced_and_a_lower_one_kept(setup, parts):
    """Given an ON equilibrium that is not one (the skin-tight start stopped after 2 Newton
    iterations: higher energy, unconverged), the motion's converged end replaces it, and it is
    the end of ``evaluate --path`` (the evaluator's own motion from rest); given the motion's
    own end, nothing changes; OFF states are never touched."""
    keyed = setup.case.states()
    mask = np.ones(setup.case.model.n_faces, bool)
    mask[::3] = False
    design = design_values(mask)
    stopped = setup.case.solve(design, [s for _, s in keyed], options=dataclasses.replace(setup.case.solver, max_iter=2))
    assert not any(r.converged for r in stopped)
    out, moved = motion_ends(setup, design, keyed, stopped)
    on = [i for i, (k, _) in enumerate(keyed) if k[1] == "on"]
    off = [i for i, (k, _) in enumerate(keyed) if k[1] == "off"]
    assert moved == ["arm_flexion.right"] and on and off
    for i in on:
        assert out[i] is not stopped[i] and out[i].converged and out[i].name == keyed[i][1].name
    for i in off:
        assert out[i] is stopped[i]
    # the evaluator's motion from rest (its own setup, tolerance and frames) ends where the check did
    ev = Evaluator(case_from_problem(*parts))
    (end,) = (r for (m, s), r in path_forces(ev, design, parts[0], frames=PATH_FRAMES).ends.items() if s == "on")
    assert out[on[0]].total_energy == pytest.approx(end.total_energy, rel=1e-6)
    again, moved = motion_ends(setup, design, keyed, out)
    assert moved == []
    for i in on:  # its own end (solved again the same way) is not lower by MULTISTABLE
        assert again[i] is out[i] or again[i].total_energy < out[i].total_energy * (1 - MULTISTABLE)
        assert again[i].total_energy == pytest.approx(out[i].total_energy, rel=MULTISTABLE)


def test_bad_values_and_uses_are_one_line_errors(anny_body):
    with pytest.raises(KgarmentError, match="path_start"):
        parse_problem(tomllib.loads(SLEEVE.format(every=-1)))
    p = parse_problem(tomllib.loads(SLEEVE.format(every=0)))
    g = build_garment(p, anny_body)
    assert setup_from_problem(p, anny_body, g, build_clutches(p, anny_body, g)).beso.path_frames == ()
    for bad in (0, 201, 2.5):
        with pytest.raises(KgarmentError, match="path_frames"):
            parse_problem(tomllib.loads(SLEEVE.format(every=3) + f"path_frames = {bad}\n"))


def test_the_check_solves_the_frames_the_problem_asks_for(parts):
    """``[solver] path_frames``: the check's motion from rest in that many frames, the
    last one the target pose."""
    p = parse_problem(tomllib.loads(SLEEVE.format(every=3) + "path_frames = 4\n"))
    _, index = setup_from_problem(p, *parts[1:]).beso.path_frames
    assert [t for _, _, t in index] == pytest.approx([0.25, 0.5, 0.75, 1.0])


def test_the_reported_design_is_one_whose_motion_was_solved(tmp_path):
    """The best iteration of a path_start run is chosen among the iterations whose ON states
    were also solved over the motion (the others' objectives may be of an equilibrium the
    wearer never reaches), and its final evaluation is ``evaluate --path``'s (the path in
    the JSON, the rows saying which equilibrium each kept)."""
    import json

    from kgarment.cli import main
    from kgarment.design.run import best_iteration

    rows = [{"iteration": i, "area": 0.6, "objective": o, "unconverged_states": "", "path_checked": c}
            for i, (o, c) in enumerate([(1.0, False), (0.9, True), (3.0, False), (0.8, True)])]
    assert best_iteration(rows, 0.6, 0.15) == 1
    assert best_iteration([dict(r, path_checked=False) for r in rows], 0.6, 0.15) == 2  # none checked: all count
    problem = SLEEVE.format(every=2) + "[design]\ntarget_area = 0.6\ner = 0.15\nar_max = 0.05\nmax_iterations = 5\n"
    (tmp_path / "p.toml").write_text(problem)
    assert main(["-q", "design", str(tmp_path / "p.toml"), "--out", str(tmp_path / "run")]) == 0
    metrics = json.loads((tmp_path / "run" / "metrics.json").read_text())
    assert [r["path_checked"] for r in metrics] == [i > 0 and i % 2 == 0 for i in range(len(metrics))]
    final = json.loads((tmp_path / "run" / "final" / "evaluation.json").read_text())
    assert next(r for r in metrics if r["iteration"] == final["iteration"])["path_checked"]
    assert sorted({f["t"] for f in final["path"]["frames"]}) == pytest.approx([k / PATH_FRAMES  # rest, then frames
                                                                              for k in range(PATH_FRAMES + 1)])
    assert all(isinstance(r["from_path"], bool) for r in final["rows"])


def test_with_the_two_starts_the_state_becomes_the_evaluators_even_when_higher(setup):
    """With the iteration's two-start solves (skin_start) the checked state becomes what the
    evaluator reports, the lower of those and the motion's end: an equilibrium only the loop's
    continuation reached is dropped even where it stores less (stood in for here by a
    converged solve of a sparser design: lower energy, not the evaluator's)."""
    keyed = setup.case.states()
    mask = np.ones(setup.case.model.n_faces, bool)
    mask[::3] = False
    design = design_values(mask)
    sparse = design_values(np.arange(setup.case.model.n_faces) % 5 == 0)
    ends, _ = motion_ends(setup, design, keyed, setup.case.solve(design, [s for _, s in keyed],
                                                              options=dataclasses.replace(setup.case.solver, max_iter=2)))
    on = next(i for i, (k, _) in enumerate(keyed) if k[1] == "on")
    low = setup.case.solve(sparse, [s for _, s in keyed], options=setup.case.solver)
    assert low[on].converged and low[on].total_energy < ends[on].total_energy * (1 - MULTISTABLE)
    out, moved = motion_ends(setup, design, keyed, low, starts=ends)
    assert moved == ["arm_flexion.right"]
    assert out[on].total_energy == pytest.approx(ends[on].total_energy, rel=MULTISTABLE)
    # without the starts a lower equilibrium is kept
    kept, moved = motion_ends(setup, design, keyed, low)
    assert kept[on] is low[on] and moved == []
    # where the loop already holds the evaluator's equilibrium nothing moves
    same, moved = motion_ends(setup, design, keyed, out, starts=ends)
    assert moved == [] and same[on] is out[on]
