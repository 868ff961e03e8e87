"""kgarment reproduce: the baselines' geometry, and a tiny end-to-end run with its report."""

from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np
import pytest
from cli_runner import run_cli

from kgarment.case.starts import MULTISTABLE
from kgarment.garment.topology import triangle_areas
from kgarment.reproduce.baselines import manual_design, random_design


def grid(n: int = 20, size: float = 0.2):
    """A flat n x n square sheet of 2 n^2 triangles, size metres wide, z = 0."""
    xs = np.linspace(0.0, size, n + 1)
    X, Y = np.meshgrid(xs, xs, indexing="ij")
    v = np.stack([X.ravel(), Y.ravel(), np.zeros(X.size)], 1)
    idx = np.arange((n + 1) ** 2).reshape(n + 1, n + 1)
    a, b, c, d = idx[:-1, :-1].ravel(), idx[1:, :-1].ravel(), idx[1:, 1:].ravel(), idx[:-1, 1:].ravel()
    f = np.concatenate([np.stack([a, b, c], 1), np.stack([a, c, d], 1)])
    return v, f


def faces_near(v, f, p, r):
    c = v[f].mean(1)
    return np.flatnonzero(np.linalg.norm(c - p, axis=1) < r)


def test_manual_strip_runs_straight_to_the_nearest_attachment():
    v, f = grid()
    areas = triangle_areas(v, f)
    c = v[f].mean(1)
    held = c[:, 0] < 0.01  # the left edge is an attachment ring
    end = faces_near(v, f, np.array([0.15, 0.1, 0.0]), 0.008)
    far_end = faces_near(v, f, np.array([0.19, 0.1, 0.0]), 0.008)
    d = manual_design(v, f, [(end, far_end)], [], held, budget=0.06) > 0.5
    on = c[d]
    # the strip from the nearer end goes left along y = 0.1 to the attachment at x = 0
    assert on[:, 0].min() < 0.01 and np.all(np.abs(on[:, 1] - 0.1) < 0.03)
    assert d[end].all()
    assert abs(areas[d].sum() / areas.sum() - 0.06) <= areas.max() / areas.sum()


def test_limb_bands_close_around_the_upper_arms_of_a_long_sleeve_only(anny_body):
    """A long sleeve is held at the wrists, so a designer bands the upper arms: one band per
    arm across the middle of the upper arm, closing around it (taking its faces out cuts the
    sleeve from the shirt: the cuff is no longer joined to the hem). The short sleeves' cuffs
    and the arm sleeve's attached ring already hold their upper arms: no band there."""
    import dataclasses

    from scipy.sparse.csgraph import connected_components

    from kgarment.garment import make_garment
    from kgarment.garment.topology import face_adjacency
    from kgarment.reproduce.baselines import BAND_WIDTH, anchor_rings

    g = make_garment(anny_body, "long_sleeve_shirt", 0)
    plain, _ = anchor_rings(g)
    rings, held = anchor_rings(g, anny_body)
    assert plain == [] and len(rings) == 2 and held.any()
    names = list(anny_body.bone_names)
    adj = face_adjacency(g.faces).tocsr()
    hem = np.flatnonzero(np.isin(g.faces, g.loops["hem"]).any(axis=1))
    centre = g.rest_vertices[g.faces].mean(axis=1)
    for side in "LR":
        p0 = anny_body.rest_joints[names.index(f"upperarm01.{side}")]
        p1 = anny_body.rest_joints[names.index(f"lowerarm01.{side}")]
        cuff = np.flatnonzero(np.isin(g.faces, g.loops[f"cuff.{side}"]).any(axis=1))
        near = [b for b in rings if np.linalg.norm(centre[b].mean(0) - (p0 + p1) / 2) < 0.1]
        assert len(near) == 1
        band = near[0]
        along = (centre[band] - p0) @ (p1 - p0) / np.linalg.norm(p1 - p0)
        assert np.all(np.abs(along - np.linalg.norm(p1 - p0) / 2) <= BAND_WIDTH / 2)
        keep = np.setdiff1d(np.arange(len(g.faces)), band)
        _, label = connected_components(adj[keep][:, keep], directed=False)
        where = np.full(len(g.faces), -1)
        where[keep] = label
        assert not np.isin(where[cuff], where[hem]).any()  # the band cuts the sleeve through
    for name in ("short_sleeve_shirt", "arm_sleeve.right"):
        other = make_garment(anny_body, name, 0)
        assert [len(r) for r in anchor_rings(other, anny_body)[0]] == [len(r) for r in anchor_rings(other)[0]]
    unrigged = dataclasses.replace(anny_body, bone_names=())
    assert anchor_rings(g, unrigged)[0] == []


