"""A tiny design end to end: the same run whichever way it is driven, the area schedule
of docs/method/index.md, "BESO", and one truth per design (the run's metrics against the one
design evaluator)."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from tiny_problems import TINY_SLEEVE

from kgarment.cli import main
from kgarment.constants import DESIGN_TOL, EVOLUTION_TOL, target_reached
from kgarment.design import finish, load_design, load_design_history, open_run
from kgarment.errors import KgarmentError
from kgarment.evaluate import Evaluator
from kgarment.problem import load_problem

SLEEVE = TINY_SLEEVE + """[design]
target_area = 0.6
er = 0.15
ar_max = 0.05
max_iterations = 5
[solver]
workers = {workers}
"""


@pytest.fixture(scope="module")
def runs(tmp_path_factory, anny_body):
    """The same problem run from the command line (2 worker processes) and through the
    driver in this process (1 process)."""
    tmp = tmp_path_factory.mktemp("e2e")
    (tmp / "two.toml").write_text(SLEEVE.format(workers=2))
    (tmp / "one.toml").write_text(SLEEVE.format(workers=1))
    assert main(["-q", "design", str(tmp / "two.toml"), "--out", str(tmp / "cli")]) == 0
    dr = finish(open_run(load_problem(tmp / "one.toml"), tmp / "lib", body=anny_body))
    return tmp / "cli", tmp / "lib", dr


def _rows(run):
    return [{k: v for k, v in r.items() if k != "seconds"} for r in json.loads((run / "metrics.json").read_text())]


def test_the_run_does_not_depend_on_how_it_is_driven(runs):
    cli, lib, dr = runs
    np.testing.assert_array_equal(load_design_history(cli), load_design_history(lib))
    assert _rows(cli) == _rows(lib)
    with np.load(cli / "final" / "design.npz") as z:  # the best iteration at the target area
        k = int(z["iteration"])
        np.testing.assert_array_equal(z["design"] > 0.5, load_design_history(cli)[k])
    rows = _rows(cli)
    p = dr.setup.beso.params
    at_target = [r for r in rows if target_reached(r["area"], p.target_area, p.er) and not r["unconverged_states"]]
    assert rows[k] in at_target and rows[k]["objective"] == max(r["objective"] for r in at_target)


def test_the_area_follows_the_schedule(runs):
    """Target of iteration k: max(A*, (1 - ER)^k) (docs/method/index.md, "BESO"); the reinforced
    area meets it to within the faces of one update."""
    _, lib, dr = runs
    p = dr.setup.beso.params
    rows = _rows(lib)
    assert len(rows) == p.max_iterations
    for k, r in enumerate(rows):
        assert r["target"] == pytest.approx(max(p.target_area, (1 - p.er) ** k))
        assert abs(r["area"] - r["target"]) <= p.ar_max + 1e-9
        assert r["solver_tol"] == (DESIGN_TOL if k == 0 else EVOLUTION_TOL)  # [solver] tol, then evolution_tol
    assert rows[-1]["target"] == p.target_area  # A* reached: ceil(log 0.6 / log 0.85) = 4 steps
    assert math.ceil(math.log(p.target_area) / math.log(1 - p.er)) == 4


def test_the_run_and_the_evaluator_agree(runs, anny_body):
    """rho of iteration 0 is 1 by definition; the final design's shape metrics from the run
    and from the one design evaluator agree; the evaluator's batched and one-state-at-a-time
    modes agree exactly."""
    _, lib, dr = runs
    rows = _rows(lib)
    keys = [k for k in rows[0] if k.startswith("rho[")]
    assert keys and all(rows[0][k] == pytest.approx(1.0) for k in keys)
    ev = Evaluator.from_problem(dr.problem, body=anny_body)
    design = load_design(f"{lib}@{len(rows) - 1}", ev.n_faces)
    res = ev.evaluate(design)
    assert res.converged and {(s.motion, s.state) for s in res.states} == {tuple(k[4:-1].split(":")) for k in keys}
    assert res.islands == rows[-1]["islands"] and res.clutch_ends_supported == rows[-1]["clutch_ends_supported"]
    # the fully reinforced garment is its own reference: rho 1 exactly
    full = ev.evaluate(np.ones(ev.n_faces))
    assert all(s.rho == pytest.approx(1.0, abs=1e-12) for s in full.states)
    # batched and one-state-at-a-time evaluations (the studio's) give the same numbers
    one = ev.evaluate(design, report=lambda text: None)
    assert [s.row() for s in one.states] == [s.row() for s in res.states]
    with pytest.raises(KgarmentError, match="design has"):
        ev.evaluate(design[:-1])
    # the final evaluation says, per motion, the run's rho ON at the reported iteration beside its own
    doc = json.loads((lib / "final" / "evaluation.json").read_text())
    run_row, on = rows[doc["iteration"]], {m: r["on"] for m, r in doc["rho"].items()}
    assert set(doc["along_run"]) == set(on)
    for m, v in doc["along_run"].items():
        assert v["run"] == pytest.approx(run_row[f"rho[{m}:on]"]) and v["evaluated"] == pytest.approx(on[m])
        assert v["reached"]  # the tiny sleeve's run ends where the evaluator's starts end (rho 0.955 / 0.889)


def test_force_over_the_motion(runs, anny_body, capsys):
    """``evaluate --path K``: K frames from rest to the target pose, ON and OFF; the last
    frame is the target pose itself (skinning transforms interpolated to the end); the garment
    stores more energy the further the arm bends; the plot and the JSON are written."""
    from kgarment.evaluate.path import frame_motions

    cli, _, dr = runs
    motions, index = frame_motions(dr.problem, ["arm_flexion.right"], 2)
    assert [(m, t) for _, m, t in index] == [("arm_flexion.right", 0.5), ("arm_flexion.right", 1.0)]
    ev = Evaluator.from_problem(dr.problem, body=anny_body)
    target = ev.case.motions["arm_flexion.right"]
    np.testing.assert_allclose(motions[index[-1][0]].garment_x0, target.garment_x0, atol=1e-9)
    assert not np.allclose(motions[index[0][0]].garment_x0, target.garment_x0, atol=1e-3)
    assert main(["-q", "evaluate", str(cli), "--path", "2", "--no-loads", "--json", str(cli / "with-path.json")]) == 0
    (written,) = [p for p in cli.glob("path-*.json") if not p.stem.endswith(("-slip", "-cable"))]  # path-ITERATION
    doc = json.loads(written.read_text())
    # the evaluation comes after the path, whose ends competed with the two starts
    # (tests/test_design_pick.py); each row says which was kept
    rows = json.loads((cli / "with-path.json").read_text())["rows"]
    assert {r["state"] for r in rows} == {"on", "off"} and all(isinstance(r["from_path"], bool) for r in rows)
    assert written.with_suffix(".png").stat().st_size > 10_000
    frames = doc["frames"]  # the rest pose (t = 0) first
    assert sorted((f["state"], f["t"]) for f in frames) == [("off", 0.0), ("off", 0.5), ("off", 1.0),
                                                             ("on", 0.0), ("on", 0.5), ("on", 1.0)]
    on = sorted((f["t"], f["energy_J"]) for f in frames if f["state"] == "on")
    off = sorted((f["t"], f["energy_J"]) for f in frames if f["state"] == "off")
    assert 0 < on[1][1] < on[2][1]
    assert all(set(f["tension_N"]) == {"elbow_outer.R"} and f["converged"] for f in frames)
    # at rest the attachment rings and the body already hold the garment stretched: the work
    # over the motion is the energy at the target less that at rest
    assert off[0][1] > 0 and on[0][1] > 0
    s = doc["summary"][0]
    assert s["energy_on_J"] == pytest.approx(on[2][1]) and s["energy_off_J"] == pytest.approx(off[2][1])
    assert s["work_on_J"] == pytest.approx(on[2][1] - on[0][1])
    assert s["work_off_J"] == pytest.approx(off[2][1] - off[0][1])
    assert s["peak_on_N"] >= s["mean_on_N"]
    # the rest pose is the motion at t = 0: the frames approach it as t goes to 0
    rest = frame_motions(dr.problem, ["arm_flexion.right"], 1, rest=True)[0]["rest"].garment_x0
    near = frame_motions(dr.problem, ["arm_flexion.right"], 20)  # t = 0.05 first
    first = near[0][near[1][0][0]].garment_x0
    assert 0 < np.abs(first - rest).max() < 0.1 * np.abs(target.garment_x0 - rest).max()
    assert "force over the motion" in capsys.readouterr().out
    # again: every solve read back from the run's store (the same states from the same
    # starts: the run's final evaluation and the path above left them), the same numbers
    assert main(["-q", "evaluate", str(cli), "--path", "2", "--no-loads", "--json", str(cli / "again.json")]) == 0
    assert " 0 solved now" in capsys.readouterr().out
    assert json.loads((cli / "again.json").read_text()) == json.loads((cli / "with-path.json").read_text())
    assert json.loads(written.read_text()) == doc


def test_force_over_the_motion_until_the_frame_count_does_not_matter(runs, capsys):
    """``evaluate --path K --converge``: K, 2K, ... frames until two counts agree; the file
    holds the finest path and the counts' check, whose gap is the largest energy change at
    the coarser path's frames over the ON energy at the target."""
    from kgarment.evaluate.path import PathReport
    from kgarment.evaluate.path_converge import frame_gap

    cli, _, _ = runs
    k = json.loads((cli / "final" / "evaluation.json").read_text())["iteration"]
    assert main(["-q", "evaluate", str(cli), "--path", "1", "--no-loads"]) == 0
    one = PathReport.from_json(json.loads((cli / f"path-{k}.json").read_text()))
    assert main(["-q", "evaluate", str(cli), "--path", "1", "--converge", "--no-loads"]) == 0
    out = capsys.readouterr().out
    doc = json.loads((cli / f"path-{k}.json").read_text())
    (check,) = doc["frames_checked"]
    assert check["motion"] == "arm_flexion.right" and check["frames"][:2] == [1, 2]
    n = check["frames"][-1]
    assert [f["t"] for f in doc["frames"] if f["state"] == "on"] == pytest.approx([i / n for i in range(n + 1)])
    assert check["converged"] == (check["gaps"][-1] <= check["tol"]) and (check["converged"] or n == 80)
    if len(check["frames"]) == 2:  # the first gap is the 1-frame path's against the one written now
        assert check["gaps"][0] == pytest.approx(frame_gap(one, PathReport.from_json(doc), "arm_flexion.right"),
                                                 rel=1e-6, abs=1e-9)
    assert "arm_flexion.right: frames 1 -> 2" in out
    assert main(["-q", "evaluate", str(cli), "--converge"]) == 2  # --converge refines --path
    assert "give --path K too" in capsys.readouterr().err


