"""The control table: which clutches to switch on for which motion (issue #22, item 3).

A garment designed for several motions resists all of them whenever all its clutches are
on.  Its controller can do better: switch on, for the motion the wearer is making, the
set of clutches that resists it, and leave off the ones that would lock another motion.
:func:`make_plan` evaluates a design under clutch sets for every motion:

* every non-empty subset of the clutches up to :data:`PLAN_EXHAUSTIVE` clutches (2^K - 1
  sets), and beyond that a greedy search per motion (add the clutch that raises the
  resistance most while it still does, every prefix kept), the sets found then evaluated
  in every motion;
* per (motion, set): the garment's energy with that set ON (J, the total energy of the
  equilibrium, what it holds at rest included), the *resistance* (that energy minus all
  OFF: what the set adds to what the wearer works against), its *fraction* of the all-ON resistance, and the tension of every clutch of the
  set (N, :func:`kgarment.sim.clutch_tensions`).

Per motion the plan names the set of highest resistance and the *smallest* set that keeps
at least :data:`PLAN_KEEP` of the all-ON resistance (fewer clutches to power and wire),
and, for that set, what it does to the other motions: a set *locks* another motion where
it resists it with at least :data:`PLAN_LOCK` of that motion's all-ON resistance (the
paper's two-motion sleeve switches the opposing clutch off "to prevent full arm-locking").

Equilibria come from the one design evaluator (ON and all OFF from its two starts,
:func:`kgarment.evaluate.loads.on_off_equilibria`, as the clutch loads; a set starts from the
nearer of the ON and OFF equilibria, :func:`kgarment.evaluate.loads.activation_equilibria`),
so the ON and all-OFF energies are those of ``kgarment evaluate``.  A motion's own
activation set is its ON state; another motion's set is solved like the evaluator's
``lock:`` states (two starts, the lower kept), so that one state has one answer.  With
``known`` (the ends of the motion from rest, ``kgarment plan --path K`` and the
reproduction) they compete with the two starts by the evaluator's rule
(:func:`kgarment.case.starts.with_known`), as in ``kgarment evaluate --path K``; every
set then starts from the nearer of the equilibria kept.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass, field

import numpy as np

from kgarment.constants import MIN_GAIN, PLAN_EXHAUSTIVE, PLAN_KEEP, PLAN_LOCK
from kgarment.evaluate.loads import activation_equilibria, on_off_equilibria
from kgarment.sim import clutch_tensions


@dataclass(frozen=True)
class SetResult:
    """One clutch set in one motion.  clutches : the names switched on (the rest off);
    energy_J : garment energy (J); resistance_J : energy minus all OFF (J); fraction :
    resistance over the all-ON resistance (NaN where all ON changes less than MIN_GAIN of
    the OFF energy); tension_N : {clutch: N} for the clutches of the set; converged."""

    motion: str
    clutches: tuple[str, ...]
    energy_J: float
    resistance_J: float
    fraction: float
    tension_N: dict
    converged: bool = True

    def row(self) -> dict:
        return {"motion": self.motion, "clutches": list(self.clutches), "energy_J": self.energy_J,
                "resistance_J": self.resistance_J, "fraction": None if math.isnan(self.fraction) else self.fraction,
                "tension_N": self.tension_N, "converged": self.converged}


@dataclass(frozen=True)
class Plan:
    """Every evaluated (motion, set), the motions and clutch names, the all-OFF energy per
    motion (J), whether every subset was tried (``exhaustive``), and the activation sets the
    design was made for (``designed``, [motions.activation]; empty: all clutches)."""

    motions: tuple[str, ...]
    clutch_names: tuple[str, ...]
    results: tuple[SetResult, ...]
    energy_off_J: dict
    exhaustive: bool
    designed: dict = field(default_factory=dict)  # {motion: clutch names} of the problem's activation sets
    from_path: tuple = ()  # "motion:on" / "motion:off" whose equilibrium is the motion from rest's end

    def sets(self, motion: str) -> list[SetResult]:
        return [r for r in self.results if r.motion == motion]

    def find(self, motion: str, clutches) -> SetResult | None:
        """The result of the set ``clutches`` (names, any order) in ``motion``; None if not evaluated."""
        key = tuple(c for c in self.clutch_names if c in set(clutches))
        return next((r for r in self.results if r.motion == motion and r.clutches == key), None)

    def get(self, motion: str, clutches) -> SetResult:
        """:meth:`find`, for a set that was evaluated (KeyError otherwise)."""
        r = self.find(motion, clutches)
        if r is None:
            raise KeyError((motion, tuple(clutches)))
        return r

    def all_on(self, motion: str) -> SetResult:
        return self.get(motion, self.clutch_names)

    def controllable(self, motion: str) -> bool:
        """Whether switching clutches on changes this motion at all (above MIN_GAIN)."""
        return self.all_on(motion).resistance_J > MIN_GAIN * abs(self.energy_off_J[motion])

    def best(self, motion: str) -> SetResult:
        """The set of highest resistance (fewer clutches first among equals)."""
        return max(self.sets(motion), key=lambda r: (r.resistance_J, -len(r.clutches)))

    def smallest(self, motion: str, keep: float = PLAN_KEEP) -> SetResult:
        """The fewest clutches keeping ``keep`` of the all-ON resistance (the strongest of
        those); the best set where the motion is not controllable."""
        if not self.controllable(motion):
            return self.best(motion)
        ok = [r for r in self.sets(motion) if r.fraction >= keep]
        return min(ok, key=lambda r: (len(r.clutches), -r.resistance_J)) if ok else self.best(motion)

    def locks(self, chosen: SetResult, lock: float = PLAN_LOCK) -> list[SetResult]:
        """The other motions that ``chosen``'s set resists with at least ``lock`` of their
        all-ON resistance."""
        out = []
        for m in self.motions:
            r = self.find(m, chosen.clutches)
            if m != chosen.motion and self.controllable(m) and r is not None and r.fraction >= lock:
                out.append(r)
        return out

    def to_json(self) -> dict:
        per = {}
        for m in self.motions:
            s = self.smallest(m)
            per[m] = {"controllable": self.controllable(m), "energy_off_J": self.energy_off_J[m],
                      "designed_set": list(self.designed.get(m, self.clutch_names)),
                      "best": self.best(m).row(), "recommended": s.row(),
                      "locks": {r.motion: r.fraction for r in self.locks(s)},
                      "elsewhere": {o: self.find(o, s.clutches).row() for o in self.motions
                                    if o != m and self.find(o, s.clutches) is not None}}
        return {"clutches": list(self.clutch_names), "exhaustive": self.exhaustive, "keep": PLAN_KEEP,
                "lock": PLAN_LOCK, "motions": per, "sets": [r.row() for r in self.results],
                "from_path": list(self.from_path)}


def _label(names) -> str:
    return "+".join(names) if names else "none"


def make_plan(evaluator, design: np.ndarray, motions=None, exhaustive_up_to: int = PLAN_EXHAUSTIVE,
              known: dict | None = None) -> Plan:
    """The :class:`Plan` of ``design`` (m,) on ``motions`` (default: the evaluator's), with
    every subset of the clutches when there are at most ``exhaustive_up_to`` of them,
    greedy sets otherwise.  ``known``: {(motion, "on" | "off"): StateResult} equilibria
    found otherwise (the ends of the motion from rest, ``PathReport.ends``), kept instead of
    the two starts' by :func:`kgarment.case.starts.with_known`."""
    from kgarment.case.starts import Equilibrium, with_known

    case = evaluator.case
    names = tuple(c.name for c in case.model.clutches)
    K = len(names)
    motions = evaluator.motion_names(motions)
    design = np.asarray(design, dtype=np.float64)
    keyed, known_eq = on_off_equilibria(evaluator, design, motions)
    from_path = []
    for key, end in (known or {}).items():
        if key in known_eq and (eq := with_known(Equilibrium(known_eq[key]), end)).from_path:
            known_eq[key] = eq.result
            from_path.append(f"{key[0]}:{key[1]}")
    known = known_eq
    states = dict(keyed)
    full = tuple(range(K))
    for m in motions:  # the motion's ON set (all clutches unless it has its own) is the evaluation's ON state
        on = case.on_activation(m)
        if np.all((on == 0.0) | (on == 1.0)) and on.any():
            label = _label(names[i] for i in np.flatnonzero(on))
            known[(m, label)] = known[(m, "on")]
            states[(m, label)] = states[(m, "on")]

    own = {m: case.on_activation(m) for m in motions if not np.all(case.on_activation(m) == 1.0)}  # activation sets
    designed_sets = {tuple(g) for g in own.values()}

    def solve(sets, ms):
        keyed, locks = [], []
        for idx in sets:
            g = np.zeros(K)
            g[list(idx)] = 1.0
            for key, st in evaluator.activation_states(g, ms, _label(names[i] for i in idx)):
                if key in known:
                    continue
                # another motion's designed set: solved like the evaluator's lock states (its
                # two starts, the lower kept), so the table says what evaluate's lock rows say
                lock = tuple(g) in designed_sets and not np.array_equal(g, case.on_activation(key[0]))
                (locks if lock else keyed).append((key, st))
        if locks:
            known.update(zip([k for k, _ in locks], evaluator.equilibria(design, locks)))
        if keyed:
            known.update(activation_equilibria(evaluator, design, keyed, known))
        states.update(dict(keyed + locks))

    def energy(m, idx):
        return known[(m, _label(names[i] for i in idx))].total_energy

    if K <= exhaustive_up_to:
        chosen = [s for n in range(1, K + 1) for s in itertools.combinations(range(K), n)]
    else:
        chosen = {full}
        for m in motions:
            cur: tuple[int, ...] = ()
            best_e = known[(m, "off")].total_energy
            while len(cur) < K:
                cand = [tuple(sorted(cur + (k,))) for k in range(K) if k not in cur]
                solve(cand, [m])
                e = [energy(m, c) for c in cand]
                j = int(np.argmax(e))
                if e[j] <= best_e:
                    break
                cur, best_e = cand[j], e[j]
                chosen.add(cur)
        chosen = sorted(chosen, key=lambda c: (len(c), c))
    solve(chosen, motions)
    results = []
    for m in motions:
        off = known[(m, "off")]
        gain = energy(m, full) - off.total_energy
        for idx in chosen:
            label = _label(names[i] for i in idx)
            r = known[(m, label)]
            t = clutch_tensions(case.model_of(m), design, states[(m, label)], r.x, case.solver)
            res = r.total_energy - off.total_energy
            frac = res / gain if gain > MIN_GAIN * abs(off.total_energy) else float("nan")
            results.append(SetResult(m, tuple(names[i] for i in idx), float(r.total_energy), float(res), float(frac),
                                     {names[i]: float(t[i]) for i in idx}, converged=bool(r.converged)))
    designed = {m: tuple(n for n, a in zip(names, g) if a > 0) for m, g in own.items()}
    return Plan(tuple(motions), names, tuple(results), {m: float(known[(m, "off")].total_energy) for m in motions},
                K <= exhaustive_up_to, designed=designed, from_path=tuple(from_path))


def plan_markdown(plan: Plan, title: str) -> str:
    """``plan.md``: per motion the recommended set (what to program into the garment's
    controller), its resistance and tensions, what it does in the other motions, and the
    full motion x set table of resistances."""
    md = [f"# Control plan: {title}", "",
          f"Clutches: {', '.join(plan.clutch_names)}. Resistance = garment energy with the set ON minus all "
          f"OFF (J; what the wearer works against, beyond the plain garment). Recommended = the fewest clutches "
          f"keeping {PLAN_KEEP:.0%} of the all-ON resistance; a set *locks* another motion where it resists it "
          f"with {PLAN_LOCK:.0%} or more of that motion's all-ON resistance. "
          + ("Every subset of the clutches was evaluated." if plan.exhaustive else
             "Sets found by a greedy search per motion (more clutches than the exhaustive limit).")
          + ("".join(f" Designed for: {m} -> {', '.join(v)}." for m, v in plan.designed.items()))
          + (f" Ended lower over the motion from rest than from the evaluator's two starts, and kept: "
             f"{', '.join(plan.from_path)}." if plan.from_path else ""), "",
          "| motion | switch on | resistance (J) | of all ON | tensions (N) | locks |", "|---|---|---|---|---|---|"]
    for m in plan.motions:
        if not plan.controllable(m):
            md.append(f"| {m} | (none: no clutch set changes this motion) | "
                      f"{plan.all_on(m).resistance_J:.3g} | - | - | - |")
            continue
        s = plan.smallest(m)
        locks = ", ".join(f"{r.motion} ({r.fraction:.0%})" for r in plan.locks(s)) or "none"
        tens = ", ".join(f"{k} {v:.0f}" for k, v in s.tension_N.items())
        md.append(f"| {m} | {', '.join(s.clutches)} | {s.resistance_J:.3g} | {s.fraction:.0%} | {tens} | {locks} |")
    md += ["", "## Every set in every motion (resistance in J, fraction of all ON)", "",
           "| set | " + " | ".join(plan.motions) + " |", "|---|" + "---|" * len(plan.motions)]
    seen = []
    for r in plan.results:
        if r.clutches not in seen:
            seen.append(r.clutches)
    for key in seen:
        cells = []
        for m in plan.motions:
            r = plan.find(m, key)
            if r is None:
                cells.append("-")
                continue
            frac = "" if math.isnan(r.fraction) else f" ({r.fraction:.0%})"
            cells.append(f"{r.resistance_J:.3g}{frac}" + ("" if r.converged else " (not converged)"))
        md.append(f"| {', '.join(key)} | " + " | ".join(cells) + " |")
    return "\n".join(md) + "\n"
