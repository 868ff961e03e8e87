"""Which motions the clutches can control at all, checked once at the start of a design.

A clutch is felt in a motion only if switching it ON changes the energy the wearer works
against there.  The check compares two numbers every problem has before any design exists:
how much switching all clutches ON changes the fully reinforced garment's energy, and the
plain garment's energy with the clutches OFF (the wearer's baseline).  A motion whose ratio
is below ``UNCONTROLLABLE`` is reported with what to change.  It is a screen, not a bound:
a sparse design can gain far more than the full garment does (on the paper's shirt the full
garment gains 0.46-1.0 J, the designs 15 J), but where even the full garment barely notices
the clutches the motion does not stretch the garment across them.  Measured: the shirt's
arms forward, arms raise and bend forward 15, 16 and 34; a 120-degree overhead reach with
the same clutches 0.46-0.68 (its sleeve slides off the rising arm on the frictionless body).
The full garment's own ON/OFF contrast is no test: 1.4% for arms forward, a motion the
designs control 30-fold.  The final evaluation then says, per design, which clutches carry
load in which motion.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass

import numpy as np

from kgarment.constants import UNCONTROLLABLE, X_MIN
from kgarment.design.setup import DesignSetup
from kgarment.sim import solve_states

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class Control:
    """One motion: stored energy (J) of the fully reinforced garment with the clutches ON
    and OFF, and of the plain garment with them OFF."""

    motion: str
    full_on_J: float
    full_off_J: float
    plain_off_J: float

    @property
    def ratio(self) -> float:
        """(full ON - full OFF) / plain OFF: how much of the wearer's baseline the clutches
        can add at most."""
        return (self.full_on_J - self.full_off_J) / max(self.plain_off_J, 1e-12)

    @property
    def controllable(self) -> bool:
        return self.ratio >= UNCONTROLLABLE

    def advice(self) -> str:
        return (f"motion {self.motion}: the clutches can hardly be felt in it: switching them ON changes the fully "
                f"reinforced garment's energy by {self.full_on_J - self.full_off_J:.3g} J, {self.ratio:.2g}x the "
                f"plain garment's {self.plain_off_J:.3g} J (shirt motions: 15-34x; below {UNCONTROLLABLE:g}x is "
                "reported). Place a clutch where this motion stretches the garment (kgarment clutches suggest), "
                "attach the garment where the motion pulls it (a cuff or a band), or leave the motion out")

    def to_json(self) -> dict:
        return {"motion": self.motion, "full_on_J": self.full_on_J, "full_off_J": self.full_off_J,
                "plain_off_J": self.plain_off_J, "ratio": self.ratio, "controllable": self.controllable}


def control_check(setup: DesignSetup, warm: dict[str, np.ndarray] | None = None) -> list[Control]:
    """Per motion of ``setup`` (an active objective with clutches): the :class:`Control`
    from the fully reinforced garment ON and OFF (warm started from ``warm`` {state name:
    x}, iteration 0's equilibria) and the plain garment OFF.  Energies are the whole
    system's at equilibrium (cloth, clutches, contact, attachments): what the wearer works
    against."""
    keyed = setup.states()
    if not setup.n_clutches or {s for (_, s), _ in keyed} != {"on", "off"}:
        return []
    warm = warm or {}
    states = [s for _, s in keyed]
    full = solve_states(setup.model, np.ones(len(setup.areas)), states, warm_start=[warm.get(s.name) for s in states],
                        options=setup.solver)
    offs = [(k, s) for k, s in keyed if k[1] == "off"]
    plain = solve_states(setup.model, np.full(len(setup.areas), X_MIN), [s for _, s in offs], options=setup.solver)
    energy = {k: r.total_energy for (k, _), r in zip(keyed, full)}
    return [Control(m, energy[(m, "on")], energy[(m, "off")], r.total_energy) for ((m, _), _), r in zip(offs, plain)]


@dataclass(frozen=True)
class ClutchControl:
    """One clutch in one motion: the fully reinforced garment's energy (J) with only this
    clutch ON, against all OFF, over the plain garment's energy with all OFF."""

    motion: str
    clutch: str
    only_on_J: float
    full_off_J: float
    plain_off_J: float

    @property
    def ratio(self) -> float:
        return (self.only_on_J - self.full_off_J) / max(self.plain_off_J, 1e-12)

    @property
    def controls(self) -> bool:
        return self.ratio >= UNCONTROLLABLE


def clutch_control(setup: DesignSetup, names: list[str]) -> list[ClutchControl]:
    """Per motion of ``setup`` and clutch (``names``, in the model's order): the
    :class:`Control` screen with that clutch alone switched ON (one solve per motion and
    clutch, plus the garment fully reinforced and plain with all OFF)."""
    from kgarment.sim import SimState

    k = setup.n_clutches
    out = []
    for motion, m in setup.motions.items():
        states = [SimState.create(m, np.zeros(k), name=f"{motion}[off]")]
        states += [SimState.create(m, np.eye(k)[j], name=f"{motion}[only {names[j]}]") for j in range(k)]
        full = solve_states(setup.model, np.ones(len(setup.areas)), states, options=setup.solver)
        (plain,) = solve_states(setup.model, np.full(len(setup.areas), X_MIN), states[:1], options=setup.solver)
        out += [ClutchControl(motion, names[j], full[j + 1].total_energy, full[0].total_energy, plain.total_energy)
                for j in range(k)]
    return out


def control_table(rows: list[ClutchControl]) -> list[str]:
    """Lines: per motion and clutch the ratio (* controls it), then per motion the clutches
    that control it or what to change."""
    clutches = list(dict.fromkeys(r.clutch for r in rows))
    motions = list(dict.fromkeys(r.motion for r in rows))
    by = {(r.motion, r.clutch): r for r in rows}
    lines = [f"{'motion':22s} " + " ".join(f"{c[:14]:>15s}" for c in clutches)]
    for m in motions:
        lines.append(f"{m[:22]:22s} " + " ".join(
            f"{by[(m, c)].ratio:14.3g}{'*' if by[(m, c)].controls else ' '}" for c in clutches))
    for m in motions:
        ok = [c for c in clutches if by[(m, c)].controls]
        lines.append(f"{m}: controlled by {', '.join(ok)}" if ok else
                     f"{m}: NO suggested clutch can be felt in it (each changes the fully reinforced garment's "
                     f"energy by less than {UNCONTROLLABLE:g}x the plain garment's): the motion does not stretch the "
                     "garment across any of them; add clutches (--count), attach the garment where the motion "
                     "pulls it, or leave the motion out")
    return lines
