"""A large motion: the simulator converges on it, the design reports that the clutches
cannot control it, and ``clutches suggest`` says that no suggestion can be felt in it
(issue 20 item 6, issue 19 items 6 and 7)."""

from __future__ import annotations

import json

from kgarment.cli import main
from kgarment.constants import UNCONTROLLABLE

# a 120-degree overhead reach of the right arm (20 clavicle + 100 shoulder), the shirt's
# back clutches, subdivision 0: the short sleeve slides off the rising arm
REACH = """
[motions]
use = ["reach"]
[motions.define.reach]
rotations = [{ bone = "clavicle.R", axis = "-x", degrees = 20 }, { bone = "upperarm01.R", axis = "-x", degrees = 100 }]
[garment]
template = "short_sleeve_shirt"
subdivision = 0
"""


def test_large_reach_converges_and_is_reported_uncontrollable(tmp_path, monkeypatch, capsys, caplog, anny_body):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "p.toml").write_text(REACH)
    assert main(["simulate", "p.toml", "--clutches", "on", "--out", "sim"]) == 0  # converged (else exit 1)
    assert "reach: converged" in capsys.readouterr().out
    assert main(["-q", "design", "p.toml", "--out", "run", "--max-iterations", "1", "--no-evaluation"]) == 0
    warned = caplog.text  # the warning is logged (the CLI's log handler writes it to stderr)
    assert "motion reach: the clutches can hardly be felt in it" in warned and "clutches suggest" in warned
    (c,) = json.loads((tmp_path / "run" / "control.json").read_text())
    assert c["motion"] == "reach" and not c["controllable"] and 0 <= c["gain"] < UNCONTROLLABLE
    assert c["full_on_J"] >= c["full_off_J"] > 0  # equilibria: ON stores at least what OFF does
    row = json.loads((tmp_path / "run" / "metrics.json").read_text())[0]
    assert not row["unconverged_states"]
    # clutches suggest simulates its suggestion in the motion: it cannot be felt either, and says so
    assert main(["clutches", "suggest", "p.toml", "--count", "1", "--out", "sug"]) == 0
    out = capsys.readouterr().out
    assert "reach: NO suggested clutch can be felt in it" in out and "attach the garment" in out

