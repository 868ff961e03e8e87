"""Bad input, as a hostile or clumsy user gives it: every case exits with status 2 and one
line naming the field or file and what is allowed, no traceback, nothing touched.

The table grows with every new field (issue 20).  Cases run in-process
(``tests/cli_runner.py``, the log on stderr as a user sees it); the ones that fail only
once the body is built use the session's cached Anny body.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import trimesh
from cli_runner import run_cli

SLEEVE = '[garment]\ntemplate = "arm_sleeve.right"\nsubdivision = 0\n[motions]\nuse = ["arm_flexion.right"]\n'
CLUTCH = ('[garment]\ntemplate = "arm_sleeve.right"\nsubdivision = 0\n[motions]\nuse = ["arm_flexion.right"]\n'
          '[[clutches.clutch]]\nname = "c"\nstart = "elbow_outer.R"\n')
ROT = '[motions]\nuse = ["w"]\n[motions.define.w]\nrotations = [{ bone = "upperarm01.R", %s }]\n'


def assert_one_line(rc, err, message):
    assert rc == 2, err
    assert "Traceback" not in err and err.count("\n") == 1, err
    assert message in err, err


# (problem file text, message); each is rendered with `kgarment render p.toml`
PROBLEMS = [
    ("design = 5\n", "[design] must be a table of fields"),
    ('[garment]\ntemplate = "short_sleeve_shirt"\nattach = ["hem"]\n', "attach is for a garment given by mask"),
    ("materials = 5\n", "[materials] must be a table of fields"),
    ('[motions]\nuse = ["m"]\n[motions.define.m]\nkeyframes = [[{bone = "upperarm01.R", axis = "x", degrees = 30}], 5]\n',
     "keyframes a list of such lists"),
    ('[body]\nphenotypes = [{name = "all"}, {name = "L", weight = 0.8}]\n', "name = 'all'; allowed"),
    ('[body]\nphenotypes = [{name = ".."}, {name = "L", weight = 0.8}]\n', "not only dots"),
    ('[motions]\nuse = ["arm_flexion.right"]\n[motions.activation]\n"arm_flexion.right" = []\n',
     "[motions.activation] arm_flexion.right switches no clutch on (an empty set)"),
    ('[motions]\nuse = ["arm_flexion.right"]\n[motions.activation]\n"arm_flexion.right" = { "elbow_outer.R" = 1.5 }\n',
     "[motions.activation] arm_flexion.right: elbow_outer.R = 1.5 is outside [0, 1]"),
    ('[motions]\nuse = ["arm_flexion.right"]\n[motions.activation]\narms_raise = ["upper_back"]\n',
     "[motions.activation] 'arms_raise' is not a motion of this problem; allowed: arm_flexion.right"),
    ('[motions]\nuse = ["arm_flexion.right"]\n[motions.activation]\n"arm_flexion.right" = "elbow_outer.R"\n',
     "must be a list of clutch names or a table"),
    ('[design]\nlockout = -1\n', "lockout = -1"),
    ('[design]\nguard = 1.0\n', "guard = 1.0 is outside [0, 0.95]"),
    ('[design]\ncombine = "max"\n', "[design] combine = 'max'; allowed: sum, product"),
    ('[garment]\nsubdivision = false\n', "subdivision = False; allowed: 0, 1, 2, 3"),
    ('[garment]\nsubdivision = 0.5\n', "subdivision = 0.5; allowed"),
    (ROT % 'axis = "x", degrees = "sixty"', "degrees = 'sixty'; allowed: a number in [-180, 180]"),
    (ROT % 'axis = "x", degrees = nan', "degrees = nan; allowed"),
    (ROT % 'axis = "x", degrees = 1e6', "degrees = 1000000.0; allowed: a number in [-180, 180]"),
    (ROT % 'axis = ["a", 1, 2], degrees = 30', "axis = ['a', 1, 2]; give x, y, z or three finite numbers"),
    (ROT % 'axis = [0, 0, 0], degrees = 30', "not all 0"),
    (ROT % 'axis = "x", degrees = true', "degrees = True; allowed"),
    ('[motions]\nuse = "arm_extension.right"\n', "use = 'arm_extension.right' must be a list of motion names"),
    ('[motions]\nuse = ["arms_raise", "arms_raise"]\n', "lists 'arms_raise' more than once"),
    ('[body]\nphenotype = "tall"\n', "phenotype = 'tall' must be a table"),
    ('[body]\nphenotype = { gender = true }\n', "phenotype gender = True is outside [0, 1]"),
    ('[body]\nphenotypes = [{name = "S"}]\n', "phenotypes must list two or more tables"),
    ('[body]\nphenotypes = [{name = "S"}, {name = "S", weight = 0.8}]\n', "duplicate name 'S'"),
    ('[body]\nphenotypes = [{name = "S"}, {name = "L", weight = 1.8}]\n',
     "[body] phenotypes[1] (L): phenotype weight = 1.8 is outside [0, 1]"),
    ('[body]\nphenotypes = [{name = "S"}, {name = "L", waist = 0.3}]\n', "unknown phenotype parameter 'waist'"),
    ('[body]\nphenotypes = [{name = "a b"}, {name = "L"}]\n', "name = 'a b'; allowed: letters, digits"),
    ('[body]\nphenotype = {weight = 0.3}\nphenotypes = [{name = "S"}, {name = "L"}]\n',
     "given by phenotypes alone"),
    ('[body]\nphenotypes = [{name = "S"}, {name = "L"}]\n[design]\nlevels = [0]\n',
     "coarse-to-fine is for one body"),
    ('[design]\ntol = 0\n', "tol = 0.0 is outside"),
    ('[design]\nconnected = 1\n', "connected = 1; allowed: true, false"),
    ('[design]\ntarget_area = inf\n', "target_area = inf must be a finite number"),
    ('[solver]\ntol = nan\n', "tol = nan must be a finite number"),
    ('[solver]\nmethod = 5\n', "method = 5 must be a string"),
    ('[solver]\nworkers = 1.5\n', "workers = 1.5 must be an integer"),
    (CLUTCH + 'direction = [0, 0, -1]\nlength = 0.1\nwidth = 0.5\n', "field 'width' = 0.5 m is more than 0.5 x"),
    (CLUTCH + 'direction = [0, 0, -1]\nlength = 3.0\n', "field 'length' = 3 m; allowed: up to 1 m"),
    (CLUTCH + 'towards = "elbow_outer.R"\nlength = 0.1\n', "'towards' is the start itself"),
    ('[motions]\ndefine = 3\n', "[motions] define must hold tables"),
    ('[clutches]\nmodel = "sticky"\n', "[clutches] model = 'sticky'; allowed: locked, slip"),
    ('[clutches]\nmodel = "locked"\nholding_force = 50\n', 'holding_force does nothing with model = "locked"'),
    ('[clutches]\nholding_force = -5\n', "[clutches] holding_force = -5 is outside [0.001, 100000] N"),
    ('[clutches]\nholding_force = { upper_back = "a lot" }\n', "holding_force.upper_back = 'a lot' must be a number"),
    ('[clutches]\nholding_stress = 1e5\nvoltage = 300\n', "holding_stress and voltage both set the holding stress"),
    ('[clutches]\nvoltage = 0\n', "[clutches] voltage = 0.0 must be > 0"),
    ('[clutches]\nfriction = 5\n', "[clutches] friction = 5.0 is outside"),
    # names become file names: never a path
    (ROT.replace('"w"', '"x/../../escaped"').replace("define.w", 'define."x/../../escaped"') % 'axis = "x", degrees = 30',
     "motion name 'x/../../escaped'; allowed"),
    (ROT.replace('"w"', '"arms_raise"').replace("define.w", "define.arms_raise") % 'axis = "x", degrees = 30',
     "'arms_raise' is a built-in motion"),
    (CLUTCH.replace('name = "c"', 'name = "../c"') + 'direction = [0, 0, -1]\nlength = 0.1\n',
     "clutch name '../c': allowed: letters, digits"),
    ('[garment]\nmask = "p.toml"\nattach = 5\n', "[garment] attach = 5 must be a list of attachment loop names"),
    ('[garment]\nmask = "p.toml"\nattach = "wrist"\n', "attach = 'wrist' must be a list"),
    ('[body]\nmodel = "meshes"\nrest = "p.toml"\nmotions = "abc"\n', "[body] motions must be a table of mesh files"),
    ('[garment]\nmask = "."\n', "is a folder, not a file"),
    ('[body]\nmodel = "meshes"\nrest = "."\nmotions = {}\n', "is a folder, not a file"),
    (ROT.replace("rotations =", "description = 5\nrotations =") % 'axis = "x", degrees = 30',
     "[motions.define.w] description = 5: must be a string"),
]


@pytest.mark.parametrize("toml, message", PROBLEMS, ids=[m[:40] for _, m in PROBLEMS])
def test_bad_problem_field(toml, message, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "p.toml").write_text(toml)
    rc, _, err = run_cli(["render", "p.toml", "--out", "pics"])
    assert_one_line(rc, err, message)
    assert not (tmp_path / "pics").exists()


# (command line, message): numbers are checked when the flags are parsed
FLAGS = [
    (["design", "--max-iterations", "-5"], "argument --max-iterations: -5 is outside [1, 100000]"),
    (["design", "--max-iterations", "0"], "argument --max-iterations: 0 is outside"),
    (["demo", "--max-iterations", "2.5"], "argument --max-iterations: '2.5' is not an integer"),
    (["design", "--subdivision", "4"], "argument --subdivision: 4 is outside [0, 3]"),
    (["simulate", "--tol", "nan"], "argument --tol: nan is not a finite number"),
    (["clutches", "suggest", "--count", "0"], "argument --count: 0 is outside [1, 64]"),
    (["clutches", "suggest", "--length", "-1"], "argument --length: -1 is outside [0.01, 1]"),
    (["studio", "--port", "99999"], "argument --port: 99999 is outside [1, 65535]"),
    (["fabricate", "run", "--max-cuts", "-1"], "argument --max-cuts: -1 is outside [0, 64]"),
    (["fabricate", "run", "--min-width", "inf"], "argument --min-width: inf is not a finite number"),
    (["reproduce", "--preset", "steel"], "argument --preset: invalid choice: 'steel'"),
    (["plan", "run", "--exhaustive", "11"], "argument --exhaustive: 11 is outside [0, 10]"),
    (["evaluate", "run", "--holding-force", "-1"], "argument --holding-force: -1 is outside"),
    (["design", "--clutch-model", "glued"], "argument --clutch-model: invalid choice: 'glued'"),
    (["simulate", "--device", "nonsense"], "argument --device: 'nonsense' is not a torch device"),
    (["reproduce", "--experiments", ""], "names no experiment"),
    (["reproduce", "--experiments", " , "], "names no experiment"),
    (["design", "--resume", "somerun", "--max-iterations", "7"], "--max-iterations would be ignored"),
    (["clutches", "show", "--count", "5"], "--count and --length are for clutches suggest"),
    (["motions", "."], "problem file . is a folder; give a .toml file"),
    (["design", "p.toml", "--resume", "somerun"], "a problem file would be ignored"),
]


@pytest.mark.parametrize("argv, message", FLAGS, ids=[" ".join(a) for a, _ in FLAGS])
def test_bad_flag(argv, message):
    rc, _, err = run_cli(argv)
    assert_one_line(rc, err, message)


def test_outputs_checked_before_the_work(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "afile").write_text("x")
    (tmp_path / "adir").mkdir()
    cases = [
        (["evaluate", "norun", "--json", "adir"], "--json adir is a folder"),
        (["evaluate", "norun", "--json", "afile/x.json"], "afile is a file, not a folder"),
        (["evaluate", "norun", "--plot", "adir"], "--plot adir is a folder"),
        (["plan", "norun", "--out", "afile"], "--out afile is a file"),
        (["simulate", "--out", "afile"], "--out afile is a file, not a folder"),
        (["render", "--out", "afile/pics"], "afile is a file, not a folder"),
        (["clutches", "suggest", "--out", "afile"], "--out afile is a file"),
        (["reproduce", "--out", "afile"], "--out afile is a file"),
        (["design", "--out", "afile"], "afile is a file, not a folder"),
        (["evaluate", "norun", "--json", "afile"], "--json afile exists; use --force to overwrite it"),
        (["studio", "--runs", "afile"], "--runs afile is a file, not a folder"),
        (["studio", "--session", "afile/s"], "afile is a file, not a folder"),
        (["evaluate", "norun", "--plot", "loads.txt"], "--plot loads.txt: give a .png or .pdf or .svg file"),
        (["evaluate", "norun", "--plot", "loads.png", "--no-loads"], "--no-loads leaves out"),
        (["evaluate", "norun", "--plot", "x.svg", "--json", "x.svg"], "name the same file"),
    ]
    for argv, message in cases:
        rc, _, err = run_cli(argv)
        assert_one_line(rc, err, message)
    assert (tmp_path / "afile").read_text() == "x" and not any((tmp_path / "adir").iterdir())


def _foreign_folder(path):
    (path / "sub").mkdir(parents=True)
    (path / "notes.txt").write_text("my notes")
    (path / "sub" / "thesis.txt").write_text("chapter 1")


def test_force_never_deletes_a_folder_kgarment_did_not_write(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    _foreign_folder(tmp_path / "mine")
    for argv in (["design", "--out", "mine", "--force"], ["demo", "--out", "mine", "--force"],
                 ["design", "--out", "mine"]):
        rc, _, err = run_cli(argv)
        assert_one_line(rc, err, "mine exists and holds files kgarment did not write")
    assert (tmp_path / "mine" / "notes.txt").read_text() == "my notes"
    assert (tmp_path / "mine" / "sub" / "thesis.txt").read_text() == "chapter 1"


def _old_run(path):
    """A run folder kgarment wrote (its inputs, a checkpoint) with recognisable bytes."""
    path.mkdir()
    for name in ("problem.toml", "problem.txt", "checkpoint.npz", "metrics.csv"):
        (path / name).write_bytes(f"old {name}".encode())
    return {p.name: p.read_bytes() for p in path.iterdir()}


def test_force_keeps_the_old_run_when_the_new_problem_fails(tmp_path, monkeypatch, anny_body):
    monkeypatch.chdir(tmp_path)
    before = _old_run(tmp_path / "run")
    np.save(tmp_path / "mask.npy", np.array([3]))  # one face: not a garment
    (tmp_path / "p.toml").write_text('[garment]\nmask = "mask.npy"\nsubdivision = 0\n')
    rc, _, err = run_cli(["design", "p.toml", "--out", "run", "--force"])
    assert_one_line(rc, err, "selects 1 faces of the body; a garment needs at least 20")
    assert {p.name: p.read_bytes() for p in (tmp_path / "run").iterdir()} == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["mask.npy", "p.toml", "run"]  # no temporary left
    (tmp_path / "p.toml").write_text('[motions]\nuse = ["moonwalk"]\n')  # fails while parsing
    rc, _, err = run_cli(["design", "p.toml", "--out", "run", "--force"])
    assert_one_line(rc, err, "unknown motion 'moonwalk'")
    assert {p.name: p.read_bytes() for p in (tmp_path / "run").iterdir()} == before


def test_replace_folder_swaps_only_when_filled(tmp_path):
    from kgarment.errors import KgarmentError
    from kgarment.io import MARKER, check_replaceable, replace_folder

    before = _old_run(tmp_path / "run")

    def boom(tmp):
        (tmp / "half.txt").write_text("half")
        raise RuntimeError("disk full")

    with pytest.raises(RuntimeError):
        replace_folder(tmp_path / "run", boom, "run")
    assert {p.name: p.read_bytes() for p in (tmp_path / "run").iterdir()} == before
    replace_folder(tmp_path / "run", lambda tmp: (tmp / "new.txt").write_text("new"), "run")
    assert sorted(p.name for p in (tmp_path / "run").iterdir()) == [MARKER, "new.txt"]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["run"]
    with pytest.raises(KgarmentError, match="use --force"):
        check_replaceable(tmp_path / "run", force=False)
    check_replaceable(tmp_path / "run", force=True)  # marked: replaceable
    # never by a folder of another kind: cut files do not replace a design run, nor the reverse
    with pytest.raises(KgarmentError, match="is a kgarment run folder, not a fabrication folder"):
        check_replaceable(tmp_path / "run", force=True, kind="fabrication")
    with pytest.raises(KgarmentError, match="another kind"):
        replace_folder(tmp_path / "run", lambda tmp: None, "fabrication")
    assert sorted(p.name for p in (tmp_path / "run").iterdir()) == [MARKER, "new.txt"]


def test_an_empty_design_file_is_one_line(tmp_path, monkeypatch, anny_body):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "empty.txt").write_text("\n")
    rc, _, err = run_cli(["simulate", "--design", "empty.txt", "--subdivision", "0", "--out", "s"])
    assert_one_line(rc, err, "cannot read design empty.txt (.npy, .npz or text of 3229 numbers): the file is empty")
    assert "Warning" not in err


def test_clutches_show_checks_the_clutch_names_a_design_would(tmp_path, monkeypatch, anny_body):
    monkeypatch.chdir(tmp_path)
    for text, message in (('[motions]\nuse = ["arms_forward"]\n[motions.activation]\narms_forward = ["nope"]\n',
                           "arms_forward: unknown clutch 'nope'; the clutches are: upper_back"),
                          ('[clutches]\nlayout = "shirt"\nmodel = "slip"\nholding_force = {nope = 100}\n',
                           "holding_force names unknown clutch(es) ['nope']")):
        (tmp_path / "p.toml").write_text(text)
        rc, _, err = run_cli(["clutches", "show", "p.toml", "--subdivision", "0", "--out", "cs"])
        assert_one_line(rc, err, message)
        assert not (tmp_path / "cs").exists()


def test_clutches_show_never_rewrites_a_runs_clutch_file(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    before = _old_run(tmp_path / "run")
    (tmp_path / "run" / "clutches.toml").write_text("old clutches")
    before["clutches.toml"] = b"old clutches"
    rc, _, err = run_cli(["clutches", "show", "--out", "run", "--force"])
    assert_one_line(rc, err, "is a file of the kgarment run folder")
    assert {p.name: p.read_bytes() for p in (tmp_path / "run").iterdir()} == before


def test_results_are_never_added_to_a_folder_of_another_kind(tmp_path, monkeypatch):
    """simulate's and reproduce's output folders gain files, so neither goes into a design run;
    reproduce not into a folder of the user's either."""
    monkeypatch.chdir(tmp_path)
    before = _old_run(tmp_path / "run")
    _foreign_folder(tmp_path / "mine")
    for argv, message in ((["simulate", "--out", "run"], "is a kgarment run folder, not a simulation folder"),
                          (["reproduce", "--out", "run"], "is a kgarment run folder, not a reproduction folder"),
                          (["reproduce", "--out", "run", "--report-only"], "not a reproduction folder"),
                          (["reproduce", "--out", "mine"], "mine exists and holds files kgarment did not write")):
        rc, _, err = run_cli(argv)
        assert_one_line(rc, err, message)
    assert {p.name: p.read_bytes() for p in (tmp_path / "run").iterdir()} == before
    assert sorted(p.name for p in (tmp_path / "mine").iterdir()) == ["notes.txt", "sub"]