def test_manual_strips_reach_a_free_ring_never_their_own_clutch():
    """A clutch across the middle of a sheet whose top edge is a free opening (a cuff): both
    ends run to the ring, which is drawn all along; neither end's strip ends on the other's."""
    v, f = grid()
    c = v[f].mean(1)
    ring = np.flatnonzero(c[:, 1] > 0.19)
    a = faces_near(v, f, np.array([0.08, 0.12, 0.0]), 0.008)
    b = faces_near(v, f, np.array([0.12, 0.12, 0.0]), 0.008)
    d = manual_design(v, f, [(a, b)], [ring], np.zeros(len(f), bool), budget=0.1) > 0.5
    assert d[ring].all() and d[a].all() and d[b].all()
    # below the ring: two strips, one from each end, not one joining the ends
    from kgarment.evaluate.metrics import islands

    below = d & (c[:, 1] < 0.19)
    assert islands(f, below) == 2


def test_manual_strips_of_one_clutch_go_to_two_anchors():
    """A clutch near the left of a sheet held along its left and right edges: both ends are
    nearest the left edge, but a clutch strapped to one edge at both ends sits between two
    points nothing moves apart, so the second end's strip runs to the right edge."""
    v, f = grid()
    c = v[f].mean(1)
    held = (c[:, 0] < 0.01) | (c[:, 0] > 0.19)
    a = faces_near(v, f, np.array([0.05, 0.1, 0.0]), 0.008)
    b = faces_near(v, f, np.array([0.08, 0.1, 0.0]), 0.008)
    d = manual_design(v, f, [(a, b)], [], held, budget=0.06) > 0.5
    from kgarment.evaluate.metrics import islands

    assert islands(f, d) == 2  # two strips, joined only through the clutch
    left, right = d & (c[:, 0] < 0.01), d & (c[:, 0] > 0.19)
    assert left.any() and right.any()
    assert np.all(np.abs(c[d, 1] - 0.1) < 0.03)  # both straight along y = 0.1
    # with one anchor only there is nowhere else to go: both ends to it
    one = manual_design(v, f, [(a, b)], [], c[:, 0] < 0.01, budget=0.06) > 0.5
    assert not (one & (c[:, 0] > 0.19)).any()


def test_the_manual_baseline_loads_a_clutch_nearest_one_ring():
    """A tube held at its bottom ring and pulled 5% at its top, an 8 cm clutch near the bottom:
    with both ends strapped to the bottom ring (the nearest anchor of each) the clutch would
    carry nothing; the manual baseline takes its upper end to the top ring, so switching the
    clutch on carries the pull (share of the ON - OFF energy, docs/method/index.md, "Judging a design as a garment")."""
    from kgarment.case import Case
    from kgarment.evaluate import Evaluator
    from kgarment.sim import SolverOptions, build_model
    from kgarment.sim.synthetic import Tube

    tube = Tube(0.05, 0.0, 0.3, 48, 31)
    clutch = tube.clutch("low", 0.0, 0.04, 0.12, 0.01, 16)
    model = build_model(tube.vertices, tube.faces, [clutch], preset="paper")
    setup = Case.build(model, {"pull": tube.motion("pull", 0.05, 0.0)}, "active", SolverOptions(tol=1e-5, max_iter=300))
    held = np.zeros(len(tube.faces), bool)
    held[np.concatenate([tube.ring_faces(0), tube.ring_faces(tube.n_z - 2)])] = True
    design = manual_design(tube.vertices, tube.faces, setup.end_faces, [], held, budget=0.08)
    top = tube.ring_faces(tube.n_z - 2)
    assert (design[top] > 0.5).any() and (design[tube.ring_faces(0)] > 0.5).any()
    load = Evaluator(setup).evaluate(design, loads=True).loads.get("pull", "low")
    assert load.share > 0.5 and load.loaded


