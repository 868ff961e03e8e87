"""One design for a size range against one design per size: ``kgarment sizes``.

For a multi-body problem (``[body] phenotypes``, :mod:`kgarment.case.wearers`) this runs
the shared design (``OUT/runs/all``) and, for every wearer, the same problem on that body
alone (``OUT/runs/<wearer>``): ordinary run folders, resumed where they stopped and
reused when finished.  It then compares, per wearer and motion, what the shared design
keeps of the wearer's own design (rho ON of the shared design on that body over rho ON of
the design made for it), with the clutch loads and the structural properties of each, and
writes ``sizes.json``, ``sizes.md`` and ``sizes.png``.  The target of the size range:
the shared design keeps at least :data:`KEEP` of every own design's rho ON.
"""

from __future__ import annotations

import logging
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from kgarment.case.wearers import split_key, wearer_key, wearer_problem
from kgarment.design.driver import finish, open_run
from kgarment.design.run import run_status
from kgarment.errors import KgarmentError
from kgarment.io import atomic_write_text, check_kind, json_text, make_folder, read_json_object
from kgarment.problem import Problem, load_problem

log = logging.getLogger(__name__)
KEEP = 0.80  # the shared design keeps at least this share of each own design's rho ON
SHARED = "all"  # the shared design's run folder under OUT/runs


@dataclass(frozen=True)
class SizeRow:
    """One wearer and motion: rho ON / OFF of the design made for this wearer alone (own)
    and of the shared design on this wearer (shared); kept = shared ON / own ON."""

    wearer: str
    motion: str
    own_on: float
    own_off: float
    shared_on: float
    shared_off: float

    @property
    def kept(self) -> float:
        return self.shared_on / self.own_on if self.own_on > 0 else float("nan")

    def row(self) -> dict:
        return {"wearer": self.wearer, "motion": self.motion, "own": {"on": self.own_on, "off": self.own_off},
                "shared": {"on": self.shared_on, "off": self.shared_off}, "kept": self.kept}


def run_sizes(problem: Problem, out, *, device: str = "cpu", force: bool = False,
              progress: Callable[[str], Callable] | None = None) -> dict:
    """Run (or resume, or reuse) the shared design and every wearer's own design of
    ``problem`` in ``out/runs``, then write the comparison; returns its JSON document.

    progress(name) -> a callback per iteration (the CLI's progress bar), or None."""
    names = problem.body.names
    if not names:
        raise KgarmentError("kgarment sizes needs a multi-body problem: [body] phenotypes = [{name = ...}, ...] "
                            "(e.g. the example shirt_sizes)")
    out = check_kind(out, "sizes", legacy=("sizes.json", "runs"))
    runs = out / "runs"
    jobs = [(SHARED, problem)] + [(n, wearer_problem(problem, n)) for n in names]
    if not force:  # before any work: a kept run of another problem is never reported as this one's
        for name, p in jobs:
            if run_status(runs / name) != "new":
                _check_same(p, runs / name)
    (make_folder(out, "sizes") / "runs").mkdir(exist_ok=True)
    for name, p in jobs:
        _design(p, runs / name, device, force, None if progress is None else progress(name))
    doc = compare(runs, names, list(problem.motions))
    atomic_write_text(out / "sizes.json", json_text(doc))
    atomic_write_text(out / "sizes.md", sizes_markdown(doc))
    sizes_plot(doc, out / "sizes.png")
    return doc


def _design(problem: Problem, folder: Path, device: str, force: bool, progress) -> None:
    status = "new" if force else run_status(folder)
    if status == "finished":
        log.info("%s: finished, reused", folder)
        return
    dr = open_run(None if status == "unfinished" else problem, folder, resume=status == "unfinished",
                  force=force, device=device)
    finish(dr, progress=progress)


def _check_same(problem: Problem, folder: Path) -> None:
    """A kept run (finished or not) must have been made for ``problem``: the same body,
    motions, garment, clutches, materials, design and solver settings, else one line."""
    old = load_problem(folder / "problem.toml")
    differ = [what for what in ("body", "motions", "garment", "materials", "design", "solver")
              if getattr(old, what) != getattr(problem, what)]
    if old.clutch_spec().hardware != problem.clutch_spec().hardware:
        differ.append("clutch hardware")
    if differ:
        raise KgarmentError(f"{folder} was designed for another problem (its {', '.join(differ)} differ); "
                            "use --force to design every size again, or give another --out")


def _evaluation(run: Path) -> dict:
    path = run / "final" / "evaluation.json"
    if not path.is_file():
        raise KgarmentError(f"{run} has no final evaluation; run kgarment evaluate {run} --json ... or resume it")
    try:
        return read_json_object(path, "final evaluation", ("rho",))
    except KgarmentError as exc:
        raise KgarmentError(f"{exc}; run kgarment evaluate {run} --json ... or design it again (--force)") from None


