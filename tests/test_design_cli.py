"""End to end: tiny design runs of every objective from the command line, resume, evaluate."""

from __future__ import annotations

import json
import re
import subprocess
import sys

import numpy as np
import pytest
from cli_runner import run_cli
from tiny_problems import TINY_SLEEVE

SLEEVE = TINY_SLEEVE + """[design]
objective = "{objective}"
target_area = 0.8
er = 0.1
max_iterations = {iterations}
"""


@pytest.mark.parametrize("objective", ["active", "passive", "compliance"])
def test_tiny_design_run(tmp_path, anny_body, objective):
    (tmp_path / "p.toml").write_text(SLEEVE.format(objective=objective, iterations=3))
    rc, out, err = run_cli(["design", "p.toml", "--out", "run"], tmp_path)
    assert rc == 0, err
    run = tmp_path / "run"
    for f in ("problem.toml", "problem.txt", "checkpoint.npz", "designs.npz", "metrics.csv", "metrics.json",
              "progress.png", "final/design.npz", "final/design.ply", "final/design.obj", "final/design.png"):
        assert (run / f).is_file(), f
    rows = json.loads((run / "metrics.json").read_text())
    assert [r["iteration"] for r in rows] == [0, 1, 2]
    assert rows[0]["area"] == pytest.approx(1.0)
    assert rows[1]["area"] < 1.0
    states = ["on", "off"] if objective == "active" else (["on"] if objective == "compliance" else ["none"])
    for s in states:
        assert f"rho[arm_flexion.right:{s}]" in rows[0]
        assert (run / "final" / f"energy_arm_flexion.right_{s}.png").is_file()
    # the final numbers are the one evaluator's, printed at the end and written as JSON
    final = json.loads((run / "final" / "evaluation.json").read_text())
    assert final["iteration"] == 2 and {r["state"] for r in final["rows"]} == set(states)
    assert "evaluated like kgarment evaluate" in out
    # stdout is not a terminal here (a log file, a pipe): the progress comes as lines, the last
    # iteration's among them, with the time elapsed and an ETA
    assert re.search(r"^it +3 of ~\d+  area +[\d.]+%  objective .* elapsed, ETA \d+:\d\d:\d\d$", out, re.MULTILINE), out
    # what to run next, where there are clutches to feel
    assert ("kgarment evaluate run --path 10; " in out and "kgarment plan run;" in out) == (objective != "passive")
    if objective == "passive":  # no clutches in the passive objective: no loads
        assert "clutches" not in final
    else:
        assert [c["clutch"] for c in final["clutches"]] == ["elbow_outer.R"]
        assert (run / "final" / "clutch_loads.png").is_file() and "clutch loads" in out
    # the designs are stored compactly and any iteration can be taken as a design
    from kgarment.design.run import load_design_history

    hist = load_design_history(run)
    assert hist.shape[0] == 3 and hist[0].all()
    assert (run / "designs.npz").stat().st_size < 10_000
    # an existing run is never overwritten without --force
    rc, _, err = run_cli(["design", "p.toml", "--out", "run"], tmp_path)
    assert rc == 2 and "--resume" in err and "--force" in err
    # resuming the finished run rebuilds its history files from the checkpoint
    if objective == "active":
        metrics = (run / "metrics.json").read_text()
        (run / "designs.npz").write_bytes(b"")
        (run / "metrics.json").unlink()
        rc, _, err = run_cli(["design", "--resume", "run"], tmp_path)
        assert rc == 0, err
        np.testing.assert_array_equal(load_design_history(run), hist)
        assert (run / "metrics.json").read_text() == metrics


