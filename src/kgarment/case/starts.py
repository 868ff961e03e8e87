"""The starts of a design's equilibrium and the choice between the equilibria they reach.

A membrane without bending on a frictionless body can have several equilibria (the
garment settles in different places).  A design's state is solved from two starts (the
garment as put on, and a start along the design run's path); :func:`pick_equilibrium`
keeps the converged solution of lower total energy, the more stable one, and reports the
other when the two differ by more than :data:`MULTISTABLE` (relative total energy).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from kgarment.case.keys import Start, started
from kgarment.case.levels import put_on
from kgarment.case.setup import Case
from kgarment.sim import SimState, StateResult

MULTISTABLE = 0.01  # two equilibria whose total energies differ by more than this (relative) are reported


@dataclass(frozen=True)
class Equilibrium:
    """The equilibrium kept for one state, and the other start's when it differs.

    result : the kept StateResult (converged before unconverged, then the lower total
    energy);  other : the other converged solution when the two store energies more than
    :data:`MULTISTABLE` apart (relative), else None.
    """

    result: StateResult
    other: StateResult | None = None
    from_path: bool = False


def with_known(e: Equilibrium, known: StateResult | None) -> Equilibrium:
    """``e`` against an equilibrium found otherwise (the motion from rest; None: none):
    ``known`` replaces it (``from_path``, ``e``'s reported as the other) where it is converged
    and lower by more than :data:`MULTISTABLE`; closer ones leave ``e`` as it is, so the
    numbers do not change with ``--path`` for round-off."""
    if known is None or not known.converged:
        return e
    if not e.result.converged:
        return Equilibrium(known, from_path=True)
    p = pick_equilibrium(e.result, known)
    if p.result is known and p.other is not None:
        return Equilibrium(known, e.result, from_path=True)
    return e


def pick_equilibrium(a: StateResult, b: StateResult) -> Equilibrium:
    """The better of two solutions of one state (``a`` on ties) and whether they differ."""
    if a.converged != b.converged:
        return Equilibrium(a if a.converged else b)
    if not a.converged:
        return Equilibrium(a if a.convergence.residual <= b.convergence.residual else b)
    keep, other = (a, b) if a.total_energy <= b.total_energy else (b, a)
    apart = abs(keep.total_energy - other.total_energy) > MULTISTABLE * max(abs(keep.total_energy), 1e-300)
    return Equilibrium(keep, other if apart else None)


def solve_two_starts(case: Case, design: np.ndarray, states: list[SimState], starts: list,
                     options=None) -> tuple[list[StateResult], list[StateResult]]:
    """``states`` solved for ``design`` (m,) from ``starts`` (per state (N, 3) positions or
    None) and from the garment as put on (the skin-tight garment, or on a subdivided garment
    its equilibrium one level down, :func:`kgarment.case.levels.put_on`), in one batch
    (the workers share the 2n solves instead of waiting twice for the slowest); returns
    (from ``starts``, as put on), both under the states' own names.  ``options``: the case's
    solver options unless given."""
    n = len(states)
    worn = put_on(case, design, list(states))
    skin = [dataclasses.replace(s, name=started(s.name, Start.SKIN_TIGHT if w is None else Start.PUT_ON))
            for s, w in zip(states, worn)]
    both = case.solve(design, list(states) + skin, warm_start=list(starts) + worn, options=options)
    return both[:n], [dataclasses.replace(r, name=s.name) for r, s in zip(both[n:], states)]


