"""The reproduction report: one Markdown document and its HTML twin, with figures.

Built from ``data.json`` (:mod:`kgarment.reproduce.pipeline`) alone, so it can be
rewritten without simulating anything.  Sections: single-motion designs, multi-motion
designs with the cross-evaluation matrix, baselines, the paper side by side with the
targets of the reproduction, progress and emergent-property figures, performance.
"""

from __future__ import annotations

import html
import json
import logging
from pathlib import Path

import numpy as np

from kgarment.design.reported import CANDIDATES, UNREACHED
from kgarment.reproduce.catalog import DATA, EXPERIMENTS, PAPER_SHIRT_MATRIX, objectives_at_target
from kgarment.reproduce.figures import emergent_figure, force_stats, rho_bars
from kgarment.reproduce.pipeline import PATH_EVALUATED
from kgarment.reproduce.targets import set_resistance
from kgarment.reproduce.text import (
    assessment,
    comparison_paragraph,
    load_rows,
    md_table,
    performance_rows,
    preset_note,
    strips_note,
    targets,
)
from kgarment.reproduce.validation import validation_lines

log = logging.getLogger(__name__)


def _f(v, nd=2) -> str:
    return "–" if v is None or (isinstance(v, float) and not np.isfinite(v)) else f"{v:.{nd}f}"


def random_stats(evals: list[dict], motion: str, state: str) -> tuple[float, float]:
    v = np.array([e["rho"][motion][state] for e in evals])
    return (float(v.mean()), float(v.std(ddof=1)) if len(v) > 1 else 0.0) if len(v) else (np.nan, np.nan)


def path_evaluated_words() -> str:
    """The designs the pipeline evaluates over the motion from rest (``PATH_EVALUATED``), in words."""
    words = {"ours": "ours", "ours_last": "its last iteration", "manual": "the manual baseline",
             "compliance": "the compliance design"}
    names = [words[k] for k in PATH_EVALUATED]
    return ", ".join(names[:-1]) + " and " + names[-1] if len(names) > 1 else names[0]


def design_rows(e: dict) -> list[list[str]]:
    """One row per design kind: rho ON/OFF per motion, islands, clutch ends, area."""
    ev = e["evaluations"]
    rows = []
    for kind in ("ours", "ours_last", "manual", "compliance", "full"):
        if kind not in ev:
            continue
        r = ev[kind]
        cells = [f"{_f(r['rho'][m]['on'])} / {_f(r['rho'][m]['off'])}" for m in e["motions"]]
        label = {"ours": f"ours (iteration {e['run']['reported_iteration']})",
                 "ours_last": f"ours, last iteration ({e['run']['iterations'] - 1})"}.get(kind, kind)
        rows.append([label, *cells, f"{r['islands_with_clutches']} / {r['islands']}",
                     f"{r['clutch_ends_supported']}/{r['clutch_ends']}",
                     f"{100 * r['area']:.1f}%"])
    rnd = ev["random"]
    if rnd:
        cells = []
        for m in e["motions"]:
            on, son = random_stats(rnd, m, "on")
            off, soff = random_stats(rnd, m, "off")
            cells.append(f"{_f(on)}±{_f(son)} / {_f(off)}±{_f(soff)}")
        isl = (f"{np.mean([r['islands_with_clutches'] for r in rnd]):.1f} / "
               f"{np.mean([r['islands'] for r in rnd]):.1f}")
        ends = np.mean([r["clutch_ends_supported"] for r in rnd])
        rows.append([f"random (n={len(rnd)})", *cells, isl, f"{ends:.1f}/{rnd[0]['clutch_ends']}",
                     f"{100 * np.mean([r['area'] for r in rnd]):.1f}%"])
    paper = [f"{_f(e['paper'].get(m, (None, None))[0])} / {_f(e['paper'].get(m, (None, None))[1])}"
             for m in e["motions"]]
    rows.append(["paper's design", *paper, "–", "–", f"{100 * e['budget']:.0f}%"])
    return rows


