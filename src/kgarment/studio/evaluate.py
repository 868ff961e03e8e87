"""Simulate a design from the studio: equilibria and rho per motion and state.

The same computation as :func:`kgarment.cli_design.evaluate_design` (solve the fully
reinforced garment and the design, from the skin-tight start and where that fails from
the full garment's equilibrium: ``design.driver.design_equilibria``; compare stored energies
per method.md section 7), but on the studio's own garment (its painted attachments) and
clutches, one state at a time so the page can show progress and a stop request is
honoured between states; it also keeps the equilibria for display.
"""

from __future__ import annotations

import logging
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from kgarment.design.beso import X_MIN
from kgarment.errors import KgarmentError

log = logging.getLogger(__name__)


class Cancelled(Exception):
    """A background job was asked to stop."""


@dataclass
class Evaluation:
    """Results of one design on some motions.

    label : "A" / "B" / free text; design : (m,) bool; revision : the studio state's
    revision it was computed for; rows : one dict per (motion, state) with rho, energy
    (J), energy_full (J), converged; garment_x : {(motion, state): (n, 3) m};
    density : {(motion, state): (m,) J/m^2}; clutch_x : {(motion, state): [(nc, 3)]}.
    """

    label: str
    design: np.ndarray
    revision: int
    rows: list = field(default_factory=list)
    garment_x: dict = field(default_factory=dict)
    density: dict = field(default_factory=dict)
    clutch_x: dict = field(default_factory=dict)

    def rho(self, motion: str, state: str) -> float | None:
        for r in self.rows:
            if r["motion"] == motion and r["state"] == state:
                return r["rho"]
        return None

    def to_json(self) -> dict:
        return {"label": self.label, "revision": self.revision, "rows": self.rows}


def evaluate(problem, body, garment, strips, design: np.ndarray, motions=None, *, label: str = "A",
             revision: int = 0, device: str = "cpu", full_cache: dict | None = None,
             report: Callable[[str], None] | None = None,
             cancelled: Callable[[], bool] | None = None) -> Evaluation:
    """Simulate ``design`` (m,) bool (True = reinforced) on ``motions`` (default: the
    problem's) in the states of the problem's objective (ON and OFF for "active").

    full_cache : a dict kept by the caller: the fully reinforced solves are reused from it
    when the garment, clutches and solver settings are the same. report(text) is called
    before each solve; cancelled() is checked between solves (raises Cancelled).
    """
    from kgarment.design.driver import build_setup, design_equilibria
    from kgarment.design.metrics import Stored, relative_energy_density
    from kgarment.sim import solve_states

    d = np.asarray(design, bool)
    if d.shape != (garment.n_faces,):
        raise KgarmentError(f"the design has {d.size} faces, the garment {garment.n_faces}")
    motions = list(motions or problem.motions)
    unknown = [m for m in motions if m not in garment.motion_names]
    if unknown:
        raise KgarmentError(f"motion {unknown[0]!r} is not posed on this body; posed: {', '.join(garment.motion_names)}")
    if not motions:
        raise KgarmentError("pick at least one motion to simulate")
    values = np.where(d, 1.0, X_MIN)
    setup = build_setup(problem, body, posed_only(garment, motions), strips, device, evaluation=True)
    keyed = setup.states()
    clutched = setup.objective != "passive"
    cache_key = (_strips_key(strips), garment.attached.tobytes(), repr(problem.solver), problem.design.objective, device)
    ev = Evaluation(label, d.copy(), revision)
    total = 2 * len(keyed)
    for k, (key, s) in enumerate(keyed):
        if cancelled is not None and cancelled():
            raise Cancelled()
        full = None if full_cache is None else full_cache.get((cache_key, key))
        if full is None:
            if report:
                report(f"{label}: fully reinforced garment, {key[0]} {key[1]} ({2 * k + 1}/{total})")
            full = solve_states(setup.model, np.ones(garment.n_faces), [s], options=setup.solver)[0]
            if full_cache is not None:
                full_cache[(cache_key, key)] = full
        if cancelled is not None and cancelled():
            raise Cancelled()
        if report:
            report(f"{label}: design, {key[0]} {key[1]} ({2 * k + 2}/{total})")
        mine = design_equilibria(setup, values, lambda f=full: [f], states=[s])[0]
        sf, sd = Stored.of(full, clutched), Stored.of(mine, clutched)
        ev.rows.append({"motion": key[0], "state": key[1],
                        "rho": relative_energy_density(values, setup.areas, sd, sf, setup.clutch_area()),
                        "energy": float(sd.face_energy[d].sum() + sd.clutch_energy),
                        "energy_full": float(sf.face_energy.sum() + sf.clutch_energy),
                        "converged": bool(full.converged and mine.converged)})
        gx, cx = setup.model.split(mine.x)
        ev.garment_x[key] = np.asarray(gx).copy()
        ev.density[key] = np.asarray(mine.garment_density).copy()
        ev.clutch_x[key] = [np.asarray(x).copy() for x in cx]
    return ev


def posed_only(garment, motions):
    """The garment with only ``motions`` posed (the body may be posed in more motions than
    a problem uses; the design setup simulates every posed motion of the garment)."""
    import dataclasses

    idx = [garment.motion_names.index(m) for m in motions]
    return dataclasses.replace(garment, initial=garment.initial[idx], motion_names=tuple(motions))


def _strips_key(strips) -> tuple:
    return tuple((s.name, s.vertices.tobytes(), s.prestrain) for s in strips)


def results_table(a: Evaluation | None, b: Evaluation | None, stale_a: bool = False) -> str:
    """Markdown table of rho per motion and state for designs A and B side by side."""
    evs = [e for e in (a, b) if e is not None]
    if not evs:
        return "No simulation yet: pick motions and press **Simulate design A**."
    keys = list(dict.fromkeys((r["motion"], r["state"]) for e in evs for r in e.rows))
    head = "| motion | state | " + " | ".join(f"rho {e.label}" for e in evs) + " |"
    lines = [head, "|---|---|" + "---:|" * len(evs)]
    for m, s in keys:
        cells = []
        for e in evs:
            row = next((r for r in e.rows if r["motion"] == m and r["state"] == s), None)
            cells.append("" if row is None else f"{row['rho']:.3f}" + ("" if row["converged"] else " (nc)"))
        lines.append(f"| {m} | {s} | " + " | ".join(cells) + " |")
    notes = []
    if stale_a and a is not None:
        notes.append("A was simulated before the latest edits.")
    if any(not r["converged"] for e in evs for r in e.rows):
        notes.append("(nc): the solver did not fully converge.")
    return "\n".join(lines) + ("\n\n" + " ".join(notes) if notes else "")
