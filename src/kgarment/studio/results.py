"""What the page keeps of a simulated design, and the results table it shows.

A :class:`SimResult` is a :class:`kgarment.design.DesignEvaluation` (the one design
evaluator's answer) reduced to what the page draws and saves: the numbers per (motion,
state) and, for display, the equilibrium positions and energy densities.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from kgarment.case.states import StateKey
from kgarment.evaluate import DesignEvaluation
from kgarment.sim import SimModel


@dataclass(frozen=True)
class SimResult:
    """One design simulated on some motions.

    label : "A", "B (...)" or free text;  revision : the studio state's revision it was
    computed for;  design : (m,) bool;  rows : per (motion, state) the evaluator's numbers
    (motion, state, rho, energy J, energy_full J, converged);  garment_x : {(motion, state):
    (n, 3) equilibrium positions, m};  density : {(motion, state): (m,) energy density,
    J/m^2};  clutch_x : {(motion, state): [(nc, 3) positions of each clutch, m]};  loads :
    per (motion, clutch) the share of the ON - OFF energy, tension N and loaded flag
    (:mod:`kgarment.evaluate.loads`; empty without clutches).
    """

    label: str
    revision: int
    design: np.ndarray = field(repr=False)
    rows: tuple[dict, ...] = ()
    garment_x: dict[StateKey, np.ndarray] = field(default_factory=dict, repr=False)
    density: dict[StateKey, np.ndarray] = field(default_factory=dict, repr=False)
    clutch_x: dict[StateKey, list[np.ndarray]] = field(default_factory=dict, repr=False)
    loads: tuple[dict, ...] = ()

    @classmethod
    def of(cls, label: str, revision: int, evaluation: DesignEvaluation, model: SimModel) -> SimResult:
        """The page's copy of ``evaluation`` (its equilibria split by ``model``, the
        evaluator's simulation model)."""
        garment_x, density, clutch_x = {}, {}, {}
        for s in evaluation.states:
            gx, cx = model.split(s.result.x)
            garment_x[s.key] = np.asarray(gx).copy()
            density[s.key] = np.asarray(s.result.garment_density).copy()
            clutch_x[s.key] = [np.asarray(x).copy() for x in cx]
        loads = () if evaluation.loads is None else tuple(c.row() for c in evaluation.loads.clutches)
        return cls(label, revision, np.asarray(evaluation.design, bool).copy(),
                   tuple(s.row() for s in evaluation.states), garment_x, density, clutch_x, loads)

    def load(self, motion: str, clutch: str) -> dict | None:
        return next((r for r in self.loads if r["motion"] == motion and r["clutch"] == clutch), None)

    def row(self, motion: str, state: str) -> dict | None:
        return next((r for r in self.rows if r["motion"] == motion and r["state"] == state), None)

    def rho(self, motion: str, state: str) -> float | None:
        """rho of (motion, state), or None when not simulated."""
        r = self.row(motion, state)
        return None if r is None else r["rho"]

    def states(self) -> set[str]:
        """The clutch states simulated ("on", "off", "none")."""
        return {k[1] for k in self.garment_x}

    def to_json(self) -> dict:
        """What a session's results.json holds of it (no equilibria)."""
        return {"label": self.label, "revision": self.revision, "rows": [dict(r) for r in self.rows],
                "clutches": [dict(r) for r in self.loads]}


def _side_by_side(key_head: list[str], heads: list[str], keys, results, cell) -> list[str]:
    """Markdown table lines: one row per key (a tuple, one column per ``key_head``), one
    column per result with ``cell(result, key)`` (None: empty)."""
    lines = ["| " + " | ".join(key_head + heads) + " |", "|" + "---|" * len(key_head) + "---:|" * len(heads)]
    for k in keys:
        cells = ["" if (c := cell(e, k)) is None else c for e in results]
        lines.append("| " + " | ".join([*k, *cells]) + " |")
    return lines


def results_table(a: SimResult | None, b: SimResult | None, stale_a: bool = False) -> str:
    """Markdown table of rho per motion and state for designs A and B side by side."""
    evs = [e for e in (a, b) if e is not None]
    if not evs:
        return "No simulation yet: pick motions and press **Simulate design A**."
    keys = list(dict.fromkeys((r["motion"], r["state"]) for e in evs for r in e.rows))
    lines = _side_by_side(["motion", "state"], [f"rho {e.label}" for e in evs], keys, evs,
                          lambda e, k: None if (r := e.row(*k)) is None else
                          f"{r['rho']:.3f}" + ("" if r["converged"] else " (nc)"))
    pairs = list(dict.fromkeys((r["motion"], r["clutch"]) for e in evs for r in e.loads))
    if pairs:
        lines += [""] + _side_by_side(["motion", "clutch"], [f"share / needed {e.label} / N" for e in evs], pairs, evs,
                                      lambda e, k: None if (r := e.load(*k)) is None else
                                      f"{r['share']:.2f} / {r.get('needed', float('nan')):.2f} / "
                                      f"{r['tension_N']:.0f}" + (" *" if r["loaded"] else ""))
    notes = []
    if pairs:
        notes.append("share: of the ON - OFF energy with only that clutch ON; needed: the share lost with only "
                     "that clutch OFF; N: its tension with all ON; *: loaded (share or needed >= 0.1).")
    if stale_a and a is not None:
        notes.append("A was simulated before the latest edits.")
    if any(not r["converged"] for e in evs for r in e.rows):
        notes.append("(nc): the solver did not fully converge.")
    return "\n".join(lines) + ("\n\n" + " ".join(notes) if notes else "")
