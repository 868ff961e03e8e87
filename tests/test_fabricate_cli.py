"""``kgarment fabricate`` end to end on a fake run folder: every file, inputs, no clobbering."""
# ruff: noqa: F811  (pytest fixtures imported from test_fabricate_support)

from __future__ import annotations

import argparse
import json

import numpy as np
import pytest
from test_fabricate_support import band_design, sleeve, sleeve_clutches, write_run  # noqa: F401

from kgarment.cli.fabricate import add_parsers as add_parser
from kgarment.errors import KgarmentError

FILES = ("cut_patterns.svg", "cut_patterns.dxf", "cut_patterns.pdf", "cut_patterns.png", "placement.svg",
         "placement.png", "placement_3d.png", "design_clean.glb", "design_clean.obj", "design_clean.ply",
         "design_clean.npz", "bom.md", "bom.csv", "report.md", "report.json")


def fabricate_cli(*argv) -> int:
    ap = argparse.ArgumentParser(prog="kgarment")
    add_parser(ap.add_subparsers(dest="command"))
    args = ap.parse_args(["fabricate", *map(str, argv)])
    return args.func(args)


@pytest.fixture
def run(tmp_path, sleeve, sleeve_clutches, band_design):
    return write_run(tmp_path / "run", sleeve, sleeve_clutches[0], band_design[0])


def test_run_folder_to_every_file(run, capsys):
    assert fabricate_cli(run, "--no-resimulate") == 0
    out = run / "fabrication"
    for f in FILES:
        assert (out / f).is_file() and (out / f).stat().st_size > 0, f
    text = capsys.readouterr().out
    assert str(out / "cut_patterns.svg") in text and "millimetres" in text
    rep = json.loads((out / "report.json").read_text())
    assert rep["cleanup"]["islands_removed"] == 1 and rep["rho"] == []
    assert all(p["max_length_distortion_pct"] <= 5.0 for p in rep["patches"])
    bom = (out / "bom.csv").read_text()
    assert "elbow_outer.R" in bom and "snap fastener pair,6," in bom
    assert "units: millimetres" in (out / "cut_patterns.svg").read_text()
    # never overwritten without --force
    with pytest.raises(KgarmentError, match="--force"):
        fabricate_cli(run, "--no-resimulate")
    stamp = (out / "report.json").stat().st_mtime_ns
    assert fabricate_cli(run, "--no-resimulate", "--force", "--no-smooth", "--method", "lscm", "--paper", "letter") == 0
    assert (out / "report.json").stat().st_mtime_ns != stamp
    assert json.loads((out / "report.json").read_text())["method"] == "lscm"


def test_iteration_of_a_run(run, sleeve):
    # iteration 0 of the fake run is the fully reinforced sleeve: a tube, cut open along a seam
    assert fabricate_cli(f"{run}@0", "--no-resimulate") == 0
    rep = json.loads((run / "fabrication@0" / "report.json").read_text())
    assert rep["seams"] and rep["seams"][0]["kind"] == "hole"
    area = sum(p["area_3d_m2"] for p in rep["patches"])
    assert area == pytest.approx(sleeve.face_areas().sum(), rel=1e-9)
    for p in rep["patches"]:
        assert p["area_distortion_pct"] < 2.0 and p["flipped"] == 0
    with pytest.raises(KgarmentError, match="iterations 0..2"):
        fabricate_cli(f"{run}@7", "--no-resimulate", "--out", run / "x")


def test_design_file_needs_its_problem(run, tmp_path):
    design = run / "final" / "design.npz"
    with pytest.raises(KgarmentError, match="--problem"):
        fabricate_cli(design, "--no-resimulate")
    out = tmp_path / "fab"
    assert fabricate_cli(design, "--problem", run / "problem.toml", "--out", out, "--no-resimulate") == 0
    assert all((out / f).is_file() for f in FILES)
    with np.load(out / "design_clean.npz") as z:
        assert z["design"].shape == z["original"].shape == (len(z["faces"]),)
    # a design made for another mesh is refused
    with np.load(design) as z:
        np.savez(tmp_path / "other.npz", design=z["design"][:-2], faces=z["faces"][:-2])
    with pytest.raises(KgarmentError):
        fabricate_cli(tmp_path / "other.npz", "--problem", run / "problem.toml", "--no-resimulate")
    with pytest.raises(KgarmentError, match="neither a run folder"):
        fabricate_cli(tmp_path / "missing.npz", "--problem", run / "problem.toml")


def test_resimulation_reports_rho_before_and_after(run, capsys):
    """The 563-face sleeve, preset "reference": four solves (full and design, before and
    after the clean-up), about 12 s on two cores."""
    assert fabricate_cli(run, "--out", run / "fab_sim") == 0
    rep = json.loads((run / "fab_sim" / "report.json").read_text())
    states = {(r["motion"], r["state"]) for r in rep["rho"]}
    assert states == {("arm_flexion.right", "on"), ("arm_flexion.right", "off")}
    for r in rep["rho"]:
        assert np.isfinite(r["rho_before"]) and np.isfinite(r["rho_after"]) and r["rho_after"] > 0
    assert "Re-simulation" in (run / "fab_sim" / "report.md").read_text()
    # the cleaned design's per-clutch loads reach the report and the sheet's legend
    assert {c["clutch"] for c in rep["clutch_loads"]["clutches"]} == {"elbow_outer.R"}
    assert "load not evaluated" not in (run / "fab_sim" / "cut_patterns.svg").read_text()
    assert "rho arm_flexion.right" in capsys.readouterr().out