def plan_lines(e: dict) -> list[str]:
    """An experiment's activation sets and our design's clutch-set table (``kgarment plan``)."""
    md = []
    if e.get("activation"):
        sets = "; ".join(f"{m} -> {', '.join(v)}" for m, v in e["activation"].items())
        md += [f"Activation sets: {sets} (other motions: every clutch); lockout {e.get('lockout', 0):g}.", ""]
    plan = e.get("plan")
    if not plan:
        return md
    motions = list(plan["motions"])
    md += ["Clutch sets (`kgarment plan` of our design): garment energy with the set ON minus all OFF, J "
           "(share of all clutches ON); **bold**: the set recommended for the motion (the fewest clutches "
           f"keeping {plan['keep']:.0%})."
           + (f" ON / OFF equilibria from the motion from rest (lower than the two starts'): "
              f"{', '.join(plan['from_path'])}." if plan.get("from_path") else ""), ""]
    rec = {m: tuple(plan["motions"][m]["recommended"]["clutches"]) for m in motions}
    rows, seen = [], []
    for r in plan["sets"]:
        if tuple(r["clutches"]) not in seen:
            seen.append(tuple(r["clutches"]))
    for key in seen:
        cells = []
        for m in motions:
            r = next((x for x in plan["sets"] if x["motion"] == m and tuple(x["clutches"]) == key), None)
            if r is None:
                cells.append("-")
                continue
            frac = "" if r["fraction"] is None else f" ({r['fraction']:.0%})"
            text = f"{r['resistance_J']:.3g}{frac}"
            cells.append(f"**{text}**" if rec[m] == key else text)
        rows.append([", ".join(key), *cells])
    return md + md_table(["set ON", *motions], rows) + all_on_lines(e)


def all_on_lines(e: dict) -> list[str]:
    """The all-ON comparison of an experiment with activation sets: the same problem designed
    with every clutch ON (``plan_all_on``), every clutch ON in each motion against our
    design's own set there (empty without it)."""
    base, plan = e.get("plan_all_on"), e.get("plan")
    if not base or not plan:
        return []
    every = sorted(base["clutches"])
    nan = float("nan")
    parts = []
    for m in plan["motions"]:
        own = sorted(e.get("activation", {}).get(m, every))
        mine, theirs = set_resistance(plan, m, own), set_resistance(base, m, every)
        mine, theirs = nan if mine is None else mine, nan if theirs is None else theirs
        parts.append(f"{m} {theirs:.3g} J (ours with {', '.join(own)}: {mine:.3g} J, {mine / theirs:.0%})")
    run = e.get("all_on_run", {})
    return ["", "The all-ON design (the same problem designed with every clutch ON and the same clutches"
            + (f", iteration {run['reported_iteration']}" if "reported_iteration" in run else "")
            + "), every clutch ON: " + "; ".join(parts) + ".", ""]


def force_lines(e: dict) -> list[str]:
    """The force over the motion (``kgarment evaluate --path``) of our design and the
    baselines: per motion, peak and mean of the largest clutch tension and the work."""
    paths = e.get("path")
    if not paths:
        return []
    rows = []
    for m in e["motions"]:
        for kind, doc in paths.items():
            st = force_stats(doc, m)
            rows.append([m, kind, f"{st['on']['peak']:.0f} / {st['off']['peak']:.0f}",
                         f"{st['on']['mean']:.0f} / {st['off']['mean']:.0f}",
                         f"{st['on']['work']:.3g} / {st['off']['work']:.3g}",
                         f"{st['on']['energy']:.3g} / {st['off']['energy']:.3g}"])
    n = sum(f["t"] > 0 for f in next(iter(paths.values()))["frames"]) // max(2 * len(e["motions"]), 1)
    notes = []
    for kind, doc in paths.items():
        bad = [f for f in doc["frames"] if not f["converged"]]
        again = doc.get("resolved", [])
        if bad:
            notes.append(f"{kind}: {len(bad)} frame(s) did not converge (crossed in the figure: "
                         + ", ".join(f"{f['motion']} {f['state'].upper()} t = {f['t']:.2f}" for f in bad) + ")")
        if again:
            notes.append(f"{kind}: {len(again)} frame(s) re-solved (the first solve had ended in another, "
                         "higher-energy equilibrium)")
        for sl in doc.get("slips", []):  # the slip model's (kgarment.sim.slip)
            notes.append(f"{kind}: {sl['clutch']} slides at its holding force ({sl['holding_N']:.0f} N) in "
                         f"{sl['motion']} from t = {sl['from_t']:.2f}")
    return ["Force over the motion (" + str(n) + " frames from rest to the target pose; force: the largest clutch "
            "tension, its mean over the frames after rest; work: what the wearer does against the garment, its "
            "energy at the target less its energy at rest, where the attachment rings and the body already hold it "
            "stretched), ON / OFF.", ""] + \
        md_table(["motion", "design", "peak force (N)", "mean force (N)", "work (J)", "energy at the target (J)"],
                 rows) + \
        ([f"- {x}" for x in notes] + [""] if notes else [])