@pytest.mark.parametrize("model", ["slip", "cable"])
def test_force_over_the_motion_with_slipping_clutches(runs, capsys, model):
    """``evaluate --clutch-model slip|cable --holding-force N --path K``: the same run judged
    with clutches that slide at N newtons (bands, or cables between their ends); its files
    go beside the run's own (path-K-MODEL), and the ON tension stays near N once the clutch
    slides, from where the report says."""
    cli, _, _ = runs
    k = json.loads((cli / "final" / "evaluation.json").read_text())["iteration"]
    locked = json.loads((cli / "final" / "evaluation.json").read_text())
    t_locked = max(c["tension_N"] for c in locked["clutches"])
    hold = 0.5 * t_locked
    assert main(["-q", "evaluate", str(cli), "--path", "2", "--clutch-model", model, "--holding-force", f"{hold}",
                 "--json", str(cli / f"{model}.json")]) == 0
    doc = json.loads((cli / f"path-{k}-{model}.json").read_text())
    assert doc["holding_N"] == {"arm_flexion.right": {"elbow_outer.R": pytest.approx(hold)}}
    (c,) = json.loads((cli / f"{model}.json").read_text())["clutches"]
    assert c["slipping"] and c["holding_N"] == pytest.approx(hold)
    assert hold <= c["tension_N"] < 1.2 * hold  # at its holding force (+ the guide and the hardening)
    assert doc["slips"] and doc["slips"][0]["clutch"] == "elbow_outer.R"
    assert "slips in arm_flexion.right from t =" in capsys.readouterr().out


