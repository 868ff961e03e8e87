"""``[solver] path_start``: the design loop's ON states also solved over their motion from
rest, that end kept where it is clearly lower (kgarment.design.path.motion_ends)."""

from __future__ import annotations

import dataclasses
import itertools
import tomllib

import numpy as np
import pytest

from kgarment.constants import PATH_START_FRAMES
from kgarment.design.beso import design_values
from kgarment.design.evaluate import MULTISTABLE
from kgarment.design.path import motion_ends
from kgarment.design.setup import setup_from_problem
from kgarment.errors import KgarmentError
from kgarment.problem import build_clutches, build_garment, parse_problem

SLEEVE = """
[garment]
template = "arm_sleeve.right"
subdivision = 0
[motions]
use = ["arm_flexion.right"]
[clutches]
layout = "arm_flexion"
[materials]
preset = "reference"
[solver]
path_start = {every}
workers = 1
"""


@pytest.fixture(scope="module")
def setup(anny_body):
    p = parse_problem(tomllib.loads(SLEEVE.format(every=3)))
    g = build_garment(p, anny_body)
    return setup_from_problem(p, anny_body, g, build_clutches(p, anny_body, g), "design")


def test_the_frames_lead_to_the_target_pose(setup):
    (frames,) = setup.path_frames.values()
    assert setup.path_start == 3 and len(frames) == PATH_START_FRAMES - 1
    target = setup.motions["arm_flexion.right"].garment_x0
    # the body's pose moves towards the target frame by frame: the attached garment with it
    gaps = [float(np.abs(f.garment_x0 - target).max()) for f in frames]
    assert all(a > b for a, b in itertools.pairwise(gaps)) and gaps[-1] > 1e-4


def test_a_higher_equilibrium_is_replaced_and_a_lower_one_kept(setup):
    """Given an ON equilibrium that is not one (the skin-tight start stopped after 2 Newton
    iterations: higher energy, unconverged), the motion's converged end replaces it; given
    the motion's own end, nothing changes; OFF states are never touched."""
    keyed = setup.states()
    mask = np.ones(setup.model.n_faces, bool)
    mask[::3] = False
    design = design_values(mask)
    stopped = setup.solve(design, [s for _, s in keyed], options=dataclasses.replace(setup.solver, max_iter=2))
    assert not any(r.converged for r in stopped)
    out, newton = motion_ends(setup, design, keyed, stopped, setup.solver)
    on = [i for i, (k, _) in enumerate(keyed) if k[1] == "on"]
    off = [i for i, (k, _) in enumerate(keyed) if k[1] == "off"]
    assert newton > 0 and on and off
    for i in on:
        assert out[i] is not stopped[i] and out[i].converged and out[i].name == keyed[i][1].name
    for i in off:
        assert out[i] is stopped[i]
    again, _ = motion_ends(setup, design, keyed, out, setup.solver)
    for i in on:  # its own end (solved again the same way) is not lower by MULTISTABLE
        assert again[i] is out[i] or again[i].total_energy < out[i].total_energy * (1 - MULTISTABLE)
        assert again[i].total_energy == pytest.approx(out[i].total_energy, rel=MULTISTABLE)


def test_bad_values_and_uses_are_one_line_errors(anny_body):
    with pytest.raises(KgarmentError, match="path_start"):
        parse_problem(tomllib.loads(SLEEVE.format(every=-1)))
    p = parse_problem(tomllib.loads(SLEEVE.format(every=0)))
    g = build_garment(p, anny_body)
    assert setup_from_problem(p, anny_body, g, build_clutches(p, anny_body, g), "design").path_frames == {}
