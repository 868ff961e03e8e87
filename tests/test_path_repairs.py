"""The force-over-the-motion path's repairs of a switched equilibrium (kgarment.evaluate.path).

A path's frames are solved one after the other; where the energy drops by more than
PATH_JUMP from frame i - 1 to frame i, frame i - 1 is re-solved from frame i's equilibrium
and from the evaluator's starts, the lowest-energy converged solution kept.  These tests
drive one path's repairs (``_jump_repairs``, a generator that asks for the solves and
receives their results) with equilibria given by hand, so what is asked and what is kept
follow from the rule alone.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from kgarment.evaluate.path import PATH_JUMP, _jump_repairs


@dataclass
class Eq:
    """An equilibrium as the repairs read it: total energy (J), converged, positions."""

    total_energy: float
    converged: bool = True
    x: np.ndarray = None


def _path(energies):
    by_motion = {"m": [(f"m@{i}", (i + 1) / len(energies)) for i in range(len(energies))]}
    results = {("m", "on", i): Eq(e, True, np.full((2, 3), float(i))) for i, e in enumerate(energies)}
    return by_motion, results


def _state(label, motion, s):
    return (label, motion, s)


def test_a_drop_is_repaired_from_the_next_frame_and_the_lowest_solution_kept():
    by_motion, results = _path([1.0, 2.0, 1.5, 3.0])  # frame 1 -> 2 drops by 25%: frame 1 is suspect
    replaced: set = set()
    gen = _jump_repairs("m", "on", 4, by_motion, _state, results, replaced)
    state, warm, key = next(gen)
    assert state == ("m@1", "m", "on") and key == ("m@1", "on")
    np.testing.assert_array_equal(warm, results[("m", "on", 2)].x)  # from the later frame's equilibrium
    try:
        gen.send([Eq(1.6), Eq(1.4), Eq(0.1, converged=False)])  # an unconverged solution is never kept
        raise AssertionError("the path has no drop left: nothing more to ask")
    except StopIteration:
        pass
    assert results[("m", "on", 1)].total_energy == 1.4
    assert replaced == {("m", "on", 1)}
    energies = [results[("m", "on", i)].total_energy for i in range(4)]
    assert all(energies[i] >= (1 - PATH_JUMP) * energies[i - 1] for i in range(1, 4))


def test_a_repair_that_finds_nothing_lower_stops():
    by_motion, results = _path([1.0, 2.0, 1.5, 3.0])
    replaced: set = set()
    gen = _jump_repairs("m", "on", 4, by_motion, _state, results, replaced)
    next(gen)
    try:
        gen.send([Eq(2.5), Eq(2.0)])  # no lower equilibrium: the frame stays, the repairs end
        raise AssertionError("a pass that fixed nothing must end the repairs")
    except StopIteration:
        pass
    assert results[("m", "on", 1)].total_energy == 2.0 and not replaced


def test_a_repaired_frame_exposes_the_drop_before_it():
    by_motion, results = _path([1.0, 3.0, 3.5, 3.0])  # a drop from frame 2 to 3
    replaced: set = set()
    gen = _jump_repairs("m", "on", 4, by_motion, _state, results, replaced)
    asked = [next(gen)[0][0]]
    asked.append(gen.send([Eq(1.8), Eq(2.9)])[0][0])  # frame 2 -> 1.8: now frame 1 (3.0) drops to it
    try:
        gen.send([Eq(1.5), Eq(1.7)])  # frame 1 -> 1.5: no drop left
        raise AssertionError("the path has no drop left: nothing more to ask")
    except StopIteration:
        pass
    assert asked == ["m@2", "m@1"]
    assert [results[("m", "on", i)].total_energy for i in range(4)] == [1.0, 1.5, 1.8, 3.0]
    assert replaced == {("m", "on", 2), ("m", "on", 1)}