def test_resume_from_the_command_line_and_evaluate(tmp_path, anny_body):
    (tmp_path / "p.toml").write_text(SLEEVE.format(objective="active", iterations=4))
    rc, _, err = run_cli(["design", "p.toml", "--out", "whole"], tmp_path)
    assert rc == 0, err
    # Ctrl-C in the middle of a run leaves a resumable run folder
    import signal
    import time

    proc = subprocess.Popen([sys.executable, "-m", "kgarment.cli", "design", "p.toml", "--out", "part",
                             "--no-evaluation"], cwd=tmp_path,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))  # even if ignored here
    metrics = tmp_path / "part" / "metrics.json"
    t0 = time.time()
    while time.time() - t0 < 120 and proc.poll() is None:
        if metrics.is_file() and len(json.loads(metrics.read_text() or "[]")) >= 2:
            proc.send_signal(signal.SIGINT)
            break
        time.sleep(0.05)
    out, err = proc.communicate(timeout=120)
    if proc.returncode == 130:
        assert "kgarment design --resume" in out
    else:  # the run finished before the signal arrived; resuming a finished run is a no-op
        assert proc.returncode == 0, err
    rc, out, err = run_cli(["design", "--resume", "part", "--no-evaluation"], tmp_path)
    assert rc == 0, err
    from kgarment.design.run import load_design_history

    np.testing.assert_array_equal(load_design_history(tmp_path / "whole"), load_design_history(tmp_path / "part"))
    rc, out, err = run_cli(["evaluate", "whole@1", "--json", "e.json"], tmp_path)
    assert rc == 0, err
    doc = json.loads((tmp_path / "e.json").read_text())
    rows = doc["rows"]
    assert {r["state"] for r in rows} == {"on", "off"}
    assert all(np.isfinite(r["rho"]) and r["rho"] > 0 for r in rows)
    (load,) = doc["clutches"]
    assert load["motion"] == "arm_flexion.right" and load["clutch"] == "elbow_outer.R" and "tension_N" in load
    (g,) = doc["garment"]
    assert g["energy_on_J"] > 0 and g["energy_off_J"] > 0
    # one truth per design: evaluating the final design gives the run's final numbers
    rc, _, err = run_cli(["evaluate", "whole", "--json", "f.json"], tmp_path)
    assert rc == 0, err
    again = json.loads((tmp_path / "f.json").read_text())
    final = json.loads((tmp_path / "whole" / "final" / "evaluation.json").read_text())
    assert again["rows"] == final["rows"] and again["clutches"] == final["clutches"]
    # a run folder can be moved: its problem.toml finds its clutch file beside it
    import shutil

    shutil.move(tmp_path / "whole", tmp_path / "moved")
    rc, _, err = run_cli(["evaluate", "moved", "--json", "m.json"], tmp_path)
    assert rc == 0, err
    moved = json.loads((tmp_path / "m.json").read_text())
    assert moved["rows"] == final["rows"] and moved["clutches"] == final["clutches"]
    shutil.move(tmp_path / "moved", tmp_path / "whole")
    rc, _, err = run_cli(["evaluate", "nowhere"], tmp_path)
    assert rc == 2 and "not a run folder" in err
    # the control table of the same design: its all-ON and all-OFF energies are the evaluation's
    rc, out, err = run_cli(["plan", "whole@1"], tmp_path)
    assert rc == 0, err
    plan = json.loads((tmp_path / "whole" / "plan@1.json").read_text())
    rec = plan["motions"]["arm_flexion.right"]
    assert plan["clutches"] == ["elbow_outer.R"] and plan["exhaustive"]
    assert rec["best"]["energy_J"] == pytest.approx(g["energy_on_J"], rel=1e-9)
    assert rec["energy_off_J"] == pytest.approx(g["energy_off_J"], rel=1e-9)
    assert rec["best"]["resistance_J"] == pytest.approx(g["energy_on_J"] - g["energy_off_J"], rel=1e-9)
    assert "# Control plan" in (tmp_path / "whole" / "plan@1.md").read_text()
    rc, _, err = run_cli(["plan", "whole@1"], tmp_path)
    assert rc == 2 and "exists" in err  # an existing plan is not replaced without --force
    # with the motion from rest competing: the same all-ON / OFF energies as evaluate --path
    rc, out, err = run_cli(["plan", "whole@1", "--path", "2", "--out", "pathplan"], tmp_path)
    assert rc == 0, err
    rc, _, err = run_cli(["evaluate", "whole@1", "--path", "2", "--json", "p.json"], tmp_path)
    assert rc == 0, err
    (gp,) = json.loads((tmp_path / "p.json").read_text())["garment"]
    rec = json.loads((tmp_path / "pathplan" / "plan@1.json").read_text())["motions"]["arm_flexion.right"]
    assert rec["best"]["energy_J"] == pytest.approx(gp["energy_on_J"], rel=1e-9)
    assert rec["energy_off_J"] == pytest.approx(gp["energy_off_J"], rel=1e-9)
