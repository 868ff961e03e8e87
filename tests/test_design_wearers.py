"""One design for several bodies ([body] phenotypes, kgarment.case.wearers) and
``kgarment sizes``.

Invariants, not today's numbers: a size range of two identical wearers is the one-body
problem twice, so its design history is the one-body run's (each motion's normalised
sensitivities are added twice: BESO ranks the same faces) and the shared design keeps
exactly 100% of each own design; a wearer of another size is evaluated exactly as the
transfer of the design to that body (``kgarment evaluate --phenotype``) evaluates it."""

from __future__ import annotations

import json

import numpy as np
import pytest
from tiny_problems import TINY_SLEEVE

from kgarment.cli import main
from kgarment.design import load_design, load_design_history
from kgarment.evaluate import Evaluator
from kgarment.problem import load_problem, parse_problem, problem_to_dict

SLEEVE = TINY_SLEEVE + """[body]
phenotypes = [{phenotypes}]
[design]
target_area = 0.6
er = 0.15
ar_max = 0.05
max_iterations = 4
[solver]
workers = 2
"""
TWINS = '{name = "a"}, {name = "b"}'
SIZES = '{name = "M"}, {name = "L", weight = 0.9, height = 0.7}'


@pytest.fixture(scope="module")
def twins(tmp_path_factory, anny_body):
    tmp = tmp_path_factory.mktemp("sizes")
    (tmp / "twins.toml").write_text(SLEEVE.format(phenotypes=TWINS))
    assert main(["-q", "sizes", str(tmp / "twins.toml"), "--out", str(tmp / "out")]) == 0
    return tmp / "out"


def test_phenotypes_round_trip(tmp_path):
    import tomllib

    p = parse_problem(tomllib.loads(SLEEVE.format(phenotypes=SIZES)))
    assert p.body.names == ("M", "L") and p.body.phenotype == p.body.phenotypes[0][1]
    assert p.body.phenotypes[1][1].weight == 0.9
    again = parse_problem(problem_to_dict(p))
    assert again.body == p.body
    unnamed = parse_problem(tomllib.loads(SLEEVE.format(phenotypes="{}, {weight = 0.2}")))
    assert unnamed.body.names == ("body1", "body2")


def test_identical_wearers_are_the_one_body_design(twins):
    """Two identical wearers: the shared design's history is each own design's, and every
    motion keeps exactly 100%."""
    runs = twins / "runs"
    shared = load_design_history(runs / "all")
    for own in ("a", "b"):
        np.testing.assert_array_equal(load_design_history(runs / own), shared)
    doc = json.loads((twins / "sizes.json").read_text())
    assert [r["wearer"] for r in doc["rows"]] == ["a", "b"]
    for r in doc["rows"]:
        assert r["kept"] == pytest.approx(1.0, rel=1e-6)
        assert r["shared"]["off"] == pytest.approx(r["own"]["off"], rel=1e-6)
    assert doc["keeps"] is True
    shared_ev = json.loads((runs / "all" / "final" / "evaluation.json").read_text())
    assert set(shared_ev["rho"]) == {"arm_flexion.right@a", "arm_flexion.right@b"}
    assert (twins / "sizes.md").read_text().count("| a |") == 1 and (twins / "sizes.png").stat().st_size > 0


def test_sizes_reuses_finished_runs(twins, capsys):
    before = {p: p.stat().st_mtime_ns for p in (twins / "runs").glob("*/checkpoint.npz")}
    assert main(["-q", "sizes", str(twins.parent / "twins.toml"), "--out", str(twins)]) == 0
    assert {p: p.stat().st_mtime_ns for p in (twins / "runs").glob("*/checkpoint.npz")} == before
    assert "kept" in capsys.readouterr().out


def test_sizes_never_reports_runs_of_another_problem_nor_writes_into_other_folders(twins, tmp_path, capsys):
    """Kept runs made for another problem are refused before any work (not reported as this
    one's), and the output folder is never a design run or a folder of the user's."""
    before = {p: p.stat().st_mtime_ns for p in twins.rglob("*") if p.is_file()}
    (tmp_path / "other.toml").write_text(SLEEVE.format(phenotypes=TWINS).replace("target_area = 0.6", "target_area = 0.7"))
    assert main(["-q", "sizes", str(tmp_path / "other.toml"), "--out", str(twins)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "was designed for another problem (its design differ)" in err
    assert {p: p.stat().st_mtime_ns for p in twins.rglob("*") if p.is_file()} == before
    (tmp_path / "mine").mkdir()
    (tmp_path / "mine" / "sizes.md").write_text("my table")
    for out, message in ((twins / "runs" / "a", "is a kgarment run folder, not a sizes folder"),
                         (tmp_path / "mine", "exists and holds files kgarment did not write")):
        assert main(["-q", "sizes", str(twins.parent / "twins.toml"), "--out", str(out)]) == 2
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and message in err, err
    assert (tmp_path / "mine" / "sizes.md").read_text() == "my table"


def test_another_size_is_the_transferred_design(twins, tmp_path, anny_body, capsys):
    """A wearer of another size in a multi-body evaluation gets the numbers of the design
    moved to that body by ``kgarment evaluate --phenotype``, and the first wearer those of
    the one-body evaluation: one truth per design."""
    own = twins / "runs" / "a"  # a one-body run on the default body (= wearer M below)
    assert main(["-q", "evaluate", str(own), "--no-loads", "--phenotype", "weight=0.9,height=0.7",
                 "--json", str(tmp_path / "t.json")]) == 0
    doc = json.loads((tmp_path / "t.json").read_text())
    (moved,) = doc["transfer"]
    (tmp_path / "sizes.toml").write_text(SLEEVE.format(phenotypes=SIZES))
    ev = Evaluator.from_problem(load_problem(tmp_path / "sizes.toml"), body=anny_body)
    assert list(ev.motions) == ["arm_flexion.right@M", "arm_flexion.right@L"]
    assert ev.motion_names(["arm_flexion.right"]) == list(ev.motions)
    rho = ev.evaluate(load_design(own, ev.n_faces)).rho()
    for s in ("on", "off"):
        assert rho["arm_flexion.right@M"][s] == pytest.approx(doc["rho"]["arm_flexion.right"][s], rel=1e-6)
        assert rho["arm_flexion.right@L"][s] == pytest.approx(moved["rho"]["arm_flexion.right"][s], rel=1e-6)
    assert rho["arm_flexion.right@L"]["on"] != pytest.approx(rho["arm_flexion.right@M"]["on"], rel=1e-3)
    assert main(["-q", "evaluate", str(twins / "runs" / "all"), "--path", "2"]) == 2
    assert "multi-body design" in capsys.readouterr().err


def test_sizes_needs_a_multi_body_problem(tmp_path, capsys):
    (tmp_path / "one.toml").write_text(SLEEVE.replace("phenotypes = [{phenotypes}]", "").format())
    assert main(["-q", "sizes", str(tmp_path / "one.toml"), "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err
    assert "needs a multi-body problem" in err and err.count("\n") == 1
    assert not (tmp_path / "o").exists()
