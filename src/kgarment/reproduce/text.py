"""The report's words: targets met or missed, per-experiment assessment, the comparison
with the paper, and the performance tables; all computed from ``results.json``."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np

from kgarment.constants import LOADED_SHARE
from kgarment.reproduce.targets import evaluate_targets, ratio_text

ROOT = Path(__file__).resolve().parents[3]


def md_table(head: list[str], rows: list[list[str]]) -> list[str]:
    """A Markdown table (and a blank line) as lines."""
    out = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    out += ["| " + " | ".join(str(c) for c in r) + " |" for r in rows]
    return out + [""]


def _ok(flag: bool) -> str:
    return "**met**" if flag else "**MISSED**"


def _on(e: dict, kind: str, m: str) -> float:
    return e["evaluations"][kind]["rho"][m]["on"]


def targets(doc: dict) -> list[str]:
    """Bullets: the issue's targets for our designs, each met or missed, with the numbers;
    then what limits the missed ones."""
    out = [f"- `{t.name}`: {_ok(t.ok)}: {t.detail}" for t in evaluate_targets(doc)]
    out += ["", "What limits them (measured, see `docs/notes/design.md`):",
            "- On this frictionless body only the attachment rings and bands that close around an arm or the "
            "torso hold load: an open strip of reinforcement slides. A clutch carries load only in series between "
            "such anchors, and the objective routes each motion through its strongest clutch; `[design] balance` "
            "rewards every clutch of a motion's set for carrying load on its own (one more state per clutch and "
            "motion; the single-motion shirts use it, and the five-motion long sleeve in arms raise only, "
            "`balance = { arms_raise = 2.0 }`, where without it the V carried no motion).",
            "- A membrane on a frictionless body has several equilibria: one BESO step can move a motion's ON "
            "state to another (the sleeve turns about the arm until its clutch lies over the elbow's axis) and "
            "BESO then cuts the idle path; `[design] guard` takes such steps back (the multi-motion sleeves and "
            "arms forward use it).",
            "- At the target area the paper's BESO keeps exchanging faces, and on a frictionless body the exchange "
            "can swing for ever between equilibria (the arm-flexion sleeve climbs, turns about the arm and "
            "collapses, again and again); `[design] settle` halves the faces added every few iterations at the "
            "target (arm flexion and arms forward use it) and each run reports its best iteration there.",
            "- Every clutch loaded against the diagonal: the single-motion arms-forward design must load the V "
            "clutches in arms forward, a motion that pulls across the upper back; the routes through the V cost "
            "it rho ON that the designs for bend forward or all three motions (which load the V in arms raise, "
            "or not at all in arms forward) keep.",
            "- The manual baseline of a one-clutch sleeve is a strip from each clutch end to the sleeve's nearest "
            "attachment ring, widened to the budget: for arm extension that is nearly the load path BESO finds, so ours can "
            "match it but not beat it 1.5-fold.",
            "- Bend forward moves the arms too (the reference amounts: shoulder flexion and elbow), so the arm-band "
            "path through the upper back clutch carries most of it."]
    if doc["resolution"]["name"] != "default":
        out += ["- Preview resolution: 18 mm edges and doubled BESO steps; `--resolution default` is the comparison "
                "that counts."]
    return out


def assessment(e: dict) -> list[str]:
    """A few sentences on one experiment: contrast, baselines, structure."""
    ev = e["evaluations"]
    lines = []
    for m in e["motions"]:
        on, off = _on(e, "ours", m), ev["ours"]["rho"][m]["off"]
        rnd = np.mean([r["rho"][m]["on"] for r in ev["random"]]) if ev["random"] else np.nan
        manual = ratio_text(on, _on(e, "manual", m), "rho") if "manual" in ev else "n/a"
        lines.append(f"- {m}: ON/OFF contrast {on / max(off, 1e-12):.1f}x; rho ON against the manual baseline: "
                     f"{manual}; {on / max(_on(e, 'compliance', m), 1e-12):.2f}x the compliance design, "
                     f"{on / max(rnd, 1e-12):.2f}x the random mean.")
    rows = e.get("run", {}).get("objectives_at_target", [])
    if len(rows) >= 5:
        lo, hi = min(rows), max(rows)
        lines.append(f"- Run: objective between {lo:.3f} and {hi:.3f} over the {len(rows)} iterations at the target area"
                     + (" -- it oscillates: the ON equilibria of these sparse designs are multistable, and a "
                        "1.5-3% design change can move the garment to another one." if hi > 2 * max(lo, 1e-9) else "."))
    for kind in ("ours", "manual"):
        moved = [r for r in ev.get(kind, {}).get("rows", []) if r.get("from_path")]
        if moved:
            lines.append(f"- Equilibria ({kind}): " + "; ".join(
                f"in {r['motion']} {r['state'].upper()} the motion from rest ends in an equilibrium below the one the "
                f"two starts reach (rho {r['rho']:.2f} against "
                + ("theirs unconverged)" if r["other_rho"] is None else f"{r['other_rho']:.2f})") for r in moved)
                + ". The numbers here (rho, loads) are the motion's: what a wearer meets.")
    o = ev["ours"]
    lines.append(f"- Structure: {o['islands_with_clutches']} part(s) counting clutches as links ({o['islands']} without), "
                 f"{o['clutch_ends_supported']} of {o['clutch_ends']} clutch ends on reinforcement; compliance design "
                 f"{ev['compliance']['islands_with_clutches']} part(s), {ev['compliance']['clutch_ends_supported']} ends."
                 + ("" if o["converged"] else " Some states did not converge to tolerance (see the run's metrics)."))
    idle = [n for n in dict.fromkeys(c["clutch"] for c in o.get("clutches", []))
            if not any(c["clutch"] == n and c["loaded"] for c in o["clutches"])]
    if o.get("clutches"):
        lines.append("- Clutches: " + ("every clutch carries load in at least one motion." if not idle else
                                       f"{', '.join(idle)} carry no load in any motion."))
    return lines


def load_rows(e: dict) -> list[list[str]]:
    """Per motion and clutch: share, needed and tension of our design and of the manual baseline."""
    ev = e["evaluations"]
    rows = []
    kinds = [k for k in ("ours", "manual") if ev.get(k, {}).get("clutches")]
    if not kinds:
        return rows
    for c in ev[kinds[0]]["clutches"]:
        cells = []
        for k in kinds:
            x = next(y for y in ev[k]["clutches"] if y["motion"] == c["motion"] and y["clutch"] == c["clutch"])
            share, needed = ("n/a" if v != v else f"{v:.2f}" for v in (x["share"], x.get("needed", float("nan"))))
            cells.append(f"{share} / {needed} / {x['tension_N']:.0f} N" + (" *" if x["loaded"] else "")
                         + (" ~" if x.get("slipping") else ""))
        rows.append([c["motion"], c["clutch"], *cells])
    return rows


def comparison_paragraph(doc: dict) -> str:
    """Where we match, exceed or fall short of the paper's rho ON, and why."""
    ratios = []
    for e in doc["experiments"].values():
        for m, (p_on, _) in e["paper"].items():
            if m in e["evaluations"]["ours"]["rho"] and p_on:
                ratios.append((_on(e, "ours", m) / p_on, e["name"], m))
    if not ratios:
        return "No experiment with published numbers was run."
    over = [r for r in ratios if r[0] > 1.2]
    match = [r for r in ratios if 0.8 <= r[0] <= 1.2]
    under = [r for r in ratios if r[0] < 0.8]

    def names(rs):
        return ", ".join(f"{n}/{m} ({r:.2f}x)" for r, n, m in rs) or "none"

    offs = [(e["evaluations"]["ours"]["rho"][m]["off"], p_off) for e in doc["experiments"].values()
            for m, (_, p_off) in e["paper"].items() if p_off is not None and m in e["evaluations"]["ours"]["rho"]]
    off_txt = ""
    if offs:
        ours_off, paper_off = np.mean([a for a, _ in offs]), np.mean([b for _, b in offs])
        off_txt = f" Our rho OFF is {ours_off:.2f} on average against the paper's {paper_off:.2f}" + (
            ": with the clutches off, our garment slides and stretches its plain cloth, which stores almost nothing, "
            "so the reinforcement carries little load." if ours_off < 0.5 * paper_off else ".")
    return (f"Against the paper's rho ON, ours exceeds it by more than 20% on {len(over)} motion(s): {names(over)}; "
            f"matches within 20% on {len(match)}: {names(match)}; falls short on {len(under)}: {names(under)}."
            + off_txt +
            " Part of the difference comes from the setting: the body is Anny (smaller than the "
            "paper's STAR body, with its own rig and motion magnitudes), our shirt clutches follow the paper's layout "
            "but are 10-13.5 cm long rather than 15 cm, the garment is at the report's resolution ("
            + resolution_words(doc) + "), the `" + doc.get("preset", "paper") + "` material preset is used ("
            + PRESET_WORDS.get(doc.get("preset", "paper"), "") + ")"
            + (", the clutches slip at their holding force (the paper's never do)" if "slip" in doc.get("clutch_model", "")
               else "")
            + (", the clutches are pull-only cables between their ends that slip at their holding force (the "
               "paper's are stiff bands that never slip)" if "cable" in doc.get("clutch_model", "") else "")
            + (", the ON clutch strips buckle instead of resisting compression (the paper's resist it as stiffly as "
               "tension)" if buckling(doc) else "")
            + ", and our Newton solver finds tighter equilibria than the paper's L-BFGS. rho is a ratio to "
            "the fully reinforced garment, so it depends on all of these."
            + short_words(doc, [r for r in under if r[0] < 0.5]))


