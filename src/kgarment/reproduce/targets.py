"""The reproduction's targets (issue #19), computed from the report's data: each a flag and
a sentence with the numbers behind it.

``every_clutch_loaded``  in every design of ours, every clutch is loaded in at least one of
                         its motions (share or needed >= 0.10, :mod:`kgarment.evaluate.loads`)
``clutch_ends_supported`` every clutch end on reinforcement, in every design of ours
``one_part``             one part, counting clutches as links, in every design of ours
``single_on_off``        every single-motion design rho ON > 1 and rho OFF < 1
``multi_keeps_60``       the three-motion shirt keeps >= 60% of each single-motion rho ON
``diagonal``             the cross-evaluation's largest value of each row on the diagonal
``beats_manual``         ours >= 1.5x the manual baseline's rho ON and clutch tension (the
                         largest in the motion) on every motion
``peak_force``           (issue #23) ours' peak clutch force over the motion (ON, the
                         largest clutch tension of any frame) exceeds the manual baseline's on
                         every motion
``selective``            (issue #22) a design with activation sets: each motion's own set gives
                         rho ON > 1, another motion's set stores at most half of its own set's
                         resistance in it, and it keeps >= 80% of the all-ON multi-motion
                         design's resistance per motion (``kgarment plan`` of both)
"""

from __future__ import annotations

from dataclasses import dataclass

from kgarment.constants import LOADED_SHARE

NEGLIGIBLE_RHO = 0.01  # a baseline below this rho ON stores (almost) nothing: no ratio is printed


@dataclass(frozen=True)
class Target:
    """name; ok : met; detail : the numbers."""

    name: str
    ok: bool
    detail: str


def _on(e: dict, kind: str, m: str) -> float:
    return e["evaluations"][kind]["rho"][m]["on"]


def max_tension(ev: dict, motion: str) -> float:
    """The largest clutch tension (N) of a design's evaluation in ``motion`` (0 without loads)."""
    return max((c["tension_N"] for c in ev.get("clutches", []) if c["motion"] == motion), default=0.0)


def ratio_text(ours: float, base: float, what: str) -> str:
    """``ours / base`` as text, or a sentence when the baseline holds (almost) nothing."""
    if base < NEGLIGIBLE_RHO * max(abs(ours), 1.0) and what == "rho":
        return f"the {what} of the baseline is {base:.3g}: it stores almost nothing"
    return f"{ours / max(base, 1e-12):.2f}x"


def evaluate_targets(doc: dict) -> list[Target]:
    """Every target that the data can decide (the cross-evaluation and the shirt's share
    need their experiments)."""
    exps = doc["experiments"]
    out = []
    idle, ends, parts = [], [], []
    for e in exps.values():
        o = e["evaluations"]["ours"]
        names = list(dict.fromkeys(c["clutch"] for c in o.get("clutches", [])))
        for n in names:
            if not any(c["clutch"] == n and c["loaded"] for c in o["clutches"]):
                rows = [c for c in o["clutches"] if c["clutch"] == n]
                best = max((c["share"] for c in rows if c["share"] == c["share"]), default=float("nan"))
                need = max((c.get("needed", float("nan")) for c in rows if c.get("needed") == c.get("needed")),
                           default=float("nan"))
                idle.append(f"{e['name']}/{n} (largest share {best:.2f}, needed {need:.2f})")
        if o["clutch_ends_supported"] < o["clutch_ends"]:
            ends.append(f"{e['name']} ({o['clutch_ends_supported']}/{o['clutch_ends']})")
        if o["islands_with_clutches"] > 1:
            parts.append(f"{e['name']} ({o['islands_with_clutches']} parts)")
    out.append(Target("every_clutch_loaded", not idle, "every clutch of every design has share or "
                      f"needed >= {LOADED_SHARE:g} in one of its motions" + (f"; not: {', '.join(idle)}" if idle else "")))
    out.append(Target("clutch_ends_supported", not ends, "every clutch end on reinforcement"
                      + (f"; not: {', '.join(ends)}" if ends else "")))
    out.append(Target("one_part", not parts, "one part counting clutches as links"
                      + (f"; not: {', '.join(parts)}" if parts else "")))
    singles = [e for e in exps.values() if not e["multi"]]
    if singles:
        bad = [f"{e['name']} ({_on(e, 'ours', m):.2f} / {e['evaluations']['ours']['rho'][m]['off']:.2f})"
               for e in singles for m in e["motions"]
               if not (_on(e, "ours", m) > 1 and e["evaluations"]["ours"]["rho"][m]["off"] < 1)]
        out.append(Target("single_on_off", not bad, "every single-motion design has rho ON > 1 and OFF < 1"
                          + (f"; not: {', '.join(bad)}" if bad else "")))
    shirt = exps.get("shirt_three_motions")
    if shirt:
        shares = [(m, _on(shirt, "ours", m) / max(_on(exps[m], "ours", m), 1e-12)) for m in shirt["motions"]
                  if m in exps]
        if shares:
            out.append(Target("multi_keeps_60", all(s >= 0.6 for _, s in shares),
                              "the three-motion shirt keeps at least 60% of each single-motion rho ON ("
                              + ", ".join(f"{m} {100 * s:.0f}%" for m, s in shares) + ")"))
        cross = doc.get("cross", {}).get("shirt")
        if cross:
            rows = cross["rho_on"]
            diag = [r for r in rows if r in rows[r] and rows[r][r] >= max(rows[r].values()) - 1e-12]
            out.append(Target("diagonal", len(diag) == len(rows), "the cross-evaluation's largest value of each "
                              f"row is on the diagonal ({len(diag)} of {len(rows)} rows)"))
    worst = []
    for e in exps.values():
        ev = e["evaluations"]
        if "manual" not in ev:
            continue
        for m in e["motions"]:
            r_rho = _on(e, "ours", m) / max(_on(e, "manual", m), 1e-12)
            r_t = max_tension(ev["ours"], m) / max(max_tension(ev["manual"], m), 1e-12)
            worst.append((min(r_rho, r_t), r_rho, r_t, e["name"], m))
    if worst:
        w = min(worst)
        out.append(Target("beats_manual", w[0] >= 1.5, "ours has at least 1.5x the manual baseline's rho ON and "
                          f"clutch tension on every motion (smallest: {w[3]} / {w[4]}, rho {w[1]:.2f}x, "
                          f"tension {w[2]:.2f}x)"))
    out += selective_targets(exps)
    out += force_targets(exps)
    return out


