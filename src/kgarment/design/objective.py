"""Design objectives: how per-state sensitivities and energies combine (method.md §6).

``active``     the paper's: maximise E_ON - E_OFF per motion; both sensitivities divided by
               that motion's maximum ON sensitivity, summed over motions.  ON is the
               motion's activation set ([motions.activation]; all clutches by default).
               With ``[design] lockout = w``, each motion also pays w times the energy
               that every other motion's set stores in it beyond OFF (``lock:`` states:
               E_ON - E_OFF - w * sum(E_LOCK - E_OFF)), so that switching on the flexion
               clutch does not lock extension.
``passive``    the 2022 predecessor: maximise the energy of each motion, no clutches.
``compliance`` ON only (with clutches), the single objective the paper compares against.
"""

from __future__ import annotations

import numpy as np

from kgarment.errors import unknown
from kgarment.problem.spec import OBJECTIVE_NAMES as OBJECTIVES


def states_needed(kind: str) -> tuple[str, ...]:
    """Activation states the objective needs: ("on", "off"), ("on",) or ("none",)."""
    if kind == "active":
        return ("on", "off")
    if kind == "compliance":
        return ("on",)
    if kind == "passive":
        return ("none",)
    raise unknown("objective", kind, OBJECTIVES)


def _locks(values: dict, motion: str) -> list:
    """The ``lock:`` states of ``motion`` among the keys of ``values``."""
    return [v for (m, s), v in values.items() if m == motion and s.startswith("lock:")]


def combine_sensitivities(kind: str, alpha: dict[tuple[str, str], np.ndarray], motions,
                          lockout: float = 0.0) -> np.ndarray:
    """(m,) combined sensitivity from per-(motion, state) sensitivities, each (m,);
    ``lockout`` weighs the ``lock:`` states (the active objective)."""
    total = 0.0
    for motion in motions:
        if kind == "active":
            on, off = alpha[(motion, "on")], alpha[(motion, "off")]
            gain = on - off
            for lock in _locks(alpha, motion) if lockout > 0 else ():
                gain = gain - lockout * (lock - off)
            total = total + gain / max(on.max(), 1e-300)
        else:
            state = states_needed(kind)[0]
            a = alpha[(motion, state)]
            total = total + a / max(a.max(), 1e-300)
    return np.asarray(total)


def objective_value(kind: str, energy: dict[tuple[str, str], float], reference: dict[tuple[str, str], float],
                    motions, lockout: float = 0.0) -> float:
    """Scalar objective for convergence tracking: per motion, the (ON - OFF) energy (less
    ``lockout`` times each ``lock:`` state's energy beyond OFF), or the energy, divided by
    the fully reinforced design's energy in the first state, summed."""
    total = 0.0
    for motion in motions:
        if kind == "active":
            off = energy[(motion, "off")]
            gain = energy[(motion, "on")] - off
            for lock in _locks(energy, motion) if lockout > 0 else ():
                gain -= lockout * (lock - off)
            total += gain / reference[(motion, "on")]
        else:
            s = states_needed(kind)[0]
            total += energy[(motion, s)] / reference[(motion, s)]
    return float(total)