def build_markdown(doc: dict, figures: dict) -> str:
    exps = doc["experiments"]
    res = doc["resolution"]
    sub = res["subdivision"] if res["subdivision"] is not None else "of the example files"
    er = "" if res["er"] is None else f", BESO evolution ratio {res['er']}"
    if res["er"] is not None and res.get("ar_max") is not None:
        er += f" with {res['ar_max']} of the faces added per iteration at most"
    md = ["# kgarment reproduces *Computational Design of Active Kinesthetic Garments* (UIST 2022)", "",
          f"Resolution **{res['name']}** (garment subdivision {sub}{er}), material preset "
          f"**{doc.get('preset', 'paper')}**{preset_note(doc)}, {strips_note(doc)}, {res['seeds']} random seeds. "
          "rho is the relative energy density of the method (kgarment's manual, docs/method/index.md, "
          "'The relative energy density'): energy per reinforced area over that of "
          "the fully reinforced garment in the same state, clutch energy and area included; "
          "ON / OFF = clutches on / off. *ours* is the iteration with the highest objective among those at the "
          "target area whose states all converged (BESO's objective is not monotone there; the paper samples designs "
          "along a run likewise) and whose rho ON the evaluator reproduces over the motion from rest (at least "
          f"{1 - UNREACHED:.0%} of the run's in every motion; the run solves each iteration warm from the one before "
          "and can hold an equilibrium the garment put on afresh does not reach); if none of the "
          f"{CANDIDATES} best does, the best of them as "
          "evaluated (the run's `final/evaluation.json`, `selection`); the last iteration is shown too. Every design is evaluated by the one design "
          "evaluator (`kgarment evaluate`'s numbers): each state from the skin-tight start and from the fully "
          "reinforced garment's equilibrium, the lower-energy equilibrium kept"
          + (f"; {path_evaluated_words()} also over the motion from rest ({res['path_frames']} frames), its end "
             "kept where lower (what a wearer meets), the random designs from the two starts only"
             if res.get("path_frames") else "")
          + ". Clutch loads: per motion and "
          "clutch the share of the ON - OFF garment energy with only that clutch ON, the share lost with only that "
          "clutch OFF (*needed*: clutches in series on one load path each have share ~0 and needed ~1) and the "
          "tension it carries with all ON. *manual* is the baseline a designer draws: strips from each clutch end to where the body "
          "pulls the garment (attachment rings, bands around the limbs), a clutch's two ends to two different ones, "
          "widened to the budget. Generated by "
          "`kgarment reproduce`; `results.json` beside this report holds the numbers and the targets.", ""]
    missing = [x.name for x in EXPERIMENTS if x.name not in exps]
    if missing:
        md += [f"Not in this report (not run into this folder yet): {', '.join(missing)}.", ""]
    md += ["## Targets", ""] + targets(doc) + [""]
    md += ["## Compared with the paper", "", comparison_paragraph(doc), ""]
    if "rho_bars" in figures:
        md += [f"![rho ON of every design and baseline]({figures['rho_bars']})", ""]
    for title, multi in (("Single-motion designs", False), ("Multi-motion designs", True)):
        md += [f"## {title}", ""]
        for e in (x for x in exps.values() if x["multi"] == multi):
            md += [f"### {e['title']}", "",
                   f"`{e['name']}`: {e['garment']}, {e['faces']} faces, {e['clutches']} clutch(es), budget "
                   f"{100 * e['budget']:.0f}%"
                   + balance_note(e)
                   + early_note(e)
                   + weights_note(e)
                   + (f", skin friction {e['skin_friction']:g} (README, \"Skin friction\")" if e.get("skin_friction") else "")
                   + f"; our run took {e['run']['iterations']} iterations, {e['run']['seconds'] / 60:.1f} min.", ""]
            head = ["design", *[f"{m} ON / OFF" for m in e["motions"]], "parts (clutch-linked / not)", "clutch ends on reinf.", "area"]
            md += md_table(head, design_rows(e))
            loads = load_rows(e)
            if loads:
                kinds = [k for k in ("ours", "manual") if e["evaluations"].get(k, {}).get("clutches")]
                md += ["Clutch loads: share of the ON - OFF garment energy with only that clutch ON / share lost "
                       "with only that clutch OFF (needed) / tension with all ON (* loaded: share or needed at "
                       "least 0.10"
                       + ("; ~ slides at its holding force" if any(c.get("slipping") for k in kinds
                                                                  for c in e["evaluations"][k]["clutches"]) else "")
                       + ").", ""]
                md += md_table(["motion", "clutch", *kinds], loads)
            md += plan_lines(e)
            md += force_lines(e)
            imgs = [f"![{k}]({e['images'][k]})" for k in ("ours", "manual", "compliance", "all_on", "progress", "force")
                    if k in e["images"]]
            md += [" ".join(imgs), ""]
            md += assessment(e) + [""]
    cross = doc.get("cross", {})
    if cross:
        md += ["## Cross-evaluation (the paper's Table 1)", "",
               "Rows: the motion evaluated; columns: the motion the design was optimised for, and *all* (the "
               "multi-motion design). Every design is evaluated with the multi-motion problem's clutches. "
               "rho ON, ours (paper in brackets where published).", ""]
        for group, m in cross.items():
            cols = list(next(iter(m["rho_on"].values())))
            rows = []
            for row in m["motions"]:
                cells = []
                for c in cols:
                    p = PAPER_SHIRT_MATRIX.get(row, {}).get(c) if group == "shirt" else None
                    cells.append(_f(m["rho_on"][row][c]) + (f" ({p:.2f})" if p is not None else ""))
                rows.append([row, *cells])
            md += [f"**{m['problem']}**", ""] + md_table(["evaluated on \\ optimised for", *cols], rows)
    if validation := validation_lines(doc):
        md += ["## Forces against the manual design (the paper's physical validation)", ""] + validation
    md += ["## Emergent properties", ""]
    if "emergent" in figures:
        md += [f"![our design against the compliance and manual baselines]({figures['emergent']})", ""]
    md += ["Parts are connected components of reinforcement (edge adjacency), counted with a clutch "
           "joining the parts its two ends sit on (the method's emergent properties: a good design's "
           "clutches link otherwise disconnected parts) and without; a design without islands has one clutch-linked part. A clutch "
           "end counts as supported when most garment faces under its anchors are reinforced.", ""]
    md += ["## Performance", ""] + performance_rows(doc) + [""]
    return "\n".join(md)