def _properties(ev: dict, motions: list[str], wearer: str | None = None) -> dict:
    """The structural properties and clutch loads of an evaluation, for ``motions`` keys
    (``wearer``: a multi-body evaluation's, on that wearer's body)."""
    shape = ev.get("by_wearer", {}).get(wearer) or ev
    loads = {}
    for c in ev.get("clutches", []):
        if c["motion"] in motions:
            loads.setdefault(c["clutch"], {})[c["motion"]] = {k: c.get(k) for k in ("share", "needed", "tension_N",
                                                                                  "loaded")}
    return {"parts": shape["islands_with_clutches"], "clutch_ends_supported": shape["clutch_ends_supported"],
            "clutch_ends": shape["clutch_ends"], "area": ev["area"], "clutches": loads}


def compare(runs: Path, names, motions: list[str]) -> dict:
    """The comparison document of finished runs ``runs/all`` and ``runs/<wearer>``."""
    shared = _evaluation(runs / SHARED)
    rows, wearers = [], {}
    for n in names:
        own = _evaluation(runs / n)
        keys = [wearer_key(m, n) for m in motions]
        for m, k in zip(motions, keys):
            rows.append(SizeRow(n, m, own["rho"][m]["on"], own["rho"][m]["off"], shared["rho"][k]["on"],
                                shared["rho"][k]["off"]))
        wearers[n] = {"own": _properties(own, motions), "shared": _properties(shared, keys, n)}
    kept = [r.kept for r in rows]
    return {"keep_target": KEEP, "keeps": bool(all(k >= KEEP for k in kept)), "min_kept": min(kept),
            "rows": [r.row() for r in rows], "wearers": wearers,
            "shared": {"iteration": shared["iteration"], "parts": shared["islands_with_clutches"],
                       "clutch_ends_supported": shared["clutch_ends_supported"], "clutch_ends": shared["clutch_ends"],
                       "area": shared["area"]}}


def sizes_markdown(doc: dict) -> str:
    """``sizes.md``: the comparison table, the target and the clutch loads per wearer."""
    s = doc["shared"]
    lines = ["# One design for every size against one design per size", "",
             (f"Shared design (runs/{SHARED}, iteration {s['iteration']}): {s['parts']} part(s) counting clutches as "
             f"links, {s['clutch_ends_supported']}/{s['clutch_ends']} clutch ends on reinforcement over the wearers, "
             f"{100 * s['area']:.1f}% of the area reinforced."), "",
             "| wearer | motion | own rho ON | own rho OFF | shared rho ON | shared rho OFF | kept |",
             "|---|---|---|---|---|---|---|"]
    for r in doc["rows"]:
        lines.append(f"| {r['wearer']} | {r['motion']} | {r['own']['on']:.2f} | {r['own']['off']:.3f} | "
                     f"{r['shared']['on']:.2f} | {r['shared']['off']:.3f} | {100 * r['kept']:.0f}% |")
    verdict = "met" if doc["keeps"] else "missed"
    lines += ["", (f"Target: the shared design keeps >= {100 * doc['keep_target']:.0f}% of every own design's rho ON: "
              f"**{verdict}** (lowest {100 * doc['min_kept']:.0f}%)."), "",
              "## Clutch loads (share / needed / tension N, ON)", ""]
    for n, w in doc["wearers"].items():
        for which in ("own", "shared"):
            p = w[which]
            lines.append(f"- {n}, {which} design: {p['parts']} part(s), {p['clutch_ends_supported']}/{p['clutch_ends']}"
                         " clutch ends supported; " + "; ".join(
                             f"{c}: " + ", ".join(f"{split_key(m)[0]} {v['share']:.2f}/{_f(v.get('needed'))}/"
                                                   f"{v['tension_N']:.0f} N" for m, v in per.items())
                             for c, per in p["clutches"].items()))
    return "\n".join(lines) + "\n"


def _f(v) -> str:
    return "n/a" if v is None else f"{v:.2f}"


def sizes_plot(doc: dict, path: Path) -> Path:
    """Grouped bars: rho ON of each wearer's own design and of the shared design, per motion."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import numpy as np

    rows = doc["rows"]
    labels = [f"{r['wearer']}\n{r['motion']}" for r in rows]
    x = np.arange(len(rows))
    fig, ax = plt.subplots(figsize=(max(6.0, 0.9 * len(rows)), 3.6), dpi=100)
    ax.bar(x - 0.2, [r["own"]["on"] for r in rows], 0.4, label="own design, ON")
    ax.bar(x + 0.2, [r["shared"]["on"] for r in rows], 0.4, label="shared design, ON")
    ax.plot(x + 0.2, [r["shared"]["off"] for r in rows], "k_", markersize=12, label="shared design, OFF")
    ax.set_xticks(x, labels, fontsize=7)
    ax.set_ylabel("relative energy density rho")
    ax.set_title("one design for every size against one design per size")
    ax.legend(fontsize=7)
    ax.grid(alpha=0.3, axis="y")
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)
    return path
