"""What each clutch does for a design: its share of the ON - OFF energy and its tension.

Per motion and clutch k (docs/method/index.md, "Judging a design as a garment"):

* ``share``: garment energy with only clutch k ON minus all OFF, over all ON minus all
  OFF (ON: the motion's activation set where the problem gives one).  A clutch that is
  not at a junction of reinforcement has share ~0 ("if clutches are not at junctures,
  then their activation will have no effect on the user"); the only
  load path has share ~1.  Shares of several clutches need not add to 1 (paths in series
  or in parallel);
* ``needed``: the share of the ON - OFF energy lost when only clutch k is switched off
  (the motion's set without k).  Two clutches in series on one load path each have share
  ~0 (alone, the other OFF clutch is a soft link that breaks the path) and needed ~1
  (switching either off breaks it): the long-sleeve shirt's outer elbow clutch, share
  0.01 in every motion, carries 200-490 N and loses 26-56% of three motions when switched
  off (preview, measured).  NaN for a clutch the motion does not switch on;
* ``tension_N``: the force carried along the clutch at the target pose with all clutches
  ON (:func:`kgarment.sim.clutch_tensions`, what a load cell in its place measures);
* ``loaded``: share or needed >= :data:`kgarment.constants.LOADED_SHARE`: switching the
  clutch on alone, or off alone, changes what the wearer works against by that much;
* ``holding_N``, ``slipping``: with the slip model (``[clutches] model = "slip"``,
  :mod:`kgarment.sim.slip`) the force the clutch holds at its activation in the ON state
  (``g^2 F_h``) and whether it slides there (tension at
  :data:`kgarment.constants.SLIPPING` of it or more); None and False for locked clutches.

Where switching all clutches on changes the garment's energy by less than
:data:`kgarment.constants.MIN_GAIN` of its OFF energy, no clutch does anything in that
motion: shares are NaN ("n/a") and no clutch is loaded (ratios of two tiny differences
would be noise).

Garment energy is the total energy of an equilibrium (J).  It includes what the garment
already holds at rest (its attachment rings and the body's contact keep it stretched; a
taut clutch): the work the wearer does over the motion is the energy at the target less
that at rest (:func:`kgarment.evaluate.path.rest_frames`, ``evaluate --path``); differences
between activations of one design (ON - OFF, the shares) are what the clutches add.  The all-ON and all-OFF equilibria
come from the one design evaluator (:meth:`kgarment.design.Evaluator.solve_design`: its
two starts, the evaluation tolerance); a state with one clutch ON, or one OFF, starts
from the all-ON or the all-OFF equilibrium, whichever stores less energy under its
activation (:func:`nearer_start`; a state that is all OFF or one of the one-clutch-ON
states, as with one or two clutches, is not solved again) and is solved to
:data:`kgarment.constants.LOAD_TOL` (shares need per cent, not digits: at 1e-3 energies
are accurate to ~1e-6, ``kgarment.sim.options``); one that has not converged in the
solver's iterations goes on from where it stopped for as many again, and falls back to the
evaluator's starts when that does not converge either.
"""

from __future__ import annotations

import dataclasses
import logging
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import torch

from kgarment.case.continuation import activation_continuation
from kgarment.constants import LOAD_TOL, LOADED_SHARE, MIN_GAIN
from kgarment.io import save_figure
from kgarment.sim import StateResult, clutch_tensions, prepare_state
from kgarment.sim.slip import slides

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class ClutchLoad:
    """One clutch in one motion: share and needed (dimensionless, the module docstring),
    tension_N (N), loaded, and with the slip model the force it holds (holding_N, N) and
    whether it slides (slipping)."""

    motion: str
    clutch: str
    share: float
    tension_N: float
    loaded: bool
    holding_N: float | None = None
    slipping: bool = False
    needed: float = float("nan")

    @property
    def effect(self) -> float:
        """The larger of share and needed (NaN where neither is defined): what switching this
        clutch alone changes, as a share of the motion's ON - OFF energy."""
        return max((v for v in (self.share, self.needed) if math.isfinite(v)), default=float("nan"))

    def row(self) -> dict:
        row = {"motion": self.motion, "clutch": self.clutch, "share": self.share, "needed": self.needed,
               "tension_N": self.tension_N, "loaded": self.loaded}
        if self.holding_N is not None:  # the slip model's
            row.update(holding_N=self.holding_N, slipping=self.slipping)
        return row


