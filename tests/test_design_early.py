"""``[design] early``: a motion also designed for part of the way (the body posed at a
share t of its movement), as one more state of the design objective, sharing its motion's weight."""

from __future__ import annotations

import tomllib

import numpy as np
import pytest
from tiny_problems import TINY_SLEEVE

from kgarment.case import case_from_problem
from kgarment.case.frames import frame_motions
from kgarment.errors import KgarmentError
from kgarment.optimize.setup import setup_from_problem
from kgarment.problem import build_clutches, build_garment, parse_problem, problem_to_dict

EARLY = TINY_SLEEVE + """[design]
early = { "arm_flexion.right" = 0.5 }
"""


def test_parsed_written_and_read_back():
    p = parse_problem(tomllib.loads(EARLY))
    assert p.design.early == (("arm_flexion.right", 0.5),)
    assert parse_problem(problem_to_dict(p)).design.early == p.design.early
    assert "early" not in problem_to_dict(parse_problem(tomllib.loads(TINY_SLEEVE)))["design"]  # hashes stay


@pytest.mark.parametrize(("value", "says"), [
    ('{ "arm_raise" = 0.5 }', "not a motion of the problem; its motions: arm_flexion.right"),
    ('{ "arm_flexion.right" = 1.0 }', "a number in (0, 1)"),
    ('{ "arm_flexion.right" = "half" }', "a number in (0, 1)"),
    ("0.5", "must be a table of motion = share"),
])
def test_bad_early_is_one_line_naming_what_is_allowed(value, says):
    with pytest.raises(KgarmentError) as e:
        parse_problem(tomllib.loads(TINY_SLEEVE + f"[design]\nearly = {value}\n"))
    assert says in str(e.value) and "\n" not in str(e.value)


def test_the_early_pose_is_the_motion_part_of_the_way_in_design_runs_only(anny_body):
    """The design setup has the motion at t = 0.5 as one more motion, ON (the motion's
    clutch set) and OFF, its garment where the force over the motion poses it at t = 0.5
    (an independent route: the path's frames); an evaluation has the target poses only."""
    p = parse_problem(tomllib.loads(EARLY))
    g = build_garment(p, anny_body)
    strips = build_clutches(p, anny_body, g)
    setup = setup_from_problem(p, anny_body, g, strips)
    keys = [k for k, _ in setup.case.states()]
    assert keys == [("arm_flexion.right", "on"), ("arm_flexion.right", "off"),
                    ("arm_flexion.right@0.50", "on"), ("arm_flexion.right@0.50", "off")]
    frames, _ = frame_motions(p, ["arm_flexion.right"], 2)
    early = setup.case.motions["arm_flexion.right@0.50"].garment_x0
    assert np.array_equal(early, frames["arm_flexion.right@0.500"].garment_x0)
    last, target = frames["arm_flexion.right@1.000"].garment_x0, setup.case.motions["arm_flexion.right"].garment_x0
    assert np.array_equal(last, target) and np.abs(early - target).max() > 1e-3
    on = dict(setup.case.states())
    assert on[("arm_flexion.right@0.50", "on")].activation == on[("arm_flexion.right", "on")].activation
    assert [k for k, _ in case_from_problem(p, anny_body, g, strips).states()] == keys[:2]
    # the motion and its early pose share one motion's weight in the objective
    assert setup.beso.shares == {"arm_flexion.right": 0.5, "arm_flexion.right@0.50": 0.5}


def test_a_motion_and_its_early_poses_split_one_share():
    from kgarment.case.frames import early_shares

    assert early_shares(()) == {}
    two = early_shares((("a", 0.25), ("a", 0.5), ("b", 0.5)))
    assert two == {"a": 1 / 3, "a@0.25": 1 / 3, "a@0.50": 1 / 3, "b": 0.5, "b@0.50": 0.5}
