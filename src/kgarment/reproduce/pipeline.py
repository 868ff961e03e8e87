"""``kgarment reproduce``: every design experiment, the baselines, and the numbers behind the report.

For each experiment: our design (the ``active`` objective), the compliance baseline
(a second design run, ON states only), the manual, fully reinforced and random baselines at
the same budget, all evaluated by one :class:`~kgarment.reproduce.evaluate.Evaluator`
with clutches ON and OFF.  For the sleeve and the three-motion shirt, every design of the
group is also evaluated on the multi-motion problem (the paper's Table 1).  Everything
lands in ``OUT/data.json`` (its summary in ``OUT/results.json``, :func:`summary`); runs and
evaluations are reused when ``reproduce`` runs
again, so an interrupted run continues.  ``data.json`` accumulates: experiments run into the
same folder by earlier invocations (``--experiments``) are kept, so a reproduction too long
for one sitting is done a few experiments at a time (:func:`previous_results`,
:func:`run_again`), and it is
written after every experiment, so one that finished is never lost.
"""

from __future__ import annotations

import json
import logging
import resource
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np

from kgarment.case.values import design_values
from kgarment.constants import SIM_MODEL
from kgarment.design.run import other_model
from kgarment.errors import KgarmentError
from kgarment.io import atomic_write_text, json_text, make_folder, time_left
from kgarment.render import faces_near, render_design
from kgarment.reproduce.baselines import anchor_rings, manual_design, random_design
from kgarment.reproduce.catalog import objectives_at_target
from kgarment.reproduce.evaluate import CachedEvaluator, EvaluationCache
from kgarment.reproduce.experiments import (
    BY_NAME,
    DATA,
    MULTI_OF_GROUP,
    RESOLUTIONS,
    Experiment,
    all_on_problem,
    design_run,
    experiment_problem,
    select,
)
from kgarment.reproduce.figures import force_figure
from kgarment.reproduce.targets import target_flags
from kgarment.reproduce.validation import sensor_rows

log = logging.getLogger(__name__)
PLAN_CLUTCHES = 3  # multi-motion experiments with at most this many clutches get their clutch-set table
PATH_DESIGNS = ("ours", "manual", "full")  # designs whose force over the motion the report draws
LOADED = ("ours", "manual")  # designs evaluated with clutch loads
# with paths, the designs whose rho the report gives over the motion from rest (its end a start,
# kept where lower): the table's rows side by side measure the same thing (until 2026-11-30 the last
# iteration and the compliance design were read from the two starts only, beside ours over the
# motion: the selective sleeve's iteration 126 read 1.08 there and 0.70 over the motion)
PATH_EVALUATED = ("ours", "ours_last", "manual", "compliance")


def _render_design(path: Path, ev: CachedEvaluator, design: np.ndarray, title: str) -> str:
    g = ev.garment
    bv = ev.body.rest_vertices
    bf = faces_near(bv, ev.body.faces, g.rest_vertices)  # frame the garment, not the body
    render_design(path, bv, bf, g.rest_vertices, g.faces, design, clutches=[(c.vertices, c.faces) for c in ev.strips],
                  title=title, height_px=260)
    return path.name


def _run_summary(outcome) -> dict:
    rows = outcome.metrics
    n = max(len(rows), 1)
    return {"folder": str(outcome.run), "iterations": len(rows), "seconds": outcome.seconds,
            "reported_iteration": outcome.iteration,
            "seconds_per_iteration": outcome.seconds / n,
            "newton_per_iteration": float(np.mean([r["newton_iterations"] for r in rows])) if rows else 0.0,
            "unconverged_iterations": int(sum(1 for r in rows if r["unconverged_states"]))}