@dataclass(frozen=True)
class MotionEnergy:
    """The whole garment's energy in one motion with all clutches ON and OFF (J)."""

    motion: str
    energy_on_J: float
    energy_off_J: float

    def row(self) -> dict:
        return {"motion": self.motion, "energy_on_J": self.energy_on_J, "energy_off_J": self.energy_off_J}


@dataclass(frozen=True)
class LoadReport:
    """Per-clutch loads and per-motion garment energies of one design."""

    clutches: tuple[ClutchLoad, ...]
    garment: tuple[MotionEnergy, ...]

    @property
    def clutch_names(self) -> list[str]:
        return list(dict.fromkeys(c.clutch for c in self.clutches))

    @property
    def motions(self) -> list[str]:
        return [g.motion for g in self.garment]

    def get(self, motion: str, clutch: str) -> ClutchLoad:
        return next(c for c in self.clutches if c.motion == motion and c.clutch == clutch)

    def unloaded(self) -> list[str]:
        """Clutches loaded in none of the motions."""
        return [n for n in self.clutch_names if not any(c.loaded for c in self.clutches if c.clutch == n)]

    def to_json(self) -> dict:
        return {"clutches": [c.row() for c in self.clutches], "garment": [g.row() for g in self.garment]}

    def table(self) -> str:
        """A plain-text table: per motion the garment energy ON/OFF, per clutch share,
        needed and tension (``*``: loaded, ``~``: slipping at its holding force)."""
        names = self.clutch_names
        head = f"{'motion':22s} {'E on (J)':>10s} {'E off (J)':>10s}  " + "  ".join(f"{n[:21]:>21s}" for n in names)
        lines = [head, f"{'':22s} {'':>10s} {'':>10s}  " + "  ".join(f"{'share needed / N':>21s}" for _ in names)]
        for g in self.garment:
            cells = []
            for n in names:
                c = self.get(g.motion, n)
                share, needed = (("  n/a" if not math.isfinite(v) else f"{v:5.2f}") for v in (c.share, c.needed))
                mark = ("*" if c.loaded else " ") + ("~" if c.slipping else "")
                cells.append(f"{share} {needed} / {c.tension_N:6.1f}{mark}".rjust(21))
            lines.append(f"{g.motion[:22]:22s} {g.energy_on_J:10.4g} {g.energy_off_J:10.4g}  " + "  ".join(cells))
        holds = {n: max((c.holding_N for c in self.clutches if c.clutch == n and c.holding_N is not None),
                        default=None) for n in names}
        if any(h is not None for h in holds.values()):
            lines.append("holding force (N): " + ", ".join(f"{n} {h:.0f}" for n, h in holds.items() if h is not None)
                         + "; ~: slips (tension at its holding force)")
        return "\n".join(lines)


def on_off_equilibria(evaluator, design: np.ndarray, motions, known: dict | None = None) -> tuple[list, dict]:
    """([((motion, "on" | "off"), SimState)], {key: StateResult}): per motion of ``motions``
    the ON state (its activation set, every clutch by default) and OFF (none), whatever the
    objective, with their equilibria of ``design`` (m,) from the evaluator's two starts;
    equilibria already in ``known`` are reused (and returned with the others)."""
    case = evaluator.case
    keyed = []
    for m in motions:
        keyed += evaluator.activation_states(case.on_activation(m), [m], "on") + \
            evaluator.activation_states(np.zeros(case.n_clutches), [m], "off")
    known = dict(known or {})
    todo = [(key, st) for key, st in keyed if key not in known]
    if todo:
        known.update(zip([key for key, _ in todo], evaluator.equilibria(design, todo)))
    return keyed, known