def test_manual_and_random_designs_spend_the_budget():
    v, f = grid()
    areas = triangle_areas(v, f)
    c = v[f].mean(1)
    held = c[:, 0] < 0.01
    ends = [(faces_near(v, f, np.array([0.1, 0.1, 0]), 0.008), faces_near(v, f, np.array([0.15, 0.15, 0]), 0.008))]
    one = areas.max() / areas.sum()
    for budget in (0.1, 0.25):
        d = manual_design(v, f, ends, [], held, budget)
        assert abs(areas[d > 0.5].sum() / areas.sum() - budget) <= one
        r = random_design(v, f, budget, seed=3)
        assert abs(areas[r > 0.5].sum() / areas.sum() - budget) <= one
    np.testing.assert_array_equal(random_design(v, f, 0.2, seed=1), random_design(v, f, 0.2, seed=1))
    assert (random_design(v, f, 0.2, seed=1) != random_design(v, f, 0.2, seed=2)).any()


def test_best_iteration_is_the_best_converged_one_at_the_target():
    from kgarment.design.run import best_iteration

    rows = [{"iteration": 0, "area": 1.0, "objective": 9.0, "unconverged_states": ""},
            {"iteration": 1, "area": 0.15, "objective": 2.0, "unconverged_states": ""},
            {"iteration": 2, "area": 0.15, "objective": 5.0, "unconverged_states": "a[on]"},
            {"iteration": 3, "area": 0.151, "objective": 3.0, "unconverged_states": ""},
            {"iteration": 4, "area": 0.15, "objective": 1.0, "unconverged_states": ""}]
    assert best_iteration(rows, 0.15, 0.015) == 3
    assert best_iteration(rows[:1], 0.15, 0.015) == 0  # none at the target: the last one


def _cli(args, cwd):
    return run_cli(["-q", *args], cwd)


def test_unknown_experiment_is_a_one_line_error(tmp_path):
    rc, out, err = _cli(["reproduce", "--experiments", "arm_flexion,moonwalk", "--out", "r"], tmp_path)
    assert rc == 2
    assert err.strip().count("\n") == 0 and "moonwalk" in err and "sleeve_two_motions" in err
    assert not (tmp_path / "r").exists()