def test_a_problem_or_sweep_file_that_is_not_utf8(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "latin1.toml").write_bytes(b'[garment]\ntemplate = "arm_sleeve.right" # \xff\n')
    rc, _, err = run_cli(["motions", "latin1.toml"])
    assert_one_line(rc, err, "problem file latin1.toml is not UTF-8 text")
    (tmp_path / "s.toml").write_bytes(b'problem = "latin1.toml"\n[grid]\n"design.target_area" = [0.2]\n')
    rc, _, err = run_cli(["sweep", "s.toml", "--dry-run"])
    assert_one_line(rc, err, "latin1.toml is not UTF-8 text")
    (tmp_path / "s2.toml").write_bytes(b'# \xff\nproblem = "latin1.toml"\n')
    rc, _, err = run_cli(["sweep", "s2.toml", "--dry-run"])
    assert_one_line(rc, err, "sweep file s2.toml is not UTF-8 text")


@pytest.mark.parametrize("content, message", [(b"garbage", "is damaged (JSONDecodeError)"),
                                              (b"[]", "is damaged (not a JSON object)"),
                                              (b"{}", "is damaged (no 'resolution')"),
                                              (b'{"resolution": 1, "experiments": []}', "'experiments' is not a table")])
def test_a_damaged_reproduction_data_file(content, message, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "repro").mkdir()
    (tmp_path / "repro" / "data.json").write_bytes(content)
    rc, _, err = run_cli(["reproduce", "--report-only", "--out", "repro"])
    assert_one_line(rc, err, message)
    assert (tmp_path / "repro" / "data.json").read_bytes() == content