def test_a_design_on_another_body(runs, capsys):
    """``evaluate --phenotype``: on the run's own phenotype the transferred garment and
    clutches reproduce the run's evaluation; on a heavier body the same faces carry the
    design; a phenotype out of range is one line, exit 2, before any work."""
    cli, _, dr = runs
    own = json.loads((cli / "final" / "evaluation.json").read_text())
    same = cli / "same.json"
    assert main(["-q", "evaluate", str(cli), "--no-loads", "--phenotype", "weight=0.5", "--json", str(same)]) == 0
    doc = json.loads(same.read_text())
    (t,) = doc["transfer"]
    assert t["phenotype"]["weight"] == 0.5
    for m, v in own["rho"].items():
        for s in ("on", "off"):
            assert t["rho"][m][s] == pytest.approx(v[s], rel=2e-3)
    heavy = cli / "heavy.json"
    assert main(["-q", "evaluate", str(cli), "--no-loads", "--phenotype", "weight=0.9,height=0.2",
                 "--json", str(heavy)]) == 0
    (t,) = json.loads(heavy.read_text())["transfer"]
    assert t["phenotype"]["weight"] == 0.9 and t["phenotype"]["height"] == 0.2
    m = dr.problem.motions[0]
    assert math.isfinite(t["rho"][m]["on"]) and t["rho"][m]["on"] != pytest.approx(own["rho"][m]["on"], rel=1e-3)
    assert "on another body (phenotype: weight 0.9, height 0.2" in capsys.readouterr().out
    for bad, message in (("weight=2", "phenotype weight = 2.0 is outside [0, 1]"),
                         ("waist=0.3", "unknown phenotype parameter 'waist'"),
                         ("weight=heavy", "'heavy' is not a number"),
                         ("weight=0.5,weight=0.6", "gives weight more than once"),
                         (",,", "changes nothing")):
        assert main(["-q", "evaluate", str(cli), "--phenotype", bad]) == 2
        err = capsys.readouterr().err
        assert message in err and err.count("\n") == 1
