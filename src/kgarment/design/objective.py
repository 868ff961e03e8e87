"""Design objectives: how per-state sensitivities and energies combine (method.md §6).

``active``     the paper's: maximise E_ON - E_OFF per motion; both sensitivities divided by
               that motion's maximum ON sensitivity, summed over motions.  ON is the
               motion's activation set ([motions.activation]; all clutches by default).
               With ``[design] lockout = w``, each motion also pays w times the energy
               that every other motion's set stores in it beyond OFF (``lock:`` states:
               E_ON - E_OFF - w * sum(E_LOCK - E_OFF)), so that switching on the flexion
               clutch does not lock extension.
               With ``[design] balance = w`` (sets of two clutches or more), each motion also
               rewards every clutch of its set carrying load on its own (``solo:`` states,
               that clutch alone ON): with G_c = E_solo:c - E_OFF (the numerator of the
               clutch's share in ``kgarment.design.loads``), the motion's gain becomes
               G + w sum_c G_c, each G_c's sensitivity scaled to the size of G's (divided by
               its largest absolute value, times the ON state's largest): every clutch's own
               load path counts, however little it carries yet, so BESO need not route the
               motion through the strongest clutch alone (measured in the README: at 15%
               area the arms-forward shirt still ends on one path).
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


def _solos(values: dict, motion: str) -> list:
    """The ``solo:`` states of ``motion`` among the keys of ``values``."""
    return [v for (m, s), v in values.items() if m == motion and s.startswith("solo:")]


def combine_sensitivities(kind: str, alpha: dict[tuple[str, str], np.ndarray], motions,
                          lockout: float = 0.0, balance: float = 0.0) -> np.ndarray:
    """(m,) combined sensitivity from per-(motion, state) sensitivities, each (m,);
    ``lockout`` weighs the ``lock:`` states, ``balance`` the ``solo:`` states (both the
    active objective)."""
    total = 0.0
    for motion in motions:
        if kind == "active":
            on, off = alpha[(motion, "on")], alpha[(motion, "off")]
            gain = on - off
            for lock in _locks(alpha, motion) if lockout > 0 else ():
                gain = gain - lockout * (lock - off)
            for solo in _solos(alpha, motion) if balance > 0 else ():
                g = solo - off
                gain = gain + balance * g * (on.max() / max(np.abs(g).max(), 1e-300))
            total = total + gain / max(on.max(), 1e-300)
        else:
            state = states_needed(kind)[0]
            a = alpha[(motion, state)]
            total = total + a / max(a.max(), 1e-300)
    return np.asarray(total)


def objective_value(kind: str, energy: dict[tuple[str, str], float], reference: dict[tuple[str, str], float],
                    motions, lockout: float = 0.0, balance: float = 0.0) -> float:
    """Scalar objective for convergence tracking: per motion, the (ON - OFF) energy (less
    ``lockout`` times each ``lock:`` state's energy beyond OFF), or the energy, divided by the
    fully reinforced design's energy in the first state; plus ``balance`` times each
    ``solo:`` state's energy beyond OFF over the fully reinforced design's in that state
    (the ON state's where ``reference`` lacks it); summed."""
    total = 0.0
    for motion in motions:
        if kind == "active":
            off = energy[(motion, "off")]
            gain = energy[(motion, "on")] - off
            for lock in _locks(energy, motion) if lockout > 0 else ():
                gain -= lockout * (lock - off)
            total += gain / reference[(motion, "on")]
            for (m, s), e in energy.items() if balance > 0 else ():
                if m == motion and s.startswith("solo:"):
                    total += balance * (e - off) / reference.get((m, s), reference[(motion, "on")])
        else:
            s = states_needed(kind)[0]
            total += energy[(motion, s)] / reference[(motion, s)]
    return float(total)
