"""Design objectives: how per-state sensitivities and energies combine (docs/method/index.md, "BESO").

``active``     the paper's: maximise E_ON - E_OFF per motion; both sensitivities divided by
               that motion's maximum ON sensitivity, summed over motions.  ON is the
               motion's activation set ([motions.activation]; all clutches by default).
               With ``[design] lockout = w``, each motion also pays w times the energy
               that every other motion's set stores in it beyond OFF (``lock:`` states:
               E_ON - E_OFF - w * sum(E_LOCK - E_OFF)), so that switching on the flexion
               clutch does not lock extension.
               With ``[design] balance = w`` (sets of two clutches or more), each motion also
               rewards every clutch of its set that carries little on its own (``solo:``
               states, that clutch alone ON): with G = E_ON - E_OFF, G_c = E_solo:c - E_OFF
               and the share s_c = G_c / G (``kgarment.evaluate.loads``), the gain becomes
               G + w sum_c h(G_c), h' = clip(1 - s_c / BALANCE_SHARE, 0, 1) (G held at the
               iteration's value): a clutch below the share BALANCE_SHARE is pushed towards
               it, one above it is left alone (the strongest clutch is not counted twice).
               Each G_c's sensitivity is scaled to the size of G's (divided by its largest
               absolute value, times the ON state's largest), so a clutch carrying nothing
               yet still counts.  w may differ per motion (``balance = { arms_raise = 2 }``:
               the other motions have no ``solo:`` states and no reward).  Measured in
               docs/notes/design.md, "Balance".

Shares (``DesignSetup.shares``): the beginning of a motion that ``[design] early`` adds is a
state of its own in the objective, but not a motion of its own: the motion and its early
poses split the motion's weight (flexion with one early pose: 1/2 each), so a motion
designed for its beginning too counts no more than one without.  Measured on the selective
sleeve (docs/notes/design.md, "The selective sleeve's holding force and early pose").
``[design] weights = { MOTION = w }`` multiplies a motion's share (and its early poses') by
w: the paper counts every motion equally, a designer may rank them (the selective sleeve's
extension, docs/notes/selective.md, "Motion weights").

How the motions combine (``[design] combine``, the active objective):

``sum``        the paper's: the motions' terms T_m (:func:`objective_terms`) add up and
               their normalised sensitivities add up, every motion counting equally;
``product``    maximise the product of the terms (their geometric mean): d log T_m = dT_m /
               T_m, so each motion's normalised sensitivity is weighted by 1 / T_m (T_m
               floored at :data:`PRODUCT_FLOOR`, weights scaled to mean 1).  A motion whose
               load path is failing weighs more the more it fails, so the design does not
               give one motion up for the others: on the two-motion sleeve the sum lets
               flexion fall from rho ON 1.1 to 0.2-0.5 while the budget shrinks from 30% to
               20% (the sleeve turns about the arm), the product holds both
               (docs/notes/design.md, "Combine").  The scalar objective is then ``n`` times
               the geometric mean of the floored terms (equal to the sum where the terms are
               equal).
"""

from __future__ import annotations

import numpy as np

from kgarment.case.keys import Kind, base_motion, kind_of
from kgarment.case.states import states_needed
from kgarment.errors import unknown
from kgarment.problem.spec import COMBINE_NAMES, balance_weight
from kgarment.problem.spec import OBJECTIVE_NAMES as OBJECTIVES  # noqa: F401 (re-exported)

BALANCE_SHARE = 0.25  # the balance term pushes a clutch's share up to this (loaded: 0.10)
PRODUCT_FLOOR = 0.02  # combine = "product": a motion's term counts as at least this (weights <= 1 / floor)


def _locks(values: dict, motion: str) -> list:
    """The ``lock:`` states of ``motion`` among the keys of ``values``."""
    return [v for (m, s), v in values.items() if m == motion and kind_of(s) is Kind.LOCK]


def _solo_keys(values: dict, motion: str) -> list:
    return [(m, s) for (m, s) in values if m == motion and kind_of(s) is Kind.SOLO]


def balance_weights(energy: dict[tuple[str, str], float], motion: str) -> dict[tuple[str, str], float]:
    """{solo key: h'(G_c) = clip(1 - s_c / BALANCE_SHARE, 0, 1)} of ``motion`` (1 where the
    motion's ON - OFF gain is not positive)."""
    off = energy[(motion, "off")]
    g = energy[(motion, "on")] - off
    return {k: 1.0 if g <= 0 else float(np.clip(1.0 - (energy[k] - off) / (BALANCE_SHARE * g), 0.0, 1.0))
            for k in _solo_keys(energy, motion)}


def _balance_value(energy: dict[tuple[str, str], float], motion: str) -> float:
    """sum_c h(G_c): h(x) = x (x < 0), x - x^2 / (2 tau G) (0 <= x <= tau G), tau G / 2 beyond."""
    off = energy[(motion, "off")]
    g = energy[(motion, "on")] - off
    total = 0.0
    for k in _solo_keys(energy, motion):
        x = energy[k] - off
        if g <= 0 or x < 0:
            total += x
        else:
            cap = BALANCE_SHARE * g
            total += x - x * x / (2 * cap) if x <= cap else cap / 2
    return total


def _share(shares: dict[str, float], name: str) -> float:
    """The share of the design state ``name`` in ``shares``: its own, else its motion's (a
    wearer's ``MOTION@BODY`` takes MOTION's ``[design] weights``), else 1."""
    return shares.get(name, shares.get(base_motion(name), 1.0))