@pytest.mark.timeout(900)
def test_reproduce_tiny_sleeve(tmp_path, anny_body):
    exps = "arm_extension,sleeve_two_motions"
    # one experiment at a time, as a reproduction too long for one sitting is done: the
    # second invocation keeps the first's experiment and cross-evaluates the two
    for k, name in enumerate(reversed(exps.split(","))):
        args = ["reproduce", "--resolution", "tiny", "--experiments", name, "--out", "rep"]
        rc, out, err = run_cli(args, tmp_path) if k == 0 else _cli(args, tmp_path)
        assert rc == 0, err
        if k == 0:  # the long phases say where they are (not quiet): each design's iterations as lines
            # (stdout is not a terminal here), each random design, each frame
            assert re.search(rf"^{name}: it +3 of ~\d+  area .* elapsed, ETA", out, re.MULTILINE), out
            assert re.search(rf"^{name}-compliance: it +3 of ~\d+  ", out, re.MULTILINE), out
            assert f"{name}: evaluating random design 1/2\n" in err
            assert f"{name}: evaluating random design 2/2 (" in err and "s to go)" in err
            assert "ours, the force over the motion: frame 2/2 (t = 1.00, " in err
    rep = tmp_path / "rep"
    doc = json.loads((rep / "data.json").read_text())
    assert list(doc["experiments"]) == exps.split(",")  # the canonical order
    for e in doc["experiments"].values():
        ev = e["evaluations"]
        assert set(ev) == {"ours", "ours_last", "compliance", "manual", "full", "random"}
        assert len(ev["random"]) == 2
        for m in e["motions"]:  # rho of the fully reinforced garment is 1 by definition
            assert ev["full"]["rho"][m]["on"] == pytest.approx(1.0, rel=1e-12)
            assert ev["full"]["rho"][m]["off"] == pytest.approx(1.0, rel=1e-12)
        for kind in ("manual", "random"):
            for r in ev[kind] if kind == "random" else [ev[kind]]:
                assert abs(r["area"] - e["budget"]) < 0.01
        # ours ends as kgarment design does: the reported iteration is the run's final one, which
        # the evaluator reproduces (or the best as evaluated), and its evaluation the same numbers
        folder = Path(e["run"]["folder"])
        final = json.loads(((folder if folder.is_absolute() else tmp_path / folder) / "final"
                            / "evaluation.json").read_text())
        assert e["run"]["reported_iteration"] == final["iteration"] == final["selection"]["iteration"]
        for r in ev["ours"]["rows"]:  # where the motion from rest did not end lower (the reproduction's --path)
            if not r["from_path"]:
                assert r["rho"] == pytest.approx(final["rho"][r["motion"]][r["state"]], rel=1e-9)
    # the designs of a report's table side by side are measured alike: with forces over the motion
    # (tiny: 2 frames) each of them is evaluated over the motion from rest (the random designs,
    # outside the comparison of rows, from the two starts only)
    from kgarment.reproduce.evaluate import design_key
    from kgarment.reproduce.pipeline import PATH_EVALUATED

    cached = json.loads((rep / "evaluations.json").read_text())
    for name in doc["experiments"]:
        designs = np.load(rep / "designs" / f"{name}.npz")
        for kind in PATH_EVALUATED:
            key = design_key(designs[kind])
            assert any(k.startswith(f"{name}@") and f"|{key}|" in k and k.endswith("|path2") for k in cached), kind
    cross = doc["cross"]["sleeve"]
    assert set(cross["rho_on"]) == {"arm_flexion.right", "arm_extension.right"}
    assert set(cross["rho_on"]["arm_flexion.right"]) == {"arm_extension.right", "all"}
    # the multi-motion design's column is its own evaluation
    assert cross["rho_on"]["arm_extension.right"]["all"] == pytest.approx(
        doc["experiments"]["sleeve_two_motions"]["evaluations"]["ours"]["rho"]["arm_extension.right"]["on"])
    # the machine-readable summary: per experiment ours and manual, and the targets
    summary = json.loads((rep / "results.json").read_text(), parse_constant=_not_json)  # strict: no NaN
    assert summary["resolution"] == "tiny" and set(summary["experiments"]) == set(exps.split(","))
    ext = summary["experiments"]["arm_extension"]["ours"]
    assert set(ext) == {"rho", "parts", "clutch_ends_supported", "clutch_ends", "clutches"}
    assert set(ext["clutches"]["elbow_inner.R"]) == {"share", "needed", "tension_N"}
    assert {"every_clutch_loaded", "clutch_ends_supported", "one_part", "single_on_off",
            "beats_manual"} <= set(summary["targets"])
    assert all(isinstance(v, bool) for v in summary["targets"].values())
    # the force over the motion: ours, manual and full, the rest pose and 2 frames ON and OFF
    # per motion; the work over the motion is the energy at the target less that at rest
    for e in doc["experiments"].values():
        assert set(e["path"]) == {"ours", "manual", "full"}
        for p in e["path"].values():
            assert sorted((f["motion"], f["state"], f["t"]) for f in p["frames"]) == sorted(
                (m, s, t) for m in e["motions"] for s in ("on", "off") for t in (0.0, 0.5, 1.0))
            energy = {(f["motion"], f["state"], f["t"]): f["energy_J"] for f in p["frames"]}
            for row in p["summary"]:
                m = row["motion"]
                assert row["work_on_J"] == pytest.approx(energy[(m, "on", 1.0)] - energy[(m, "on", 0.0)])
                assert row["work_off_J"] == pytest.approx(energy[(m, "off", 1.0)] - energy[(m, "off", 0.0)])
            # at rest every motion's OFF state is the same garment on the same body
            rest_off = [energy[(m, "off", 0.0)] for m in e["motions"]]
            assert max(rest_off) == pytest.approx(min(rest_off), rel=1e-12)
    # one truth: the motion's end and the evaluation agree on the garment's energy (each keeps
    # the other's equilibrium where it is the lower), and the evaluation says which it kept
    for e in doc["experiments"].values():
        for kind in ("ours", "manual"):
            ev = e["evaluations"][kind]
            assert all(isinstance(r["from_path"], bool) for r in ev["rows"])
            ends = {(f["motion"], f["state"]): f["energy_J"] for f in e["path"][kind]["frames"] if f["t"] == 1.0}
            for g in ev["garment"]:
                for state in ("on", "off"):
                    assert ends[(g["motion"], state)] == pytest.approx(g[f"energy_{state}_J"], rel=MULTISTABLE)
    assert "peak_force" in summary["targets"]
    # the paper's force sensor: per motion of the two-motion sleeve, ours and the manual
    # design's largest clutch tension over the motion, as in the force over the motion
    sensor = {r["motion"]: r for r in summary["sensor"] if r["experiment"] == "sleeve_two_motions"}
    sleeve = doc["experiments"]["sleeve_two_motions"]
    assert set(sensor) == set(sleeve["motions"])
    for m, r in sensor.items():
        ours = max(f["tension_N"][c] for f in sleeve["path"]["ours"]["frames"] for c in f["tension_N"]
                   if f["motion"] == m and f["state"] == "on")
        assert r["ours_N"] == pytest.approx(ours, rel=1e-12)
        assert r["ratio"] is None or r["ratio"] == pytest.approx(r["ours_N"] / r["manual_N"])
    md = (rep / "report.md").read_text()
    assert "Force over the motion" in md
    page = (rep / "report.html").read_text()
    assert "Clutch loads" in md and "`every_clutch_loaded`" in md
    for heading in ("Targets", "Single-motion designs", "Multi-motion designs", "Cross-evaluation",
                    "Emergent properties", "Performance", "Compared with the paper",
                    "Forces against the manual design"):
        assert f"## {heading}" in md and heading in page
    # the HTML is self-contained (every image embedded); the Markdown links existing files
    srcs = re.findall(r'<img[^>]*\bsrc="([^"]+)"', page)
    assert srcs and all(s.startswith("data:image/png;base64,") for s in srcs)
    links = re.findall(r"!\[[^\]]*\]\(([^)]+)\)", md)
    assert len(links) == len(srcs) and all((rep / s).is_file() for s in links)
    # a second run reuses every design run and evaluation: nothing is recomputed
    stamp = {p: p.stat().st_mtime_ns for p in rep.glob("runs/*/checkpoint.npz")}
    evals = (rep / "evaluations.json").read_text()
    rc, out, err = _cli(["reproduce", "--resolution", "tiny", "--experiments", exps, "--out", "rep"], tmp_path)
    assert rc == 0, err
    assert {p: p.stat().st_mtime_ns for p in rep.glob("runs/*/checkpoint.npz")} == stamp
    assert (rep / "evaluations.json").read_text() == evals
    # a kept experiment whose stored manual baseline is not the one today's rule draws (an
    # older rule's) gets today's evaluated; here today's was evaluated before, so the
    # evaluation comes back from the cache and equals the original
    from kgarment.reproduce.catalog import RESOLUTIONS
    from kgarment.reproduce.evaluate import EvaluationCache
    from kgarment.reproduce.experiments import BY_NAME
    from kgarment.reproduce.pipeline import refresh_manual

    entry = json.loads((rep / "data.json").read_text())["experiments"]["arm_extension"]
    before = json.dumps(entry["evaluations"]["manual"], sort_keys=True)
    npz = rep / "designs" / "arm_extension.npz"
    with np.load(npz) as z:
        stored = {k: z[k] for k in z.files}
    old_rule = stored["manual"].copy()
    old_rule[np.flatnonzero(old_rule)[:5]] = False
    np.savez_compressed(npz, **{**stored, "manual": old_rule})
    args = (BY_NAME["arm_extension"], RESOLUTIONS["tiny"], rep, EvaluationCache(rep / "evaluations.json"), "cpu")
    assert refresh_manual(entry, *args)
    with np.load(npz) as z:
        np.testing.assert_array_equal(z["manual"], stored["manual"])
    assert json.dumps(entry["evaluations"]["manual"], sort_keys=True) == before
    assert not refresh_manual(entry, *args)  # now the same: nothing to do