def short_words(doc: dict, short: list[tuple[float, str, str]]) -> str:
    """The comparison's sentence on the motions where ours is more than 2x below the paper
    (``short``: (ratio, experiment, motion)), with what our design's clutch loads say there:
    the loaded clutch of largest share (its share, tension at the target) or that none is
    loaded (the loads' own ``loaded`` flag)."""
    if not short:
        return ""
    parts = []
    for r, name, m in short:
        loads = [c for c in doc["experiments"][name]["evaluations"]["ours"].get("clutches", []) if c["motion"] == m]
        carried = [c for c in loads if c["loaded"]]
        if not loads:
            what = "no clutch loads measured"
        elif not carried:
            what = f"no clutch carries it (share and needed below {LOADED_SHARE:g})"
        else:
            top = max(carried, key=lambda c: c["share"] if math.isfinite(c["share"]) else -1.0)
            what = f"{top['clutch']} carries it (share {top['share']:.2f}, {top['tension_N']:.0f} N at the target)"
        parts.append(f"{name}/{m} ({r:.2f}x): {what}")
    return " Where we fall more than 2x short, see the experiment below; " + "; ".join(parts) + "."


PAPER_SHIRT_FACES = 56384  # the paper's shirt mesh (docs/method/index.md)


def resolution_words(doc: dict) -> str:
    """The report's garment resolution in words: its subdivision level and, where a shirt
    was designed, how its edges compare with the paper's shirt's (edge ~ 1 / sqrt(faces))."""
    sub = doc.get("resolution", {}).get("subdivision")
    level = f"subdivision {sub}" if sub is not None else "the example files' subdivision"
    shirts = [e["faces"] for e in doc["experiments"].values() if e.get("group") == "shirt" and e.get("faces")]
    if not shirts:
        return level
    f = min(shirts)
    return f"{level}: a {f:,}-face shirt, edges about {math.sqrt(PAPER_SHIRT_FACES / f):.1f}x the paper's {PAPER_SHIRT_FACES:,}-face shirt's"