def run_experiment(exp: Experiment, res, out: Path, cache: EvaluationCache, device: str,
                   progress: Callable | None, overrides: dict | None = None) -> dict:
    """Designs, baselines and evaluations of one experiment -> its results entry."""
    img = out / "img"
    t0 = time.time()
    problem = experiment_problem(exp, res, overrides=overrides)
    ev = CachedEvaluator(problem, f"{exp.name}@{res.name}", cache, device)
    # ours ends as kgarment design does (the best iteration the evaluator reproduces), in the shared store
    ours = design_run(problem, out / "runs" / exp.name, device, progress, evaluator=ev.evaluator,
                      path_frames=res.path_frames)
    comp = design_run(experiment_problem(exp, res, "compliance", overrides), out / "runs" / f"{exp.name}-compliance",
                      device, progress)
    # activation sets: the same problem designed with every clutch ON, the selective target's comparison
    all_on = design_run(all_on_problem(problem), out / "runs" / f"{exp.name}-all-on", device,
                        progress) if problem.activation else None
    phases: dict[str, float] = {}  # wall seconds per phase in this session (reused work: ~0)

    def lap(phase: str) -> None:  # the time since the last phase ended is this one's
        phases[phase] = time.time() - t0 - sum(phases.values())

    lap("designs")
    budget = problem.design.beso.target_area
    g = ev.garment
    designs = {
        "ours": ours.design,
        "ours_last": ours.last,
        "compliance": comp.design,
        "manual": _manual(ev, budget),
        "full": np.ones(g.n_faces),
        **({"all_on": all_on.design} if all_on else {}),
    }
    entry = {"name": exp.name, "title": exp.title, "group": exp.group, "multi": exp.multi,
             "preset": problem.materials.preset, "clutch_model": problem.clutch_spec().hardware.model,
             "clutch_buckle": problem.clutch_spec().hardware.buckle, "skin_friction": problem.materials.skin_friction,
             "clutch_channel": problem.clutch_spec().hardware.channel,
             "paper": {m: list(v) for m, v in exp.paper.items()}, "budget": budget,
             "garment": g.name, "faces": int(g.n_faces), "clutches": len(ev.strips), "motions": ev.motions,
             "states": ev.n_states, "run": _run_summary(ours), "compliance_run": _run_summary(comp),
             "activation": {m: dict(v) for m, v in problem.activation}, "lockout": problem.design.lockout,
             "balance": problem.design.flat().get("balance", 0.0), "early": dict(problem.design.early),
             "weights": dict(problem.design.weights), "evaluations": {}, "images": {}}
    if all_on:
        entry["all_on_run"] = _run_summary(all_on)
    paths = {}
    for kind, d in designs.items():
        if kind == "all_on":  # judged by its clutch-set table below
            continue
        log.info("%s: evaluating the %s design", exp.name, kind)
        if res.path_frames > 0 and kind in PATH_EVALUATED:  # the motion from rest first: its end competes
            entry["evaluations"][kind], paths[kind] = ev.evaluate_with_path(d, kind, res.path_frames,
                                                                            loads=kind in LOADED)
            continue
        # clutch loads where the report and the targets read them: ours against the manual baseline
        entry["evaluations"][kind] = ev.evaluate(d, kind, loads=kind in LOADED)
    lap("evaluations")
    if exp.multi and len(ev.strips) <= PLAN_CLUTCHES:
        entry["plan"] = ev.plan(ours.design, res.path_frames)
        if all_on:
            entry["plan_all_on"] = ev.plan(all_on.design, res.path_frames)
    lap("plan")
    if res.path_frames > 0:
        entry["path"] = {}
        for kind in PATH_DESIGNS:
            if kind in paths:  # ours and the manual baseline: solved before their evaluations
                entry["path"][kind] = paths[kind]
                continue
            log.info("%s: the force over the motion of the %s design (%d frames)", exp.name, kind, res.path_frames)
            entry["path"][kind] = ev.path(designs[kind], res.path_frames, kind)
        entry["images"]["force"] = _force_image(out, exp.name, entry["path"])
    lap("paths")
    entry["evaluations"]["random"] = _random_baselines(exp.name, ev, g, budget, res.seeds)
    lap("random")
    for kind in ("ours", "compliance", "manual", *(("all_on",) if all_on else ())):
        entry["images"][kind] = "img/" + _render_design(img / f"{exp.name}_{kind}.png", ev, designs[kind],
                                                        f"{exp.name}: {kind}")
    prog = ours.run / "progress.png"
    if prog.is_file():
        (img / f"{exp.name}_progress.png").write_bytes(prog.read_bytes())
        entry["images"]["progress"] = f"img/{exp.name}_progress.png"
    lap("renders")
    entry["run"]["objectives_at_target"] = objectives_at_target(ours.metrics, budget)
    entry["wall_seconds"] = sum(phases.values())
    entry["phase_seconds"] = phases
    log.info("%s: done in %.1f min (%s)", exp.name, entry["wall_seconds"] / 60,
             ", ".join(f"{k} {v / 60:.1f}" for k, v in phases.items()))
    np.savez_compressed(out / "designs" / f"{exp.name}.npz", **{k: v > 0.5 for k, v in designs.items()})
    return entry