def compact_images(folder: Path) -> None:
    """Re-save the PNGs in ``folder`` with a 256-colour palette (renders and plots lose
    nothing visible; files shrink ~4x, which keeps the committed report small)."""
    from PIL import Image

    for p in sorted(Path(folder).glob("*.png")):
        with Image.open(p) as im:
            if im.mode == "P":
                continue
            q = im.convert("RGBA").quantize(colors=256, method=Image.Quantize.FASTOCTREE)
        q.save(p, optimize=True)


def _data_uri(path: Path) -> str:
    import base64

    return "data:image/png;base64," + base64.b64encode(path.read_bytes()).decode("ascii")


def markdown_to_html(md: str, title: str, base: Path | None = None) -> str:
    """The report's Markdown as an HTML page (Python-Markdown with its tables extension).
    With ``base``, images found under it are embedded (data URIs): one self-contained file."""
    import re

    import markdown

    lines = md.splitlines()
    # GitHub-style Markdown starts a list right after a paragraph line; Python-Markdown
    # wants a blank line first
    fixed = [ln for i, line in enumerate(lines)
             for ln in (([""] if line.startswith("- ") and i and lines[i - 1].strip()
                         and not lines[i - 1].startswith("- ") else []) + [line])]
    body = markdown.markdown("\n".join(fixed), extensions=["tables"], output_format="html")

    def embed(m) -> str:
        src = html.unescape(m.group(1))
        if base is not None and (Path(base) / src).is_file():
            return f'src="{_data_uri(Path(base) / src)}"'
        return m.group(0)

    body = re.sub(r'src="([^"]+)"', embed, body)
    style = ("body{font-family:sans-serif;max-width:1100px;margin:2em auto;line-height:1.4}"
             "table{border-collapse:collapse;margin:0.5em 0}td,th{border:1px solid #ccc;padding:2px 6px;"
             "font-size:90%}img{max-width:32%;vertical-align:top}")
    return (f"<!DOCTYPE html><html><head><meta charset='utf-8'><title>{html.escape(title)}</title>"
            f"<style>{style}</style></head><body>\n{body}\n</body></html>\n")