def test_a_reproduction_folder_keeps_only_its_own_resolution_and_preset(tmp_path):
    """data.json accumulates experiments across invocations, but never mixes resolutions or
    material presets in one report."""
    from kgarment.constants import SIM_MODEL
    from kgarment.errors import KgarmentError
    from kgarment.reproduce.catalog import RESOLUTIONS
    from kgarment.reproduce.pipeline import previous_results, run_again

    tiny = RESOLUTIONS["tiny"]
    assert previous_results(tmp_path, tiny, None) == {}
    entry = {"name": "arm_extension", "preset": "paper", "clutch_model": "locked"}
    doc = {"resolution": {"name": "tiny"}, "sim_model": SIM_MODEL,
           "experiments": {"arm_extension": entry, "arm_flexion": dict(entry)}}
    (tmp_path / "data.json").write_text(json.dumps(doc))
    assert previous_results(tmp_path, tiny, {"preset": None}) == doc["experiments"]
    # nor simulation models: a report written before SIM_MODEL was recorded is model 1
    (tmp_path / "data.json").write_text(json.dumps({k: v for k, v in doc.items() if k != "sim_model"}))
    with pytest.raises(KgarmentError, match=f"made with simulation model 1 and this kgarment simulates model {SIM_MODEL}"):
        previous_results(tmp_path, tiny, {"preset": None})
    (tmp_path / "data.json").write_text(json.dumps(doc))
    with pytest.raises(KgarmentError, match="preset paper, clutch model locked, not preset reference, clutch model locked;"):
        previous_results(tmp_path, tiny, {"preset": "reference"})
    # buckling clutches are another reproduction too (their designs and energies differ)
    with pytest.raises(KgarmentError, match="clutch model locked, not preset paper, clutch model locked, buckling clutch strips;"):
        previous_results(tmp_path, tiny, {"preset": None, "buckle": True})
    with pytest.raises(KgarmentError, match="holds a tiny-resolution reproduction, not preview"):
        previous_results(tmp_path, RESOLUTIONS["preview"], None)
    # and skin friction: the selective sleeve made on a frictionless body before its example had friction
    sel = {"name": "sleeve_selective", "preset": "paper", "clutch_model": "cable", "clutch_buckle": True}
    (tmp_path / "data.json").write_text(json.dumps({**doc, "experiments": {"sleeve_selective": sel}}))
    with pytest.raises(KgarmentError, match="buckling clutch strips, not preset paper, clutch model cable, "
                                            "buckling clutch strips, skin friction 0.4, clutches in channels;"):
        previous_results(tmp_path, tiny, None)
    # and the channels: the selective sleeve made with friction before its example sewed its clutches in
    sel["skin_friction"] = 0.4
    (tmp_path / "data.json").write_text(json.dumps({**doc, "experiments": {"sleeve_selective": sel}}))
    with pytest.raises(KgarmentError, match="skin friction 0.4, not preset paper, clutch model cable, "
                                            "buckling clutch strips, skin friction 0.4, clutches in channels;"):
        previous_results(tmp_path, tiny, None)
    (tmp_path / "data.json").write_text(json.dumps(doc))
    # a committed report (entries without run folders) is continued, not redone, unless named
    assert not run_again("arm_extension", False, doc["experiments"], tmp_path)
    assert run_again("arm_extension", True, doc["experiments"], tmp_path)
    assert run_again("arms_raise", False, doc["experiments"], tmp_path)
    (tmp_path / "runs" / "arm_extension").mkdir(parents=True)
    assert run_again("arm_extension", False, doc["experiments"], tmp_path)  # reuses its run folder
    (tmp_path / "data.json").write_text("{}")
    with pytest.raises(KgarmentError, match="not a reproduction's data"):
        previous_results(tmp_path, tiny, None)