def _manual(ev: CachedEvaluator, budget: float) -> np.ndarray:
    """(m,) the manual baseline (:func:`~kgarment.reproduce.baselines.manual_design`) of ``ev``'s problem."""
    g = ev.garment
    return manual_design(g.rest_vertices, g.faces, ev.case.end_faces, *anchor_rings(g, ev.body), budget)


def _force_image(out: Path, name: str, paths: dict) -> str:
    """The experiment's force-over-the-motion figure of ``paths`` ({design: path JSON}), its report link."""
    return "img/" + force_figure(out / "img" / f"{name}_force.png", paths, f"{name}: force over the motion").name


def refresh_manual(entry: dict, exp: Experiment, res, out: Path, cache: EvaluationCache, device: str,
                   overrides: dict | None = None) -> bool:
    """A kept experiment (its data.json ``entry``, updated in place) whose manual baseline
    today's rule (:func:`~kgarment.reproduce.baselines.manual_design`) draws differently
    from the one in ``designs/<name>.npz``: today's is evaluated as :func:`run_experiment`
    evaluates it (clutch loads, the force over the motion), rendered and stored, so a report
    kept from an earlier invocation shows the baseline of today's code.  Returns whether it
    changed (False without the stored designs: nothing to compare)."""
    npz = out / "designs" / f"{exp.name}.npz"
    if not npz.is_file() or "manual" not in entry.get("evaluations", {}):
        return False
    problem = experiment_problem(exp, res, overrides=overrides)
    ev = CachedEvaluator(problem, f"{exp.name}@{res.name}", cache, device)
    manual = _manual(ev, problem.design.beso.target_area)
    with np.load(npz) as z:
        stored = {k: z[k] for k in z.files}
    if np.array_equal(stored.get("manual"), manual > 0.5):
        return False
    log.info("%s: the manual baseline's rule has changed since it was evaluated; evaluating today's", exp.name)
    t0 = time.time()
    if res.path_frames > 0 and "manual" in (entry.get("path") or {}):
        entry["evaluations"]["manual"], entry["path"]["manual"] = ev.evaluate_with_path(manual, "manual",
                                                                                         res.path_frames)
        entry["images"]["force"] = _force_image(out, exp.name, entry["path"])
    else:
        entry["evaluations"]["manual"] = ev.evaluate(manual, "manual", loads=True)
    entry["images"]["manual"] = "img/" + _render_design(out / "img" / f"{exp.name}_manual.png", ev, manual,
                                                        f"{exp.name}: manual")
    np.savez_compressed(npz, **{**stored, "manual": manual > 0.5})
    phases = entry.setdefault("phase_seconds", {})
    phases["manual again"] = phases.get("manual again", 0.0) + time.time() - t0
    entry["wall_seconds"] = sum(phases.values())
    return True


def cross_evaluate(group: str, results: dict, res, out: Path, cache: EvaluationCache, device: str,
                   overrides: dict | None = None) -> dict | None:
    """The group's designs evaluated on its multi-motion problem: rows = motions evaluated
    on, columns = the motion each design was optimised for, and "all" (the multi design)."""
    multi = MULTI_OF_GROUP.get(group)
    if multi is None or multi not in results:
        return None
    singles = [e for e in results.values() if e["group"] == group and not e["multi"]
               and (out / "designs" / f"{e['name']}.npz").is_file()]
    if not singles:
        return None
    ev = CachedEvaluator(experiment_problem(BY_NAME[multi], res, overrides=overrides), f"{multi}@{res.name}", cache, device)
    columns = {}
    for e in singles:
        with np.load(out / "designs" / f"{e['name']}.npz") as z:
            design = design_values(z["ours"])
        (motion,) = e["motions"]
        label = f"{e['name']} on {multi}"  # the motion from rest competing, as in the multi design's column
        columns[motion] = (ev.evaluate_with_path(design, label, res.path_frames, loads=False)[0] if res.path_frames
                           else ev.evaluate(design, label))["rho"]
    columns["all"] = results[multi]["evaluations"]["ours"]["rho"]
    return {"problem": multi, "motions": ev.motions,
            "rho_on": {row: {col: columns[col][row]["on"] for col in columns} for row in ev.motions},
            "rho_off": {row: {col: columns[col][row]["off"] for col in columns} for row in ev.motions}}