def write_report(out: Path, doc: dict | None = None) -> tuple[Path, Path]:
    """Write ``out/report.md`` (images under ``out/img``) and the self-contained
    ``out/report.html`` (images embedded) from
    ``out/data.json`` (or ``doc``).  Returns both paths."""
    out = Path(out)
    doc = doc if doc is not None else json.loads((out / DATA).read_text())
    for e in doc["experiments"].values():  # the objective once the budget is reached, from the run
        run = e.get("run", {})
        metrics = Path(run.get("folder", "")) / "metrics.json"
        if "objectives_at_target" not in run and metrics.is_file():  # data.json from before 2026-11-25
            run["objectives_at_target"] = objectives_at_target(json.loads(metrics.read_text()), e["budget"])
    figures = {}
    if doc["experiments"]:
        figures["rho_bars"] = rho_bars(out / "img" / "rho_on.png", doc)
    fig = emergent_figure(out / "img" / "emergent.png", doc, out)
    if fig:
        figures["emergent"] = fig
    compact_images(out / "img")
    md = build_markdown(doc, figures)
    (out / "report.md").write_text(md)
    (out / "report.html").write_text(markdown_to_html(md, "kgarment: reproduction of the paper", base=out))
    return out / "report.md", out / "report.html"


def balance_note(e: dict) -> str:
    """The report's words for an experiment's ``[design] balance`` ("" without one)."""
    b = e.get("balance") or 0.0
    if not b:
        return ""
    where = f"{b:g}" if isinstance(b, (int, float)) else ", ".join(f"{w:g} in {m}" for m, w in b.items())
    return f", clutch balance {where} (`[design] balance`: every clutch's own load path rewarded)"


def _table_note(e: dict, key: str, item, words: str) -> str:
    """The report's words for an experiment's ``[design] KEY`` table of motions ("" without
    one): ``words`` with {} the items, each ``item(motion, value)``."""
    table = e.get(key) or {}
    return words.format(", ".join(item(m, v) for m, v in table.items())) if table else ""


def early_note(e: dict) -> str:
    """The report's words for an experiment's ``[design] early`` poses ("" without any)."""
    return _table_note(e, "early", lambda m, t: f"{m} at {t:g} of its movement",
                       ", also designed for the beginning of a motion (`[design] early`: {})")


def weights_note(e: dict) -> str:
    """The report's words for an experiment's ``[design] weights`` ("" without any)."""
    return _table_note(e, "weights", lambda m, w: f"{m} {w:g}",
                       ", motions weighted in the objective (`[design] weights`: {}; the others 1)")