def _not_json(constant: str):
    raise ValueError(f"{constant} is not JSON")


def test_json_for_other_programs_is_strict():
    """Files other programs read (results.json, evaluate --json, plan.json) hold RFC 8259
    JSON: an undefined value (a clutch's 'needed' outside its set: NaN) is null, which
    JSON.parse and jq read, where Python's default would write NaN."""
    from kgarment.io import json_text

    doc = {"needed": float("nan"), "rows": [1.5, float("inf"), (-float("inf"), np.float64("nan"))],
           "name": "elbow", "n": 3, "ok": True, "none": None}
    text = json_text(doc)
    back = json.loads(text, parse_constant=_not_json)
    assert back == {"needed": None, "rows": [1.5, None, [None, None]], "name": "elbow", "n": 3, "ok": True,
                    "none": None}
    with pytest.raises(ValueError, match="NaN is not JSON"):
        json.loads(json.dumps(doc), parse_constant=_not_json)  # what the files held before


def test_an_experiment_run_again_keeps_what_it_took_before():
    """Reused work costs ~0 s: the earlier invocations' phase times are added, not lost."""
    from kgarment.reproduce.pipeline import _add_times

    new = {"phase_seconds": {"designs": 1.0, "paths": 0.5}, "wall_seconds": 1.5}
    before = {"phase_seconds": {"designs": 1674.0, "paths": 48.0, "random": 54.0}}
    out = _add_times(new, before)
    assert out["phase_seconds"] == {"designs": 1675.0, "paths": 48.5, "random": 54.0}
    assert out["wall_seconds"] == 1777.5
    assert _add_times({"phase_seconds": {"designs": 2.0}, "wall_seconds": 2.0}, None)["wall_seconds"] == 2.0