def test_simulate_and_render_never_overwrite_the_users_files(tmp_path, monkeypatch):
    """simulate writes into an empty or its own folder only; render replaces pictures only
    with --force; clutches show keeps the user's picture."""
    monkeypatch.chdir(tmp_path)
    (tmp_path / "p.toml").write_text(SLEEVE)
    (tmp_path / "mine").mkdir()
    (tmp_path / "mine" / "arm_flexion.right.png").write_text("mine")
    rc, _, err = run_cli(["simulate", "p.toml", "--out", "mine"])
    assert_one_line(rc, err, "mine exists and holds files kgarment did not write")
    (tmp_path / "mine" / "arm_sleeve.right_rest.png").write_text("mine")
    rc, _, err = run_cli(["render", "p.toml", "--out", "mine"])
    assert_one_line(rc, err, "mine/arm_sleeve.right_rest.png exists; use --force to overwrite it")
    (tmp_path / "mine" / "clutches.png").write_text("mine")
    rc, _, err = run_cli(["clutches", "show", "p.toml", "--out", "mine"])
    assert_one_line(rc, err, "mine/clutches.png exists; use --force")
    assert {p.name: p.read_text() for p in (tmp_path / "mine").iterdir()} == {
        "arm_flexion.right.png": "mine", "arm_sleeve.right_rest.png": "mine", "clutches.png": "mine"}