def reproduce(out: Path, resolution: str = "preview", experiments: str | None = None, device: str = "cpu",
              progress: Callable | None = None, overrides: dict | None = None) -> dict:
    """Run the selected experiments at ``resolution`` (with the material ``preset``, default:
    the example files', ``paper``) into ``out``; returns (and writes
    ``out/data.json``, summarised in ``out/results.json``) everything the report shows.
    The clutch strips are the paper's unless ``overrides`` says ``buckle``
    (:func:`kgarment.reproduce.experiments.experiment_problem`)."""
    res = RESOLUTIONS[resolution]
    exps = select(experiments)
    out = make_folder(out, "reproduction")  # marked when kgarment makes it (never a folder the user had filled)
    for sub in ("runs", "img", "designs"):
        (out / sub).mkdir(parents=True, exist_ok=True)
    cache = EvaluationCache(out / "evaluations.json")
    t0 = time.time()
    old = previous_results(out, res, overrides)
    results: dict = {}
    asked = {e.name for e in exps}

    def write_so_far() -> None:  # an experiment finished is never lost; the cross-evaluations follow at the end
        done = {n: results[n] if n in results else old[n] for n in BY_NAME if n in results or n in old}
        _write(out, _document(res, done, {}, t0, device))

    for exp in select(None):  # the canonical order, earlier invocations' experiments included
        if exp.name in asked and run_again(exp.name, bool(experiments), old, out):
            log.info("experiment %s (%s resolution)", exp.name, res.name)
            before = continued(exp.name, old, out)  # before the run creates its folder
            results[exp.name] = _add_times(run_experiment(exp, res, out, cache, device, progress, overrides),
                                           before)
            write_so_far()
        elif exp.name in old:
            log.info("experiment %s: kept from %s", exp.name, out / DATA)
            results[exp.name] = old[exp.name]
            if exp.name in asked and refresh_manual(results[exp.name], exp, res, out, cache, device, overrides):
                write_so_far()
    cross = {}
    for group in ("sleeve", "shirt"):
        m = cross_evaluate(group, results, res, out, cache, device, overrides)
        if m is not None:
            cross[group] = m
    doc = _document(res, results, cross, t0, device)
    _write(out, doc)
    return doc


def run_again(name: str, named: bool, old: dict, out: Path) -> bool:
    """Whether ``reproduce`` runs experiment ``name`` (reusing what its folder holds): yes when
    ``named`` in --experiments, when ``old`` (data.json's entries) lacks it, or when its run
    folder is there; an entry whose run folders are not (a committed report) is kept as it is,
    since running it again would redo its designs."""
    return named or name not in old or _has_runs(out, name)


def _has_runs(out: Path, name: str) -> bool:
    """Whether experiment ``name``'s run folder is in ``out``."""
    return (Path(out) / "runs" / name).is_dir()


def continued(name: str, old: dict, out: Path) -> dict | None:
    """The data.json entry (of ``old``) that running experiment ``name`` again continues: the
    entry when its run folder is there (the rerun reuses those runs, so their time counts),
    None when it is not (a committed report after a fresh clone: the experiment starts afresh
    and replaces the entry, its earlier time is not this run's)."""
    return old.get(name) if _has_runs(out, name) else None


def _add_times(entry: dict, before: dict | None) -> dict:
    """``entry`` with the wall seconds of each phase spent on it by earlier invocations
    (``before``, its data.json entry, when the run continues that entry's run folders) added:
    a run again that reuses everything costs ~0 s and must not hide what the experiment took."""
    if before and before.get("phase_seconds"):
        for k, v in before["phase_seconds"].items():
            entry["phase_seconds"][k] = entry["phase_seconds"].get(k, 0.0) + v
        entry["wall_seconds"] = sum(entry["phase_seconds"].values())
    return entry


def _document(res, results: dict, cross: dict, t0: float, device: str) -> dict:
    """data.json's document from the experiments' entries and the cross-evaluations."""
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024  # this process; workers are alike
    presets = sorted({e["preset"] for e in results.values()})
    return {"resolution": res.__dict__, "sim_model": SIM_MODEL, "preset": ", ".join(presets),
            "clutch_model": ", ".join(sorted({e.get("clutch_model", "locked") for e in results.values()})),
            "experiments": results, "cross": cross,
            "wall_seconds": time.time() - t0, "peak_rss_mb": peak, "device": device}


def _write(out: Path, doc: dict) -> None:
    atomic_write_text(out / DATA, json.dumps(doc, indent=1))
    atomic_write_text(out / "results.json", json_text(summary(doc)))  # strict JSON: NaN -> null


def rewrite_summary(out: Path, doc: dict) -> Path:
    """``out/results.json`` written again from ``doc`` (``out/data.json``, ``--report-only``)."""
    return atomic_write_text(Path(out) / "results.json", json_text(summary(doc)))