def activation_equilibria(evaluator, design: np.ndarray, keyed, known: dict) -> dict:
    """{(motion, label): StateResult} of ``design`` (m,) in ``keyed`` states (clutch
    activations other than all ON / all OFF, from :meth:`Evaluator.activation_states`).
    Each starts from its motion's all-ON or all-OFF equilibrium (``known[(motion, "on" |
    "off")]``), whichever has the lower energy under the state's activation
    (:func:`nearer_start`) -- on a garment with a coarser level (:attr:`Evaluator.coarser`)
    from its own equilibrium there instead (:func:`coarse_starts`) -- and is solved to
    :data:`LOAD_TOL`; a state that does not
    converge in the solver's iterations goes on from where it stopped for as many again, one
    still sliding then has its clutches switched on in steps from the motion's OFF
    equilibrium (:func:`kgarment.case.continuation.activation_continuation`, at ``LOAD_TOL``),
    and one that does not converge even so goes through the evaluator's two starts.  These solves
    have no rescue (a second solve with larger shifts, ``SolverOptions.rescue_shifts``) and
    do not warn about the states they leave unconverged: the two starts follow anyway (and
    warn where they fail too; measured: docs/notes/code.md, "kgarment.evaluate.loads")."""
    case = evaluator.case
    opts = dataclasses.replace(case.solver, tol=max(case.solver.tol, LOAD_TOL), rescue_shifts=0, on_fail="info")
    starts = [nearer_start(case, design, st, [known[(key[0], "on")].x, known[(key[0], "off")].x])
              if x is None else x for (key, st), x in zip(keyed, coarse_starts(evaluator, design, keyed))]
    solved = case.solve(design, [st for _, st in keyed], warm_start=starts, options=opts)
    out = {key: r for (key, _), r in zip(keyed, solved) if r.converged}
    slow = [i for i, (key, _) in enumerate(keyed) if key not in out]
    if slow:  # one more round from where they stopped (slow sliding, not a wrong start)
        again = case.go_on(design, [keyed[i][1] for i in slow], [solved[i] for i in slow], opts)
        out.update({keyed[i][0]: r for i, r in zip(slow, again) if r.converged})
    retry = [(key, st) for key, st in keyed if key not in out]
    if retry:  # still sliding: the clutches switched on in steps from the motion's OFF equilibrium
        stepped = activation_continuation(case, design, [st for _, st in retry],
                                          [known[(key[0], "off")] for key, _ in retry], options=opts)
        out.update({key: r for (key, _), r in zip(retry, stepped) if r.converged})
    retry = [(key, st) for key, st in keyed if key not in out]
    if retry:
        log.info("%d state(s) go on from the evaluator's two starts: %s", len(retry),
                 ", ".join(st.name for _, st in retry))
        out.update(zip([key for key, _ in retry], evaluator.equilibria(design, retry)))
    return out


def coarse_starts(evaluator, design: np.ndarray, keyed) -> list[np.ndarray | None]:
    """Per ``keyed`` state (activations of :func:`activation_equilibria`) its equilibrium one
    subdivision level down, prolongated (N, 3); None where there is no coarser level (its
    evaluator, :attr:`kgarment.design.Evaluator.coarser`).  There ``design`` (m,) is
    restricted and the state solved as here -- from that level's all-ON or all-OFF
    equilibrium, itself from the evaluator's two starts -- so the garment does its slide to
    the new activation where a Newton step moves it furthest (nested iteration,
    :mod:`kgarment.case.levels`)."""
    out: list[np.ndarray | None] = [None] * len(keyed)
    low = evaluator.coarser
    if low is None:
        return out
    idx, d, down = evaluator.down(design, keyed)
    if idx:
        _, known = on_off_equilibria(low, d, list(dict.fromkeys(key[0] for key, _ in down)))
        solved = activation_equilibria(low, d, down, known)
        for i, (key, _) in zip(idx, down):
            out[i] = evaluator.up(solved[key].x)
    return out


def nearer_start(case, design: np.ndarray, state, starts: list[np.ndarray]) -> np.ndarray:
    """Of ``starts`` (each (N, 3) positions, m), the one where ``state``'s energy is lowest
    for ``design`` (m,): a clutch that carries nothing switched on alone leaves the garment
    near its all-OFF equilibrium, one switched off alone near its all-ON one."""
    prob = prepare_state(case.model_of(state.motion.name), design, state, case.solver)
    energies = [prob.evaluate(torch.as_tensor(np.asarray(x, dtype=np.float64), device=prob.device), order=0,
                              check=False)[0] for x in starts]
    return starts[int(np.argmin(energies))]