def test_an_experiment_started_afresh_does_not_inherit_the_old_entrys_time(tmp_path):
    """A committed entry whose run folder is gone (a fresh clone) is replaced, not continued."""
    from kgarment.reproduce.pipeline import continued

    old = {"arm_flexion": {"phase_seconds": {"designs": 2845.0}}}
    assert continued("arm_flexion", old, tmp_path) is None
    assert continued("arm_extension", old, tmp_path) is None
    (tmp_path / "runs" / "arm_flexion").mkdir(parents=True)
    assert continued("arm_flexion", old, tmp_path) is old["arm_flexion"]


def test_the_peak_force_target_compares_the_largest_tension_over_the_motion():
    from kgarment.reproduce.targets import force_targets

    def path(forces):  # forces per frame (t = 0.5, 1) of one clutch pair, ON; OFF holds nothing
        return {"frames": [{"motion": "m", "state": s, "t": t, "energy_J": 1.0,
                            "tension_N": {"a": f if s == "on" else 0.0, "b": f / 2 if s == "on" else 0.0}}
                           for s in ("on", "off") for t, f in zip((0.5, 1.0), forces)]}

    def exp(ours, manual):
        return {"x": {"name": "x", "motions": ["m"], "path": {"ours": path(ours), "manual": path(manual)}}}

    (t,) = force_targets(exp([10.0, 30.0], [20.0, 25.0]))
    assert t.ok and "30 N against 25 N" in t.detail
    (t,) = force_targets(exp([10.0, 20.0], [25.0, 5.0]))  # the peak, wherever it is in the motion
    assert not t.ok and "20 against 25 N" in t.detail
    assert force_targets({"x": {"name": "x", "motions": ["m"]}}) == []