def test_run_paths_with_an_at_sign(tmp_path, monkeypatch):
    """A run folder whose path holds '@' is taken whole; RUN@K splits at the last '@'."""
    from kgarment.design.run import parse_design_source
    from kgarment.errors import KgarmentError

    monkeypatch.chdir(tmp_path)
    (tmp_path / "v@2").mkdir()
    _old_run(tmp_path / "v@2" / "run")
    assert parse_design_source("v@2/run").run == Path("v@2/run")
    src = parse_design_source("v@2/run@3")
    assert src.run == Path("v@2/run") and src.iteration == 3
    for bad in ("v@2/run@-1", "v@2/run@\u0663"):
        with pytest.raises(KgarmentError, match="must be a whole number from 0"):
            parse_design_source(bad)


def test_a_run_folders_own_files_are_never_overwritten(tmp_path, monkeypatch):
    """--json naming a file of a run folder (its problem.toml) is refused even with --force;
    the run stays usable."""
    monkeypatch.chdir(tmp_path)
    before = _old_run(tmp_path / "run")
    for extra in ([], ["--force"]):
        rc, _, err = run_cli(["evaluate", "norun", "--json", "run/problem.toml", *extra])
        assert_one_line(rc, err, "is a file of the kgarment run folder")
    assert {p.name: p.read_bytes() for p in (tmp_path / "run").iterdir()} == before