def clutch_loads(evaluator, design: np.ndarray, motions=None, known: dict | None = None) -> LoadReport:
    """The :class:`LoadReport` of ``design`` (m,) on ``motions`` (default: all).

    evaluator : kgarment.design.Evaluator (with clutches);  known : {(motion, "on" | "off"):
    StateResult} equilibria already solved (by :meth:`Evaluator.evaluate`), reused.
    """
    case = evaluator.case
    names = [c.name for c in case.model.clutches]
    motions = evaluator.motion_names(motions)
    ends, known = on_off_equilibria(evaluator, design, motions, known)
    alone, without, todo = {}, {}, []
    for m in motions:
        g_on = case.on_activation(m)
        same = {tuple(np.zeros(len(names))): (m, "off")}  # activation -> the state solving it
        for k, name in enumerate(names):  # a clutch alone at its value in the motion's set (1 if not in it)
            alone[(m, k)] = _state_for(evaluator, m, _one_hot(len(names), k, g_on[k] if g_on[k] > 0 else 1.0),
                                       f"only {name}", same, todo)
        for k, name in enumerate(names):  # the motion's set with this clutch off
            if g_on[k] > 0:
                without[(m, k)] = _state_for(evaluator, m, np.where(np.arange(len(names)) == k, 0.0, g_on),
                                             f"without {name}", same, todo)
    known.update(activation_equilibria(evaluator, design, todo, known))
    states = dict(ends)
    loads, garment = [], []
    for m in motions:
        on: StateResult = known[(m, "on")]
        e_on, e_off = on.total_energy, known[(m, "off")].total_energy
        garment.append(MotionEnergy(m, e_on, e_off))
        tension = clutch_tensions(case.model_of(m), design, states[(m, "on")], on.x, case.solver)
        gain = e_on - e_off
        hold = case.model_of(m).holding(case.on_activation(m))
        for k, name in enumerate(names):
            share = needed = float("nan")
            if gain > MIN_GAIN * abs(e_off):
                share = (known[alone[(m, k)]].total_energy - e_off) / gain
                if (m, k) in without:
                    needed = (e_on - known[without[(m, k)]].total_energy) / gain
            h = float(hold[k]) if math.isfinite(hold[k]) else None
            load = ClutchLoad(m, name, float(share), float(tension[k]), False, h, slipping=slides(tension[k], hold[k]),
                              needed=float(needed))
            loads.append(dataclasses.replace(load, loaded=bool(load.effect >= LOADED_SHARE)))
    return LoadReport(tuple(loads), tuple(garment))


def _one_hot(n: int, k: int, value: float) -> np.ndarray:
    g = np.zeros(n)
    g[k] = value
    return g


def _state_for(evaluator, motion: str, activation: np.ndarray, label: str, same: dict, todo: list):
    """The key of the state of ``motion`` under ``activation`` (K,): one already asked for
    with the same activation (``same``: activation tuple -> key), else a new one appended
    to ``todo``."""
    g = tuple(float(a) for a in activation)
    if g not in same:
        keyed = evaluator.activation_states(activation, [motion], label)
        todo += keyed
        same[g] = keyed[0][0]
    return same[g]


def load_chart(report: LoadReport, path, title: str = "") -> Path:
    """A bar chart per motion: per clutch its share of the ON - OFF energy (left bar) and
    the share lost without it (needed, right bar, hatched), its tension in newtons (labels),
    the loaded threshold drawn (a clutch is loaded where either bar reaches it); a PNG at
    ``path``."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    def finite(v: float) -> float:
        return v if math.isfinite(v) else 0.0

    names, motions = report.clutch_names, report.motions
    fig, axes = plt.subplots(1, len(motions), figsize=(max(3.2 * len(motions), 4.5), 3.4), dpi=100, sharey=True,
                             squeeze=False)
    x = np.arange(len(names))
    for ax, m in zip(axes[0], motions):
        loads = [report.get(m, n) for n in names]
        colors = ["#2a9d8f" if c.loaded else "#bbbbbb" for c in loads]
        alone = ax.bar(x - 0.2, [finite(c.share) for c in loads], 0.4, color=colors, label="alone ON (share)")
        ax.bar(x + 0.2, [finite(c.needed) for c in loads], 0.4, color=colors, alpha=0.55, hatch="//",
               edgecolor="white", label="lost when OFF (needed)")
        for b, c in zip(alone, loads):
            top = max(finite(c.share), finite(c.needed), 0.0)
            ax.annotate(f"{c.tension_N:.0f} N", (b.get_x() + 0.4, top), ha="center", va="bottom", fontsize=7)
        ax.axhline(LOADED_SHARE, color="#e76f51", lw=0.8, ls="--")
        ax.set_xticks(x, names, rotation=30, ha="right", fontsize=7)
        ax.set_title(m, fontsize=9)
        ax.grid(axis="y", alpha=0.3)
    axes[0][0].set_ylabel("share of the ON - OFF energy")
    values = [v for c in report.clutches for v in (c.share, c.needed) if math.isfinite(v)]
    axes[0][0].set_ylim(min(0.0, *values) - 0.05, max(1.05, *values) + 0.3)  # room for the legend above the bars
    axes[0][-1].legend(fontsize=6, loc="upper right", ncol=2)
    return save_figure(fig, path, title)
