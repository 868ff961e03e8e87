"""Subdivision levels (design.levels): the design moved down a level, and the garment as put
on solved one level down first (the evaluator's second start on subdivided garments)."""

from __future__ import annotations

import dataclasses
import tomllib

import numpy as np
import pytest
from tiny_problems import TINY_SLEEVE

from kgarment import constants
from kgarment.case.levels import level_problem, parent_faces, put_on, restrict, vertex_map
from kgarment.case.starts import solve_two_starts
from kgarment.case.values import design_values
from kgarment.evaluate.evaluator import Evaluator
from kgarment.evaluate.loads import coarse_starts
from kgarment.problem import parse_problem


def test_restrict_keeps_a_face_where_at_least_half_its_children_are_reinforced():
    rng = np.random.default_rng(3)
    coarse = rng.random(50) < 0.4
    parent = parent_faces(200, 50)
    # a fine design made of whole parents restricts to those parents
    np.testing.assert_array_equal(restrict(design_values(coarse[parent]), 50), design_values(coarse))
    # children counted: 2 of 4 reinforced -> reinforced, 1 of 4 -> not
    fine = np.zeros(200, bool)
    fine[[0, 50]] = True   # face 0: children 0 and 50 (2 of 4)
    fine[[1]] = True       # face 1: 1 of 4
    fine[[2, 52, 102, 152]] = True  # face 2: all four
    d = restrict(design_values(fine), 50) > 0.5
    assert d[0] and not d[1] and d[2] and d.sum() == 2
    with pytest.raises(ValueError):
        restrict(np.ones(150), 50)


def _sleeve(level: int, layout: str = "arm_flexion"):
    return parse_problem(tomllib.loads(TINY_SLEEVE.replace("subdivision = 0", f"subdivision = {level}")
                                       .replace('layout = "arm_flexion"', f'layout = "{layout}"')))


@pytest.fixture
def nested_sleeve(monkeypatch):
    """Subdivided garments of any size start from one level down (the default from
    NESTED_VERTICES garment vertices on: the sleeve at subdivision 1 has 1,167)."""
    monkeypatch.setattr(constants, "NESTED_VERTICES", 0)


def test_only_large_subdivided_garments_start_one_level_down(anny_body):
    assert Evaluator.from_problem(_sleeve(1), body=anny_body).coarser is None  # 1,167 vertices
    assert constants.NESTED_VERTICES < 6635  # the shirt at subdivision 1, the paper's resolution's level below


def test_the_put_on_start_is_the_state_solved_one_level_down_and_mapped_up(anny_body, nested_sleeve):
    """On a subdivision-1 sleeve the second start of every state is its equilibrium at
    level 0 (the design restricted, from the skin-tight garment there), mapped up by the
    subdivision; the fine solve from it converges.  Level 0 has no level below: its
    start is the skin-tight garment."""
    fine = Evaluator.from_problem(_sleeve(1), body=anny_body)
    coarse = Evaluator.from_problem(level_problem(_sleeve(1), 0), body=anny_body)
    assert coarse.case.coarser is None and fine.case.coarser().level == 0
    rng = np.random.default_rng(0)
    parents = rng.random(coarse.n_faces) < 0.5
    design = design_values(parents[parent_faces(fine.n_faces, coarse.n_faces)])
    states = [s for _, s in fine.keyed()]
    starts = put_on(fine.case, design, states)
    assert len(starts) == len(states) == 2  # ON and OFF
    # independently: the same states solved on the level-0 garment, mapped up
    low = coarse.case.solve(restrict(design, coarse.n_faces), [s for _, s in coarse.keyed()])
    S = vertex_map(coarse.case.model.garment_faces, coarse.case.model.n_garment, fine.n_faces)
    for start, r in zip(starts, low):
        assert r.converged
        expect = fine.case.model.initial_positions(S @ r.x[: coarse.case.model.n_garment])
        np.testing.assert_allclose(start, expect, rtol=0, atol=1e-12)
    assert put_on(coarse.case, restrict(design, coarse.n_faces), [s for _, s in coarse.keyed()]) == [None, None]
    # the evaluator's second start is this one, and the fine solves converge from it
    _, worn = solve_two_starts(fine.case, design, states, [None, None])
    again = fine.case.solve(design, states, warm_start=starts)
    for a, b in zip(worn, again):
        assert a.converged and a.total_energy == b.total_energy