PRESET_WORDS = {"paper": "the paper's text: plain cloth 0.5 MPa, reinforced 0.5 GPa, clutch ON 3 GPa",
                "reference": "the paper's reference code: 0.5 / 5.7 / 25.7 MPa"}


def buckling(doc: dict) -> bool:
    """Whether the report's experiments were made with buckling clutch strips (``--buckle``;
    a reproduction folder never mixes the two)."""
    return any(e.get("clutch_buckle") for e in doc.get("experiments", {}).values())


def strips_note(doc: dict) -> str:
    """The report's words on its clutch strips: the paper's (they resist compression) or
    buckling ones (``--buckle``, the example files' own)."""
    if buckling(doc):
        return ("**buckling** clutch strips (`--buckle`: an ON strip takes no compression, as the example files "
                "design; README, \"Clutches that buckle\")")
    return ("the paper's clutch strips (an ON strip resists compression as stiffly as tension; the example files "
            "design with buckling ones, `--buckle`)")


def preset_note(doc: dict) -> str:
    """The report's words on its material preset: what it is, how strongly switching the
    clutches changes what the wearer works against in this report's designs (garment
    energy ON over OFF, the range over every motion of *ours*), and where the choice of
    the examples' default is argued (docs/notes/reproduction.md, "Which material preset
    reproduces the paper?", both presets reproduced)."""
    preset = doc.get("preset", "paper")
    words = PRESET_WORDS.get(preset, "")
    ratios = [g["energy_on_J"] / g["energy_off_J"] for e in doc["experiments"].values()
              for g in e["evaluations"]["ours"].get("garment", []) if g["energy_off_J"] > 0]
    switch = ""
    if ratios:
        lo, hi = f"{min(ratios):.1f}", f"{max(ratios):.1f}"
        switch = ("switching the clutches on multiplies what the wearer works against (the garment's energy) by "
                  f"{lo if lo == hi else f'{lo}-{hi}'} in our designs")
    default = "the examples' default" if preset == "paper" else "not the examples' default (`paper`)"
    parts = [words, switch, f"{default}, why: docs/notes/reproduction.md, "
                            "\"Which material preset reproduces the paper?\""]
    return " (" + "; ".join(p for p in parts if p) + ")"