def motion_weights(combine: str, terms: dict[str, float],
                   shares: dict[str, float] | None = None) -> dict[str, float] | None:
    """{motion: weight of its sensitivities} for ``combine`` from the motions' objective
    ``terms`` (:func:`objective_terms`) and their ``shares`` ({motion: share}, a motion not
    in it: 1; :attr:`kgarment.design.DesignSetup.shares`): for "sum" the shares (None
    without any: all 1), for "product" share_m / max(T_m, PRODUCT_FLOOR) scaled to mean 1."""
    shares = shares or {}
    if combine == "sum":
        return {m: _share(shares, m) for m in terms} if shares else None
    if combine != "product":
        raise unknown("combine", combine, COMBINE_NAMES)
    w = {m: _share(shares, m) / max(t, PRODUCT_FLOOR) for m, t in terms.items()}
    mean = sum(w.values()) / max(len(w), 1)
    return {m: v / mean for m, v in w.items()}


def combined_objective(combine: str, terms: dict[str, float], shares: dict[str, float] | None = None) -> float:
    """The scalar objective from the motions' ``terms`` and ``shares`` (as in
    :func:`motion_weights`): sum_m share_m T_m, or for "product" sum_m share_m times the
    share-weighted geometric mean of the terms floored at PRODUCT_FLOOR (with every share
    1: the sum, and n times the geometric mean)."""
    shares = shares or {}
    s = np.array([_share(shares, m) for m in terms], dtype=np.float64)
    t = np.array(list(terms.values()), dtype=np.float64)
    if combine == "sum":
        return float(s @ t)
    if combine != "product":
        raise unknown("combine", combine, COMBINE_NAMES)
    if not len(t):
        return 0.0
    return float(s.sum() * np.exp(s @ np.log(np.maximum(t, PRODUCT_FLOOR)) / s.sum()))


def motion_sensitivities(kind: str, alpha: dict[tuple[str, str], np.ndarray], motions,
                         lockout: float = 0.0, balance=0.0,
                         energy: dict[tuple[str, str], float] | None = None,
                         weights: dict[str, float] | None = None) -> dict[str, np.ndarray]:
    """{motion: (m,) its normalised sensitivity} from per-(motion, state) sensitivities,
    each (m,); ``lockout`` weighs the ``lock:`` states, ``balance`` the ``solo:`` states
    (both the active objective; a number, or {motion: weight}; the balance needs the
    states' ``energy``, J); ``weights``
    (:func:`motion_weights`) scales each motion's (None: 1)."""
    out = {}
    for motion in motions:
        if kind == "active":
            on, off = alpha[(motion, "on")], alpha[(motion, "off")]
            gain = on - off
            for lock in _locks(alpha, motion) if lockout > 0 else ():
                gain = gain - lockout * (lock - off)
            b = balance_weight(balance, motion)
            if b > 0 and _solo_keys(alpha, motion):
                if energy is None:
                    raise ValueError("the balance term needs the states' energies")
                for key, w in balance_weights(energy, motion).items():
                    g = alpha[key] - off
                    gain = gain + b * w * g * (on.max() / max(np.abs(g).max(), 1e-300))
            out[motion] = gain / max(on.max(), 1e-300)
        else:
            state = states_needed(kind)[0]
            a = alpha[(motion, state)]
            out[motion] = a / max(a.max(), 1e-300)
        if weights is not None:
            out[motion] = out[motion] * weights[motion]
    return out


def combine_sensitivities(kind: str, alpha: dict[tuple[str, str], np.ndarray], motions,
                          lockout: float = 0.0, balance=0.0,
                          energy: dict[tuple[str, str], float] | None = None,
                          weights: dict[str, float] | None = None) -> np.ndarray:
    """(m,) combined sensitivity: the sum over motions of :func:`motion_sensitivities`."""
    total = 0.0
    for v in motion_sensitivities(kind, alpha, motions, lockout, balance, energy=energy, weights=weights).values():
        total = total + v
    return np.asarray(total)


def objective_terms(kind: str, energy: dict[tuple[str, str], float], reference: dict[tuple[str, str], float],
                    motions, lockout: float = 0.0, balance=0.0) -> dict[str, float]:
    """{motion: its term of the objective}: the (ON - OFF) energy (less ``lockout`` times
    each ``lock:`` state's energy beyond OFF, plus ``balance`` times the balance term
    sum_c h(G_c)), or the energy, divided by the fully reinforced design's energy in the
    motion's first state."""
    out = {}
    for motion in motions:
        if kind == "active":
            off = energy[(motion, "off")]
            gain = energy[(motion, "on")] - off
            for lock in _locks(energy, motion) if lockout > 0 else ():
                gain -= lockout * (lock - off)
            b = balance_weight(balance, motion)
            if b > 0:
                gain += b * _balance_value(energy, motion)
            out[motion] = gain / reference[(motion, "on")]
        else:
            s = states_needed(kind)[0]
            out[motion] = energy[(motion, s)] / reference[(motion, s)]
    return out


def objective_value(kind: str, energy: dict[tuple[str, str], float], reference: dict[tuple[str, str], float],
                    motions, lockout: float = 0.0, balance=0.0, combine: str = "sum") -> float:
    """Scalar objective for convergence tracking: :func:`objective_terms` combined
    (:func:`combined_objective`)."""
    return combined_objective(combine, objective_terms(kind, energy, reference, motions, lockout, balance))