def test_every_start_of_an_evaluation_comes_from_one_level_down(anny_body, nested_sleeve):
    """The two-clutch sleeve at subdivision 1: the start along a run's path is the design's
    equilibrium at level 0 reached from level 0's fully reinforced garment, and each load
    state starts from an equilibrium of level 0 in its own activation (checked against the
    level-0 model: its old vertices are the level-0 garment's), mapped up; the evaluation
    from these starts converges in every state and the load states too."""
    nested = Evaluator.from_problem(_sleeve(1, "sleeve"), body=anny_body)
    low = nested.coarser
    assert low.coarser is None and low.n_faces * 4 == nested.n_faces
    m = nested.case.model
    faces = m.garment_rest[m.garment_faces].mean(axis=1)
    anchors = np.concatenate([c.vertices[c.anchors] for c in m.clutches])
    near = np.linalg.norm(faces[:, None] - anchors[None], axis=2).min(axis=1) < 0.05
    design = design_values(near | np.isin(np.arange(nested.n_faces), nested.case.attached))
    keyed = nested.keyed()
    idx, d, down = nested.down(design, keyed)
    assert idx == [0, 1]
    there = low.case.solve(d, [s for _, s in down], warm_start=[r.x for r in low.reference(down)])
    for start, r in zip(nested.from_full(design, keyed), there):
        np.testing.assert_allclose(start, nested.up(r.x), rtol=0, atol=1e-12)
    ev = nested.evaluate(design, loads=True)
    assert ev.converged and len(ev.loads.clutches) == 2
    solo = nested.activation_states([1.0, 0.0], label="only elbow_outer.R") + \
        nested.activation_states([0.0, 1.0], label="only elbow_inner.R")
    n_low = low.case.model.n_garment
    for (_, state), start in zip(solo, coarse_starts(nested, design, solo)):
        # the level-0 garment's own vertices, the clutches bound to them again: an equilibrium
        # there (to LOAD_TOL) but for the clutches, which settle without moving the garment
        x = low.case.model.initial_positions(start[:n_low])
        (r,) = low.case.solve(d, [dataclasses.replace(state, motion=low.case.motions[state.motion.name])],
                               warm_start=[x])
        assert r.converged
        assert np.abs(r.x[:n_low] - start[:n_low]).max() < 0.25 * low.case.model.mean_edge


def test_a_design_runs_iteration_0_starts_one_level_down(anny_body, nested_sleeve):
    """The fully reinforced garment of a design run's iteration 0 is solved from its
    equilibria one level down (the design setup's own coarser level), as the evaluator's
    are; later iterations start from the iteration before."""
    from kgarment.optimize.loop import initial_state
    from kgarment.optimize.loop import solve as loop_solve
    from kgarment.optimize.setup import setup_from_problem
    from kgarment.problem import build_clutches, build_garment

    p = _sleeve(1)
    garment = build_garment(p, anny_body)
    setup = setup_from_problem(p, anny_body, garment, build_clutches(p, anny_body, garment))
    assert setup.case.coarser().case.model.n_faces * 4 == setup.case.model.n_faces
    st = initial_state(setup)
    solved = loop_solve(setup, st)
    states = [s for _, s in setup.case.states()]
    again = setup.case.solve(st.design, states, warm_start=put_on(setup.case, st.design, states), options=setup.options(0))
    for a, b in zip(solved.results, again):
        assert a.converged and np.array_equal(a.x, b.x)