def performance_rows(doc: dict) -> list[str]:
    """Tables: time per experiment, growth with motions, benchmark figures if recorded."""
    rows = []
    for e in doc["experiments"].values():
        r = e["run"]
        rows.append([e["name"], str(e["faces"]), str(len(e["motions"])), str(e["states"]), str(r["iterations"]),
                     f"{r['seconds'] / 60:.1f}", f"{r['seconds_per_iteration']:.1f}",
                     f"{r['newton_per_iteration'] / max(e['states'], 1):.0f}", str(r["unconverged_iterations"]),
                     f"{e['wall_seconds'] / 60:.0f}" if e.get("wall_seconds") else "–"])
    out = [f"Measured on this machine ({doc.get('device', 'cpu')}); the last session of the reproduction took "
           f"{doc['wall_seconds'] / 60:.0f} min, peak memory {doc['peak_rss_mb']:.0f} MB per process. *minutes*: "
           "our design run; *experiment*: everything the experiment took (both design runs, the evaluations, "
           "the force paths, the random designs, the renders), over every session that worked on it.", ""]
    out += md_table(["experiment", "faces", "motions", "states", "iterations", "minutes", "s / iteration",
                     "Newton its / state / iteration", "iterations with unconverged states", "experiment (min)"], rows)
    shirt = [e for e in doc["experiments"].values() if e["group"] in ("shirt", "long_sleeve")]
    if shirt:
        by_n: dict[int, list] = {}
        for e in shirt:
            by_n.setdefault(len(e["motions"]), []).append(e)
        parts = []
        for n, es in sorted(by_n.items()):
            sec = sorted(e["run"]["seconds_per_iteration"] for e in es)
            span = f"{sec[0]:.1f}" if len(sec) == 1 else f"{sec[0]:.1f} to {sec[-1]:.1f}"
            faces = "/".join(sorted({str(e["faces"]) for e in es}))
            parts.append(f"{n} motion(s): {span} s per iteration ({len(es)} run(s), {faces} faces)")
        out += ["Growth with the number of motions (shirt garments; each motion adds two states, ON and OFF): "
                + "; ".join(parts) + ". Time per iteration grows with the states and with how hard they "
                "are: the five-motion long sleeve has more faces, and its states converge less easily (last "
                "column).", ""]
    bench = ROOT / "benchmarks" / "results.json"
    if bench.is_file():
        data = json.loads(bench.read_text())
        out += ["Benchmarks (`benchmarks/results.json`, written by the scripts under `benchmarks/` with "
                "`--json`; `benchmarks/README.md` explains them): seconds (`_s`), milliseconds (`_ms`), "
                "megabytes (`_mb`).", ""]
        for name, entries in data.items():
            if not all(isinstance(v, dict) for v in entries.values()):
                entries = {name: entries}  # one case, its figures flat (benchmarks/path.py)
            cols = sorted({k for val in entries.values() for k in val if not isinstance(val[k], dict)})
            if len(cols) > 8:  # many figures of few cases (subdivision 0, 1): one row per figure
                head = ["", *entries]
                rows = [[c.replace("_", " "), *(_cell(val.get(c)) for val in entries.values())] for c in cols]
            else:
                head = ["", *[c.replace("_", " ") for c in cols]]
                rows = [[key, *(_cell(val.get(k)) for k in cols)] for key, val in entries.items()]
            out += [f"**{name}**", ""] + md_table(head, rows) + [""]
    return out


def _cell(v) -> str:
    if v is None:
        return "-"
    if isinstance(v, float):
        return f"{v:.3g}" if abs(v) < 1e4 else f"{v:,.0f}"
    if isinstance(v, int) and not isinstance(v, bool):
        return f"{v:,}"
    return str(v)
