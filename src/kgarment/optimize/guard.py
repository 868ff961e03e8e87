"""The step guard: a BESO step that breaks a motion's load path is taken back.

BESO removes the faces of lowest sensitivity a few percent at a time.  A membrane on a
frictionless body has several equilibria, and removing a few faces of a thin link can move
a motion's ON state to another one (a sleeve turns about the arm until its clutch lies over
the elbow's hinge axis; a back band rides up): the motion's ON - OFF gain falls to almost
nothing in one step, its sensitivities with it, and BESO goes on cutting the now idle
path.

With ``[design] guard = g`` (0 < g < 1) a step after which some motion's term of the
objective (:func:`kgarment.optimize.objective.objective_terms`) is below (1 - g) times the
last accepted iteration's is *rejected*: the iteration is recorded (its metrics, flagged
``rejected``), but the next design is made again from the last accepted design, its
sensitivities and warm starts, towards the same target area, with the half of the faces
that the rejected step removed that ranked highest for the collapsed motions at the last
accepted iteration kept (*guarded*: ranked above every other face from then on; a step that
collapses again guards half of the rest, and so on).  The
guard applies only to terms of at least :data:`~kgarment.constants.GUARD_FLOOR` (a load
path worth keeping), lets the step through after
:data:`~kgarment.constants.GUARD_RETRIES` rejections in a row, and keeps the guarded
faces' area below :data:`~kgarment.constants.GUARD_AREA` of the target area.

With ``[design] lockout`` a motion's term also pays for what the other motions' clutch sets
store in it (its ``lock:`` states), and those states are the hardest to solve (a buckled,
idle clutch on a bent limb).  The guard watches the load path, so it reads each motion's term
without that penalty (the ``gain[motion]`` column), and a ``lock:`` state that did not
converge does not keep it from judging a step.
"""

from __future__ import annotations

import numpy as np

from kgarment.case.keys import GAIN, TERM, Kind, motion_columns, parse_state_name
from kgarment.constants import GUARD_AREA, GUARD_FLOOR, GUARD_RETRIES

REJECTED = "rejected"  # metrics column: the motions whose term collapsed ("" if accepted)


def blinding(unconverged) -> list[str]:
    """The states among ``unconverged`` (names, or a metrics row's ";"-joined string) without
    which the guard cannot judge a step: all but the ``lock:`` states, whose energy only the
    lockout penalty reads (:data:`GAIN` leaves it out)."""
    names = [n for n in unconverged.split(";") if n] if isinstance(unconverged, str) else list(unconverged)
    return [n for n in names if not _is_lock(n)]


def _is_lock(name: str) -> bool:
    """Whether the state named ``name`` is a ``lock:`` state (a name not of a state's form is not)."""
    try:
        return parse_state_name(name)[0].kind is Kind.LOCK
    except ValueError:
        return False


def collapsed(terms: dict[str, float], before: dict[str, float], guard: float) -> list[str]:
    """The motions whose term fell below (1 - ``guard``) of ``before`` (their terms at the
    last accepted iteration), among those whose term there was at least GUARD_FLOOR."""
    if guard <= 0:
        return []
    return [m for m, t in terms.items()
            if before.get(m, 0.0) >= GUARD_FLOOR and t < (1.0 - guard) * before[m]]


def last_accepted(metrics) -> int | None:
    """Index (into ``metrics``, one row per finished iteration) of the last accepted
    iteration whose states converged (the guard's reference; a ``lock:`` state may not have,
    :func:`blinding`), or None."""
    for i in range(len(metrics) - 1, -1, -1):
        if not metrics[i].get(REJECTED) and not blinding(metrics[i].get("unconverged_states", "")):
            return i
    return None


def rejections_in_a_row(metrics) -> int:
    """How many of the last rows were rejected steps."""
    n = 0
    for row in reversed(metrics):
        if not row.get(REJECTED):
            break
        n += 1
    return n


def terms_of(row: dict) -> dict[str, float]:
    """{motion: term} recorded in a metrics row."""
    return motion_columns(row, TERM)


def paths_of(row: dict) -> dict[str, float]:
    """{motion: what the guard watches}: its :data:`GAIN` where the row has one (a run with
    lockout), else its term."""
    return motion_columns(row, GAIN) or terms_of(row)


def guard_step(metrics, terms: dict[str, float], guard: float, removed: np.ndarray, guarded: np.ndarray | None,
               areas: np.ndarray, target: float,
               accepted_alpha: dict[str, np.ndarray] | None = None) -> tuple[list[str], np.ndarray | None]:
    """Whether this iteration's step is rejected: (the motions whose term collapsed, or []
    when the step is accepted; the guarded faces after it).

    metrics : the rows of the iterations before this one;  terms : {motion: this iteration's
    term, or its gain with lockout} (:func:`paths_of` of its row);  removed : (m,) bool
    faces of the last accepted design that this iteration's design lacks;  guarded : (m,) bool faces already guarded, or None;  areas : (m,) m^2;
    target : the target area share;  accepted_alpha : {motion: (m,) its sensitivities at the
    last accepted iteration} (None: every removed face is guarded).
    """
    a = last_accepted(metrics)
    if a is None or guard <= 0:
        return [], guarded
    motions = collapsed(terms, paths_of(metrics[a]), guard)
    if not motions or rejections_in_a_row(metrics) >= GUARD_RETRIES:
        return [], guarded
    cand = np.flatnonzero(removed & ~guarded) if guarded is not None else np.flatnonzero(removed)
    if accepted_alpha is not None and len(cand) > 1:
        score = sum(accepted_alpha[m][cand] for m in motions)
        cand = cand[np.argsort(-score, kind="stable")[: (len(cand) + 1) // 2]]
    new = np.zeros(len(removed), bool) if guarded is None else guarded.copy()
    new[cand] = True
    if areas[new].sum() > GUARD_AREA * target * areas.sum():
        return [], guarded
    return motions, new


def boosted(alpha: np.ndarray, guarded: np.ndarray | None) -> np.ndarray:
    """(m,) sensitivities with the guarded faces ranked above all others."""
    if guarded is None or not guarded.any():
        return alpha
    return np.where(guarded, alpha.max() + 1.0, alpha)