def test_a_run_folder_made_with_other_clutch_hardware_is_refused(tmp_path):
    """A reproduction with slipping clutches never reuses a locked one's design runs."""
    import tomli_w

    from kgarment.errors import KgarmentError
    from kgarment.problem import problem_to_dict
    from kgarment.reproduce.catalog import BY_NAME, RESOLUTIONS
    from kgarment.reproduce.experiments import _check_same_problem, experiment_problem

    exp, res = BY_NAME["arm_extension"], RESOLUTIONS["tiny"]
    locked = experiment_problem(exp, res)
    (tmp_path / "problem.toml").write_text(tomli_w.dumps(problem_to_dict(locked)))
    _check_same_problem(locked, tmp_path)
    slip = experiment_problem(exp, res, overrides={"holding_force": 50.0})
    assert slip.clutch_spec().hardware.model == "slip"
    with pytest.raises(KgarmentError, match="other clutch hardware"):
        _check_same_problem(slip, tmp_path)


def test_the_reproduction_keeps_the_papers_clutch_strips():
    """The example files design with buckling clutch strips; the reproduction reproduces the
    paper's model (strips that resist compression) unless told --buckle, and its problems
    are then the ones it made before the examples buckled (nothing written for the default
    hardware: the same cache keys and run folders)."""
    from kgarment.problem import example_path, load_problem, problem_to_dict
    from kgarment.reproduce.catalog import BY_NAME, RESOLUTIONS
    from kgarment.reproduce.experiments import experiment_problem

    exp, res = BY_NAME["sleeve_two_motions"], RESOLUTIONS["tiny"]
    assert load_problem(example_path(exp.name)).clutch_spec().hardware.buckle
    paper = experiment_problem(exp, res)
    assert not paper.clutch_spec().hardware.buckle and problem_to_dict(paper).get("clutches") is None
    assert experiment_problem(exp, res, overrides={"buckle": True}).clutch_spec().hardware.buckle
    assert not experiment_problem(exp, res, overrides={"buckle": None, "preset": None}).clutch_spec().hardware.buckle


def test_the_report_names_an_experiments_early_poses():
    """An experiment designed also for the beginning of a motion says so; one without says nothing."""
    from kgarment.reproduce.report import early_note

    assert early_note({"early": {}}) == "" and early_note({}) == ""
    note = early_note({"early": {"arm_flexion.right": 0.33}})
    assert "`[design] early`" in note and "arm_flexion.right at 0.33" in note


def test_the_comparison_names_what_carries_a_motion_that_falls_short():
    """The sentence on motions more than 2x below the paper is read from the design's clutch
    loads: the clutch that carries the motion where one does, "no clutch" where none does."""
    from kgarment.reproduce.text import short_words

    def exp(loads, loaded=None):  # loaded: the clutches loaded (default: share >= 0.1)
        return {"evaluations": {"ours": {"clutches": [
            {"motion": "flex", "clutch": c, "share": s, "tension_N": t,
             "loaded": s >= 0.1 if loaded is None else c in loaded} for c, s, t in loads]}}}

    doc = {"experiments": {"a": exp([("outer", 1.0, 217.0), ("inner", 0.02, 0.1)]),
                           "b": exp([("outer", 0.03, 2.0), ("inner", 0.05, 1.0)]),
                           # in series: outer loaded by its needed share alone, inner by neither
                           "c": exp([("outer", 0.04, 90.0), ("inner", 0.08, 3.0)], loaded={"outer"})}}
    text = short_words(doc, [(0.43, "a", "flex"), (0.2, "b", "flex"), (0.3, "c", "flex")])
    assert "a/flex (0.43x): outer carries it (share 1.00, 217 N at the target)" in text
    assert "b/flex (0.20x): no clutch carries it" in text
    assert "c/flex (0.30x): outer carries it (share 0.04, 90 N at the target)" in text
    assert short_words(doc, []) == ""


def test_time_left_is_a_linear_estimate():
    from kgarment.io import time_left

    assert time_left(12.0, 0, 10) == ""  # nothing done: nothing to extrapolate from
    assert time_left(12.0, 3, 10) == "12 s so far, about 28 s to go"  # 4 s a step, 7 steps left
    assert time_left(40.0, 10, 10) == "40 s so far, about 0 s to go"
