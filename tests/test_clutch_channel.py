"""``[clutches] channel``: each clutch runs in a channel of the connecting material sewn to
the garment, its centre line held to the garment as stiffly as reinforced fabric instead of
the weak tie of the paper's build (kgarment.sim.model, ``tie``)."""

from __future__ import annotations

import tomllib

import numpy as np
import pytest
from tiny_problems import TINY_SLEEVE

from kgarment.case import case_from_problem
from kgarment.errors import KgarmentError
from kgarment.problem import build_clutches, build_garment, override, parse_problem
from kgarment.problem.build import build_model
from kgarment.sim import SimState, solve_states
from kgarment.sim.springs import GROUPS

CABLE = TINY_SLEEVE.replace('layout = "arm_flexion"', 'layout = "arm_flexion"\nmodel = "cable"\n'
                            'holding_stress = 1.0e6\nbuckle = true\nchannel = {channel}')


def _tie_gaps(model, x: np.ndarray) -> np.ndarray:
    """(t,) m: how far each tied centre-line vertex of the clutches is from its garment point."""
    spr = model.static_springs
    tie = spr.group == GROUPS.index("tie")
    assert tie.sum() >= 5
    at = np.einsum("sk,skd->sd", spr.coef[tie], x[spr.index[tie]]) - spr.target[tie]
    return np.linalg.norm(at, axis=1)


@pytest.fixture(scope="module")
def solved(anny_body):
    """Flexion's ON state of the tiny sleeve with a cable clutch over the elbow, fully
    reinforced, without and with the channel: {channel: (model, equilibrium)}."""
    out = {}
    for channel in (False, True):
        p = parse_problem(tomllib.loads(CABLE.format(channel=str(channel).lower())))
        g = build_garment(p, anny_body)
        model = build_model(p, g, build_clutches(p, anny_body, g))
        assert model.clutch_channel == channel
        setup = case_from_problem(p, anny_body, g, build_clutches(p, anny_body, g))
        st = SimState.create(setup.motions["arm_flexion.right"], [1.0], name="on")
        (r,) = solve_states(model, np.ones(model.n_faces), [st], options=setup.solver)
        assert r.converged
        out[channel] = (model, r)
    return out


def test_the_channel_keeps_the_strip_on_the_garment(solved):
    """The cable pulled taut over the bent elbow drags its weakly tied centre line across the
    sleeve (centimetres); in a channel it stays with the garment under it."""
    free, sewn = (_tie_gaps(model, r.x) for model, r in (solved[False], solved[True]))
    assert free.max() > 0.01  # the test means something: the free strip moves a centimetre or more
    assert sewn.max() < 0.5 * free.max() and sewn.mean() < 0.5 * free.mean()


def test_the_channel_is_hardware_of_the_problem():
    p = parse_problem(tomllib.loads(CABLE.format(channel="true")))
    hw = p.clutch_spec().hardware
    assert hw.channel and hw.to_dict()["channel"] is True  # written to the run's problem.toml
    assert "channel" not in parse_problem(tomllib.loads(CABLE.format(channel="false"))).clutch_spec().hardware.to_dict()
    with pytest.raises(KgarmentError, match="channel"):
        parse_problem(tomllib.loads(CABLE.format(channel='"sewn"')))


def test_the_command_line_sets_the_channel_over_the_file():
    from kgarment.cli import main

    p = parse_problem(tomllib.loads(CABLE.format(channel="false")))
    assert override(p, channel=True).clutch_spec().hardware.channel
    assert not override(override(p, channel=True), channel=False).clutch_spec().hardware.channel
    assert override(p).clutch_spec().hardware == p.clutch_spec().hardware  # None keeps the file's
    with pytest.raises(SystemExit):  # a flag, not a value
        main(["evaluate", "run", "--channel", "yes"])
