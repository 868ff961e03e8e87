"""Which motions the clutches can control at all: a screen at the start of a design and
for ``kgarment clutches suggest``.

A clutch is felt in a motion only if the motion stretches the garment across it.  The
screen asks the fully reinforced garment, where every clutch end is held as firmly as the
cloth can hold it: by how much does switching the clutches ON change its energy in the
motion?  Below ``UNCONTROLLABLE`` (relative) a motion is reported with what to change.  It
is a screen, not a bound: a sparse design gains far more than the full garment does (the
shirt's full garment gains 1-3% with the clutches ON, its designs 30-fold), but where even
the full garment does not notice the clutches the motion does not stretch the garment
across them.  Measured at subdivision 0: the shirt's arms forward, arms raise and bend
forward 1.2%, 1.3%, 2.7% with the ``paper`` material preset and 1.05%, 0.97%, 2.2% with
``reference``; the sleeve's flexion and extension 14% and 5.7% (``reference``); a
120-degree overhead reach with the shirt's back clutches 0.04-0.07% (its short sleeve
slides off the rising arm on the frictionless body).  With the garment starting on the
contact surface (``SIM_MODEL`` 2, 2026-11-26; ``paper``): the shirt's motions 2.4%, 0.86%,
3.8%, the reach 0.31% (the ON clutches now store a little of the garment's stretch over the
surface at every pose), hence the threshold 0.5%.  The final evaluation then says,
per design, which clutches carry load in which motion.
"""

from __future__ import annotations

import dataclasses
import logging
from dataclasses import dataclass

import numpy as np

from kgarment import constants as C
from kgarment.case.setup import Case
from kgarment.constants import UNCONTROLLABLE
from kgarment.sim import SimState

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class Control:
    """One motion (and, for one clutch alone, its name): the fully reinforced garment's
    energy (J, the whole system's at equilibrium) with the clutch(es) ON and all OFF."""

    motion: str
    on_J: float
    off_J: float
    clutch: str = "all"

    @property
    def gain(self) -> float:
        """(ON - OFF) / OFF of the fully reinforced garment."""
        return (self.on_J - self.off_J) / max(abs(self.off_J), 1e-12)

    @property
    def controllable(self) -> bool:
        return self.gain >= UNCONTROLLABLE

    def advice(self) -> str:
        who = "the clutches" if self.clutch == "all" else f"its activation set ({self.clutch.replace('+', ', ')})"
        return (f"motion {self.motion}: {who} can hardly be felt in it: switching them ON changes the fully "
                f"reinforced garment's energy by {100 * self.gain:.2g}% (the paper's shirt motions: 1-3%; below "
                f"{100 * UNCONTROLLABLE:g}% is reported). Place a clutch where this motion stretches the garment "
                "(kgarment clutches suggest), attach the garment where the motion pulls it (a cuff or a band), "
                "or leave the motion out")

    def to_json(self) -> dict:
        return {"motion": self.motion, "clutch": self.clutch, "full_on_J": self.on_J, "full_off_J": self.off_J,
                "gain": self.gain, "controllable": self.controllable}


def control_check(case: Case, warm: dict[str, np.ndarray] | None = None) -> list[Control]:
    """Per motion of ``case`` (an active objective with clutches): the fully reinforced
    garment ON and OFF (warm started from ``warm`` {state name: x}, iteration 0's
    equilibria, solved on to the evaluation tolerance; OFF also from ON's equilibrium, the
    lower kept, so the gain is never negative).  Measured (2026-11-26, subdivision 0):
    the shirt's motions 1.7 / 1.4 / 4.2%, the overhead reach of ``tests/test_design_control``
    0.34%; at the design tolerance with the lagged contact set the reach came out at -4%
    (its OFF solve ending in a higher equilibrium than ON's)."""
    keyed = [(k, s) for k, s in case.states() if k[1] in ("on", "off")]  # ON: each motion's set
    if not case.n_clutches or {s for (_, s), _ in keyed} != {"on", "off"}:
        return []
    warm = warm or {}
    states = [s for _, s in keyed]
    ones = np.ones(len(case.areas))
    # at the evaluation's tolerance (a gain of a fraction of a percent is judged)
    opts = dataclasses.replace(case.solver, tol=min(case.solver.tol, C.EVALUATION_TOL))
    full = case.solve(ones, states, warm_start=[warm.get(s.name) for s in states], options=opts)
    energy = {k: r.total_energy for (k, _), r in zip(keyed, full)}
    # OFF also from the ON equilibrium, the lower kept: switching clutches off lowers the
    # energy of every configuration, so OFF solved from ON's ends at or below ON.  Of a motion
    # with several equilibria (a sleeve sliding off the arm) the OFF solve from iteration 0's
    # OFF state can end above ON's, and the gain would come out negative
    on = {k[0]: r for (k, _), r in zip(keyed, full) if k[1] == "on" and r.converged}
    again = [(k, s) for k, s in keyed if k[1] == "off" and k[0] in on]
    if again:
        second = case.solve(ones, [s for _, s in again], warm_start=[on[k[0]].x for k, _ in again], options=opts)
        for (k, _), r in zip(again, second):
            if r.converged and r.total_energy < energy[k]:
                energy[k] = r.total_energy
    names = [c.name for c in case.model.clutches]

    def which(m: str) -> str:
        g = case.on_activation(m)
        return "all" if np.all(g == 1.0) else "+".join(n for n, a in zip(names, g) if a > 0)

    return [Control(m, energy[(m, "on")], energy[(m, "off")], which(m)) for m in case.motions]


def clutch_control(case: Case, names: list[str]) -> list[Control]:
    """Per motion of ``case`` and clutch (``names``, in the model's order): the screen with
    that clutch alone switched ON (one solve per motion and clutch, and one all OFF)."""
    k = case.n_clutches
    out = []
    for motion, m in case.motions.items():
        states = [SimState.create(m, np.zeros(k), name=f"{motion}[off]")]
        states += [SimState.create(m, np.eye(k)[j], name=f"{motion}[only {names[j]}]") for j in range(k)]
        full = case.solve(np.ones(len(case.areas)), states)
        out += [Control(motion, full[j + 1].total_energy, full[0].total_energy, names[j]) for j in range(k)]
    return out


def control_table(rows: list[Control]) -> list[str]:
    """Lines: per motion and clutch the gain in % (* at least ``UNCONTROLLABLE``), then per
    motion the clutches that can be felt in it or what to change."""
    clutches = list(dict.fromkeys(r.clutch for r in rows))
    motions = list(dict.fromkeys(r.motion for r in rows))
    by = {(r.motion, r.clutch): r for r in rows}
    lines = [f"{'motion':22s} " + " ".join(f"{c[:14]:>15s}" for c in clutches)]
    for m in motions:
        lines.append(f"{m[:22]:22s} " + " ".join(
            f"{100 * by[(m, c)].gain:13.3g}%{'*' if by[(m, c)].controllable else ' '}" for c in clutches))
    for m in motions:
        ok = [c for c in clutches if by[(m, c)].controllable]
        lines.append(f"{m}: can be felt through {', '.join(ok)}" if ok else
                     f"{m}: NO suggested clutch can be felt in it (none changes the fully reinforced garment's energy "
                     f"by {100 * UNCONTROLLABLE:g}%): the motion does not stretch the garment across any of them; add "
                     "clutches (--count), attach the garment where the motion pulls it, or leave the motion out")
    return lines