@pytest.mark.parametrize("content", [b"", b"PK\x03\x04 truncated", np.random.default_rng(0).bytes(300)],
                         ids=["empty", "truncated", "random"])
def test_damaged_run_files(content, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    run = tmp_path / "run"
    run.mkdir()
    (run / "problem.toml").write_text('[motions]\nuse = ["arms_raise"]\n')
    (run / "problem.txt").write_text("")
    (run / "checkpoint.npz").write_bytes(content)
    (run / "designs.npz").write_bytes(content)
    rc, _, err = run_cli(["design", "--resume", "run"])
    assert_one_line(rc, err, "checkpoint.npz is damaged or not a kgarment checkpoint")
    rc, _, err = run_cli(["evaluate", "run"])
    assert_one_line(rc, err, "designs.npz is damaged or not a kgarment design history")
    rc, _, err = run_cli(["fabricate", "run"])
    assert_one_line(rc, err, "is damaged or not a kgarment")
    assert (run / "checkpoint.npz").read_bytes() == content


def test_crashed_run_says_what_to_do(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "run").mkdir()
    for name in ("problem.toml", "problem.txt"):
        (tmp_path / "run" / name).write_text("")
    rc, _, err = run_cli(["design", "--out", "run"])
    assert_one_line(rc, err, "stopped before its first checkpoint, so there is nothing to resume: use --force")


BAD_MASKS = [
    (np.array([1.5, 2.0]), "must hold face indices (integers)"),
    (np.array([3]), "selects 1 faces of the body; a garment needs at least 20"),
    (np.zeros(0, np.int64), "selects 0 faces"),
    (np.array(["a"]), "must hold face indices"),
]


@pytest.mark.parametrize("mask, message", BAD_MASKS + [(None, "holds no array")],
                         ids=["float", "one face", "empty", "strings", "empty npz"])
def test_bad_garment_mask(mask, message, tmp_path, monkeypatch, anny_body):
    monkeypatch.chdir(tmp_path)
    name = "mask.npz" if mask is None else "mask.npy"
    np.savez(tmp_path / name) if mask is None else np.save(tmp_path / name, mask)
    (tmp_path / "p.toml").write_text(f'[garment]\nmask = "{name}"\nsubdivision = 0\n[motions]\nuse = ["arms_raise"]\n')
    rc, _, err = run_cli(["render", "p.toml", "--out", "pics"])
    assert_one_line(rc, err, message)


@pytest.mark.parametrize("which", ["rest", "motion"])
def test_mesh_with_nan_vertices(which, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    s = trimesh.creation.icosphere(2)
    v = s.vertices.copy()
    bad = v.copy()
    bad[7] = np.nan
    trimesh.Trimesh(bad if which == "rest" else v, s.faces, process=False).export(tmp_path / "rest.ply")
    trimesh.Trimesh(bad if which == "motion" else v * 1.1, s.faces, process=False).export(tmp_path / "m.ply")
    (tmp_path / "p.toml").write_text('[body]\nmodel = "meshes"\nrest = "rest.ply"\nmotions = { m = "m.ply" }\n')
    rc, _, err = run_cli(["render", "p.toml", "--out", "pics"])
    assert_one_line(rc, err, "has 1 vertices with NaN or infinite coordinates (the first: vertex 7)")


WORKER_SCRIPT = """
import os, signal, time
from kgarment.sim import parallel
pool = parallel._pool(2)
for f in [pool.submit(time.sleep, 0.3) for _ in range(4)]:
    f.result()
print(" ".join(str(p) for p in pool._processes), flush=True)
os.kill(os.getpid(), signal.SIGKILL)
"""


def _alive(pid: int) -> bool:
    try:
        with open(f"/proc/{pid}/status") as f:
            return "\nState:\tZ" not in f.read()  # a zombie has exited
    except FileNotFoundError:
        return False


@pytest.mark.skipif(not __import__("sys").platform.startswith("linux"), reason="reads /proc")
def test_workers_die_with_their_parent(tmp_path):
    """SIGKILL of the process that owns the solver pool (no atexit runs) ends its workers."""
    import os
    import signal
    import subprocess
    import sys
    import time

    with open(tmp_path / "pids.txt", "w") as out:  # a file, not a pipe: orphans would hold a pipe open
        r = subprocess.run([sys.executable, "-c", WORKER_SCRIPT], stdout=out, stderr=subprocess.DEVNULL, timeout=120)
    assert r.returncode == -signal.SIGKILL
    pids = [int(p) for p in (tmp_path / "pids.txt").read_text().split()]
    assert len(pids) == 2
    try:
        deadline = time.time() + 10
        while time.time() < deadline and any(_alive(p) for p in pids):
            time.sleep(0.1)
        assert not any(_alive(p) for p in pids), f"workers {pids} outlived their parent"
    finally:
        for p in pids:
            if _alive(p):
                os.kill(p, signal.SIGKILL)


# (the part of a sleeve problem that names a clutch, message): clutch names are known once
# the clutches are built
UNKNOWN_CLUTCH = [
    ('holding_force = { "elbow_outer.L" = 50 }\n',
     "[clutches] holding_force names unknown clutch(es) ['elbow_outer.L']; the clutches are: elbow_outer.R, "
     "elbow_inner.R"),
    ('[motions.activation]\n"arm_flexion.right" = ["elbow_outer.L"]\n',
     "[motions.activation] arm_flexion.right: unknown clutch 'elbow_outer.L'; the clutches are: elbow_outer.R, "
     "elbow_inner.R"),
]


@pytest.mark.parametrize("toml, message", UNKNOWN_CLUTCH, ids=["holding_force", "activation"])
def test_an_unknown_clutch_name(toml, message, tmp_path, monkeypatch, anny_body):
    """One line naming the field and the clutches there are, and no run folder left behind."""
    monkeypatch.chdir(tmp_path)
    (tmp_path / "p.toml").write_text('[garment]\ntemplate = "arm_sleeve.right"\nsubdivision = 0\n'
                                     '[motions]\nuse = ["arm_flexion.right"]\n[clutches]\nlayout = "sleeve"\n' + toml)
    rc, _, err = run_cli(["design", "p.toml", "--out", "run"])
    assert_one_line(rc, err, message)
    assert not (tmp_path / "run").exists()


def test_a_run_designed_under_another_simulation_model_is_not_resumed(tmp_path, monkeypatch):
    """A checkpoint written before the simulation model's version was recorded (model 1:
    the garment started on the body's mesh) is not resumed under model 2: one line, exit
    2, the folder untouched; a checkpoint of this model passes the check."""
    from kgarment.constants import SIM_MODEL
    from kgarment.design.run import check_model, checkpoint_model, save_checkpoint
    from kgarment.optimize.loop import LoopState

    monkeypatch.chdir(tmp_path)
    run = tmp_path / "run"
    run.mkdir()
    (run / "problem.toml").write_text('[motions]\nuse = ["arms_raise"]\n')
    (run / "problem.txt").write_text("")
    save_checkpoint(run, LoopState(iteration=0, design=np.ones(40), target=1.0, alpha_prev=None, warm={}, objectives=(),
                                    reference={}, reference_stored={}, designs=(), metrics=()))
    check_model(run)
    with np.load(run / "checkpoint.npz") as z:
        assert int(z["sim_model"]) == SIM_MODEL
        old = {k: z[k] for k in z.files if k != "sim_model"}
    np.savez(run / "checkpoint.npz", **old)
    assert checkpoint_model(run) == 1
    content = (run / "checkpoint.npz").read_bytes()
    rc, _, err = run_cli(["design", "--resume", "run"])
    assert_one_line(rc, err, f"was designed with simulation model 1 and this kgarment simulates model {SIM_MODEL}")
    assert (run / "checkpoint.npz").read_bytes() == content


def test_loopback_hosts_are_the_machine_itself():
    from kgarment.cli.studio import is_loopback

    assert all(is_loopback(h) for h in ("localhost", "127.0.0.1", "127.1.2.3", "::1"))
    assert not any(is_loopback(h) for h in ("0.0.0.0", "::", "192.168.1.5", "example.org", "10.0.0.1"))