def set_resistance(plan: dict, motion: str, clutches) -> float | None:
    """The resistance (J) of the set of ``clutches`` in ``motion`` from a clutch-set table
    (``kgarment plan``'s JSON), in any order; None where the table has no such row."""
    key = sorted(clutches)
    return next((r["resistance_J"] for r in plan["sets"] if r["motion"] == motion and sorted(r["clutches"]) == key),
                None)


def selective_targets(exps: dict) -> list[Target]:
    """The ``selective`` target of every experiment with activation sets and a clutch-set
    table, against the all-ON design: the same problem designed with every clutch ON and the
    same clutches (``plan_all_on``), or where an experiment has none (data of earlier
    reproductions), its group's multi-motion design."""
    from kgarment.reproduce.catalog import MULTI_OF_GROUP

    out = []
    for e in exps.values():
        plan, sets = e.get("plan"), e.get("activation")
        base = e.get("plan_all_on") or exps.get(MULTI_OF_GROUP.get(e["group"], ""), {}).get("plan")
        if not plan or not sets:
            continue
        every = plan["clutches"]
        own = {m: list(sets.get(m, every)) for m in e["motions"]}
        bad, facts = [], []
        for m in e["motions"]:
            mine = set_resistance(plan, m, own[m]) or 0.0
            rho = _on(e, "ours", m)
            locks = [(o, set_resistance(plan, m, own[o]) or 0.0) for o in e["motions"] if o != m and own[o] != own[m]]
            worst = max((r for _, r in locks), default=0.0) / max(mine, 1e-12)
            keep = mine / max(set_resistance(base, m, every) or 0.0, 1e-12) if base else float("nan")
            facts.append(f"{m}: rho ON {rho:.2f}, other sets {100 * worst:.0f}% of its own, "
                         + (f"{100 * keep:.0f}% of the all-ON design" if base else "no all-ON design to compare"))
            if not (rho > 1 and worst <= 0.5 and (not base or keep >= 0.8)):
                bad.append(m)
        # the lock and the resistance depend on the clutches and the skin
        said = ([f"{e['clutch_model']} clutches"] if e.get("clutch_model") else []) + (
            [f"skin friction {e['skin_friction']:g}"] if e.get("skin_friction") else [])
        model = f" ({', '.join(said)})" if said else ""
        out.append(Target("selective", not bad, f"{e['name']}{model}: each motion's own set gives rho ON > 1, another "
                          "motion's set stores at most half of that, and the design keeps 80% of the all-ON design's "
                          "resistance (" + "; ".join(facts) + ")"))
    return out


def target_flags(doc: dict) -> dict[str, bool]:
    """{target name: met} for results.json."""
    return {t.name: bool(t.ok) for t in evaluate_targets(doc)}


def force_targets(exps: dict) -> list[Target]:
    """The ``peak_force`` target over the experiments whose force over the motion was
    computed (none: no target)."""
    from kgarment.reproduce.figures import force_stats

    worst = []
    for e in exps.values():
        paths = e.get("path") or {}
        if "ours" not in paths or "manual" not in paths:
            continue
        for m in e["motions"]:
            ours, manual = force_stats(paths["ours"], m)["on"]["peak"], force_stats(paths["manual"], m)["on"]["peak"]
            worst.append((ours / max(manual, 1e-9), f"{e['name']} / {m}", ours, manual))
    if not worst:
        return []
    bad = [w for w in worst if w[0] <= 1.0]
    lo = min(worst)
    detail = "ours' peak clutch force over the motion exceeds the manual baseline's on every motion"
    detail += f" (smallest: {lo[1]}, {lo[2]:.0f} N against {lo[3]:.0f} N)"
    if bad:
        detail += "; not: " + ", ".join(f"{w[1]} ({w[2]:.0f} against {w[3]:.0f} N)" for w in bad)
    return [Target("peak_force", not bad, detail)]
