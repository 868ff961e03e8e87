"""Subdivision levels of one garment: the exact maps between them, and the garment as put on
solved level by level (nested iteration).

Midpoint subdivision splits each face into four children of a quarter of its area, in
blocks (:func:`kgarment.garment.topology.midpoint_subdivide`): child ``c`` of a level with
``m`` faces has parent ``c mod m``, and the fine level's vertices are the coarse ones
followed by the edge midpoints.  So a design moves down a level by its children's majority
(:func:`restrict`) and up by its parents (:func:`parent_faces`), and positions move up
exactly by :func:`vertex_map`.  The coarse-to-fine design (:mod:`kgarment.optimize.refine`)
and the nested start below use these maps.

**The garment as put on, solved level by level** (:func:`put_on`).  The evaluator solves
every state from two starts, one of them the garment as put on (docs/method/index.md: a design run's
first iteration starts there).  On a fine garment the skin-tight garment is a poor start:
the cloth must slide a long way round the body to its equilibrium, and a slide is the
softest of the garment's modes, whose stiffness falls with the square of its wavelength in
edges, so Newton crawls along it the longer the finer the mesh.  Nested iteration (the
start of full multigrid) solves the state on the garment one level down from its own start
-- the skin-tight garment at level 0 -- and starts the fine solve from that equilibrium,
prolongated: the slide is done where it is cheap, the fine solve adds the detail.  The
coarse level's design is the fine design restricted (:func:`restrict`), its states the same
motions and activations on the coarse garment (the same body and clutch specs, each clutch
walked out on the coarse garment), solved with the coarse level's own options and store,
so a later evaluation of the run reads them back.  A design run's iteration 0 (the fully
reinforced garment, the objective's reference) starts the same way: in a coarse-to-fine run
the levels below have solved exactly those states in their own iteration 0, and the
machine's store of fully reinforced garments hands them over (measured against the
skin-tight start: docs/notes/code.md, "kgarment.case.levels").
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from kgarment.case.keys import Start, level_name
from kgarment.case.values import design_values
from kgarment.garment.topology import midpoint_subdivide
from kgarment.problem import Problem
from kgarment.sim import SimState


def level_problem(problem: Problem, level: int) -> Problem:
    """``problem`` at subdivision ``level``, designed there plainly (no further levels)."""
    return dataclasses.replace(problem, garment=dataclasses.replace(problem.garment, subdivision=level),
                               design=dataclasses.replace(problem.design, levels=()))


def parent_faces(n_fine: int, n_coarse: int) -> np.ndarray:
    """(n_fine,) the coarse face each fine face lies in (children come in blocks of
    ``n_coarse``, :func:`kgarment.garment.topology.midpoint_subdivide`)."""
    if n_fine % n_coarse or (n_fine // n_coarse) & (n_fine // n_coarse - 1):
        raise ValueError(f"{n_fine} faces are not a midpoint subdivision of {n_coarse}")
    return np.arange(n_fine) % n_coarse


def vertex_map(coarse_faces: np.ndarray, n_coarse: int, n_fine_faces: int) -> sp.csr_matrix:
    """(n_fine, n_coarse) sparse map of vertex positions from a coarse garment (faces (m, 3),
    ``n_coarse`` vertices) to its subdivision with ``n_fine_faces`` faces."""
    faces, S = np.asarray(coarse_faces), sp.identity(n_coarse, format="csr")
    while len(faces) < n_fine_faces:
        faces, step = midpoint_subdivide(faces, S.shape[0])
        S = (step @ S).tocsr()
    if len(faces) != n_fine_faces:
        raise ValueError(f"{n_fine_faces} faces are not a midpoint subdivision of {len(coarse_faces)}")
    return S


def restrict(design: np.ndarray, n_coarse: int) -> np.ndarray:
    """``design`` (n_fine,) (> 0.5 = reinforced) on the garment ``n_coarse`` faces down: a
    coarse face is reinforced where at least half of its children are (design values,
    :func:`kgarment.case.values.design_values`)."""
    solid = np.asarray(design) > 0.5
    parent = parent_faces(len(solid), n_coarse)
    share = np.bincount(parent, weights=solid, minlength=n_coarse) / (len(solid) // n_coarse)
    return design_values(share >= 0.5)


@dataclass(frozen=True)
class Coarser:
    """The level below a case's garment: its ``case`` (the same problem, built the same way,
    at subdivision ``level``) and ``prolong``, the (n, n_coarse) map of garment vertex
    positions up to the case's garment (:func:`vertex_map`)."""

    level: int
    case: object
    prolong: sp.csr_matrix


def states_down(coarser: Coarser, states: list[SimState],
                start: Start | None = None) -> tuple[list[int], list[SimState]]:
    """The ``states`` (of the level above ``coarser``) that the coarser level has: their
    indices, and each as that level's state (the same motion, activation and name, with
    ``@level<L>`` and ``start``'s tag appended: :func:`kgarment.case.keys.level_name`)."""
    low = coarser.case
    idx = [i for i, s in enumerate(states) if s.motion.name in low.motions]
    return idx, [dataclasses.replace(states[i], motion=low.motions[states[i].motion.name],
                                     name=level_name(states[i].name, coarser.level, start))
                 for i in idx]


def prolong(case, coarser: Coarser, x: np.ndarray) -> np.ndarray:
    """An equilibrium ``x`` (N_coarse, 3) of ``coarser``'s garment as positions (N, 3) of
    ``case``'s: garment vertices by the subdivision, clutches bound to them again."""
    return case.model.initial_positions(coarser.prolong @ np.asarray(x)[: coarser.case.model.n_garment])


def put_on(case, design: np.ndarray, states: list[SimState]) -> list[np.ndarray | None]:
    """Per state of ``case`` (a Case) the start of the garment as put on, for
    ``design`` (m,): None (the skin-tight garment) where the case has no coarser level or
    the coarser level has no such motion, else that state's equilibrium one level down --
    itself solved from its own put-on start, the design restricted -- prolongated to this
    garment (N, 3) (module docstring)."""
    coarser = case.coarser() if case.coarser is not None else None
    out: list[np.ndarray | None] = [None] * len(states)
    if coarser is None:
        return out
    low = dataclasses.replace(coarser.case, store=case.store)
    idx, down = states_down(coarser, states)
    if not idx:
        return out
    d = restrict(design, low.model.n_faces)
    for i, r in zip(idx, low.solve(d, down, warm_start=put_on(low, d, down))):
        out[i] = prolong(case, coarser, r.x)
    return out