def previous_results(out: Path, res, overrides: dict | None) -> dict:
    """{name: entry} of ``out/data.json``'s experiments, when they were
    made at resolution ``res`` with the material preset and clutch model that ``overrides``
    give them now (else :class:`KgarmentError`: mixing them would make one report of two
    reproductions); {} without a data.json."""
    path = Path(out) / DATA
    if not path.is_file():
        return {}
    try:
        doc = json.loads(path.read_text())
        old_res, old = doc["resolution"]["name"], doc["experiments"]
    except (ValueError, KeyError, TypeError) as err:
        raise KgarmentError(f"{path} is not a reproduction's data ({err}); give another --out") from None
    if old_res != res.name:
        raise KgarmentError(f"{path} holds a {old_res}-resolution reproduction, not {res.name}; give another --out")
    then = doc.get("sim_model", 1)  # reports before the model's version was recorded: 1
    if then != SIM_MODEL:
        raise KgarmentError(f"{path} was made with {other_model(then)}; one report would mix the two: "
                            "give another --out")
    kept = {}
    for name, e in old.items():
        if name not in BY_NAME:
            continue
        p = experiment_problem(BY_NAME[name], res, overrides=overrides)
        hw = p.clutch_spec().hardware
        now = (p.materials.preset, hw.model, hw.buckle, p.materials.skin_friction, hw.channel)
        then = (e.get("preset", "paper"), e.get("clutch_model", "locked"), bool(e.get("clutch_buckle", False)),
                float(e.get("skin_friction", 0.0)), bool(e.get("clutch_channel", False)))
        if now != then:
            raise KgarmentError(f"{path}: {name} was made with {_setting(then)}, not {_setting(now)}; "
                                "give another --out")
        kept[name] = e
    return kept


def _setting(preset_model_buckle_friction_channel: tuple) -> str:
    """'preset paper, clutch model locked' (and ', buckling clutch strips', ', skin friction
    0.4', ', clutches in channels') for an error line."""
    preset, model, buckle, mu, channel = preset_model_buckle_friction_channel
    return (f"preset {preset}, clutch model {model}" + (", buckling clutch strips" if buckle else "")
            + (f", skin friction {mu:g}" if mu else "") + (", clutches in channels" if channel else ""))


def _design_summary(ev: dict) -> dict:
    """One design's entry of results.json (the issue's schema)."""
    clutches: dict = {}
    for c in ev.get("clutches", []):
        entry = clutches.setdefault(c["clutch"], {"share": {}, "needed": {}, "tension_N": {}})
        entry["share"][c["motion"]] = c["share"]
        entry["needed"][c["motion"]] = c.get("needed", float("nan"))
        entry["tension_N"][c["motion"]] = c["tension_N"]
    return {"rho": ev["rho"], "parts": ev["islands_with_clutches"], "clutch_ends_supported": ev["clutch_ends_supported"],
            "clutch_ends": ev["clutch_ends"], "clutches": clutches}


def summary(doc: dict) -> dict:
    """The machine-readable results (``results.json``): per experiment our design and the
    manual baseline (rho per motion ON/OFF, parts counting clutch links, clutch ends on
    reinforcement, per clutch share and tension per motion), the targets met, and the
    tensions at the paper's force sensor (:func:`kgarment.reproduce.validation.sensor_rows`)."""
    exps = {name: {kind: _design_summary(e["evaluations"][kind]) for kind in ("ours", "manual")
                   if kind in e["evaluations"]} for name, e in doc["experiments"].items()}
    return {"resolution": doc["resolution"]["name"], "preset": doc.get("preset", "paper"), "experiments": exps,
            "targets": target_flags(doc), "sensor": sensor_rows(doc)}


def _random_baselines(name: str, ev: CachedEvaluator, g, budget: float, seeds: int) -> list[dict]:
    """The evaluations of the random designs of seeds 0 .. ``seeds`` - 1 (``g``: the
    garment; ``budget``: their reinforced share of its area), one progress line before each
    with the time so far and an estimate of what is left (at the default resolution the
    random baselines were the longest part of the shirts' experiments, 43-76 minutes each in the
    default report of simulation model 1)."""
    out, t0 = [], time.perf_counter()
    for seed in range(seeds):
        spent = time.perf_counter() - t0
        eta = f" ({time_left(spent, seed, seeds)})" if seed else ""
        log.info("%s: evaluating random design %d/%d%s", name, seed + 1, seeds, eta)
        out.append(ev.evaluate(random_design(g.rest_vertices, g.faces, budget, seed), f"random {seed}"))
    return out
