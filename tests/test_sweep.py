"""``kgarment sweep``: a two-task sweep of the tiny sleeve on a local Ray cluster (each task
an ordinary, evaluable run folder; the table from the runs' evaluations; a rerun skips
both and rewrites nothing), a task that fails is recorded and the sweep goes on, and bad
sweep files are one line, exit 2, before anything is written."""

from __future__ import annotations

import csv
import json
import math
import time

import pytest
from tiny_problems import TINY_SLEEVE

from kgarment.cli import main
from kgarment.sweep import load_sweep, task_name

SLEEVE = TINY_SLEEVE + """[design]
target_area = 0.6
er = 0.15
ar_max = 0.05
max_iterations = 5
"""
AREAS = (0.6, 0.7)
SWEEP = f"""
problem = "sleeve.toml"
[set]
"design.max_iterations" = 4
[grid]
"design.target_area" = [{AREAS[0]}, {AREAS[1]}]
"""


@pytest.fixture(scope="module")
def swept(tmp_path_factory):
    """The sweep run once from the command line on a local Ray cluster of 2 CPUs."""
    tmp = tmp_path_factory.mktemp("sweep")
    (tmp / "sleeve.toml").write_text(SLEEVE)
    (tmp / "sweep.toml").write_text(SWEEP)
    assert main(["-q", "sweep", str(tmp / "sweep.toml"), "--out", str(tmp / "out"), "--workers", "2"]) == 0
    return tmp


def _csv(out):
    with open(out / "sweep.csv") as f:
        return list(csv.DictReader(f))


def test_each_task_is_a_finished_run_of_its_own_problem(swept):
    from kgarment.design import run_status
    from kgarment.problem import load_problem

    out = swept / "out"
    names = [f"target_area={a:g}" for a in AREAS]
    assert sorted(p.name for p in (out / "runs").iterdir()) == names
    for name, area in zip(names, AREAS):
        run = out / "runs" / name
        assert run_status(run) == "finished"
        p = load_problem(run / "problem.toml")
        assert p.design.beso.target_area == area and p.design.beso.max_iterations == 4
        assert p.solver.workers == 1  # one process per task: the sweep runs the tasks side by side
        rows = json.loads((run / "metrics.json").read_text())
        assert 1 <= len(rows) <= 4
        logged = (out / "logs" / f"{name}.log").read_text()
        assert "torch threads 1, OMP_NUM_THREADS 1, MKL_NUM_THREADS 1, OPENBLAS_NUM_THREADS 1" in logged
        assert load_problem(out / "tasks" / f"{name}.toml").design.beso.target_area == area  # runs alone too


def test_the_table_holds_each_run_s_evaluation(swept):
    out = swept / "out"
    rows = _csv(out)
    assert [float(r["design.target_area"]) for r in rows] == list(AREAS)
    for r in rows:
        ev = json.loads((out / "runs" / r["task"] / "final" / "evaluation.json").read_text())
        assert r["status"] == "finished" and not r["error"]
        m = "arm_flexion.right"
        for s in ("on", "off"):
            assert math.isfinite(float(r[f"rho_{s}[{m}]"])) and float(r[f"rho_{s}[{m}]"]) == ev["rho"][m][s]
        # the final design meets its target area within one BESO update's faces (ar_max)
        assert abs(float(r["area"]) - float(r["design.target_area"])) <= 0.05 + 1e-9
        assert int(r["best_iteration"]) == ev["iteration"] < int(r["iterations"]) <= 4
        assert 0 <= int(r["ends_supported"]) <= int(r["ends"]) == 2  # one clutch, two ends
        c = ev["clutches"][0]
        assert float(r[f"tension_N[{m}:{c['clutch']}]"]) == c["tension_N"] and float(r["wall_s"]) > 0
    md = (out / "sweep.md").read_text()
    assert all(f"| {r['task']} |" in md for r in rows)
    assert (out / "sweep.png").stat().st_size > 10_000


def test_the_runs_are_ordinary_run_folders(swept, capsys):
    """``kgarment evaluate`` works on a sweep's run and gives its table's rho (one evaluator)."""
    out = swept / "out"
    for r in _csv(out):
        js = swept / f"{r['task']}.json"
        assert main(["-q", "evaluate", str(out / "runs" / r["task"]), "--no-loads", "--json", str(js)]) == 0
        rho = json.loads(js.read_text())["rho"]["arm_flexion.right"]
        assert rho["on"] == pytest.approx(float(r["rho_on[arm_flexion.right]"]), rel=1e-3)
    capsys.readouterr()


def test_a_rerun_skips_finished_runs_and_rewrites_nothing(swept, monkeypatch, capsys):
    from kgarment.sweep import execute

    out = swept / "out"
    before = {p: p.stat().st_mtime_ns for p in out.rglob("*") if p.is_file()}

    def no_ray():
        raise AssertionError("a sweep of finished runs starts no Ray")

    monkeypatch.setattr(execute, "import_ray", no_ray)
    t0 = time.time()
    assert main(["sweep", str(swept / "sweep.toml"), "--out", str(out)]) == 0
    assert time.time() - t0 < 20
    assert "0 ran, 2 skipped, 0 failed" in capsys.readouterr().out
    assert {p: p.stat().st_mtime_ns for p in out.rglob("*") if p.is_file()} == before


def test_a_changed_sweep_is_refused_over_the_folder(swept, capsys):
    out = swept / "out"
    other = swept / "other.toml"
    other.write_text(SWEEP.replace("[set]", "[set]\n\"design.er\" = 0.2"))
    before = {p: p.stat().st_mtime_ns for p in out.rglob("*") if p.is_file()}
    assert main(["sweep", str(other), "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "2 changed (target_area=0.6, target_area=0.7)" in err and "--force" in err
    assert {p: p.stat().st_mtime_ns for p in out.rglob("*") if p.is_file()} == before
    # comments and spacing are no change
    same = swept / "same.toml"
    same.write_text("# the same sweep\n" + SWEEP.replace(" = ", "="))
    assert main(["-q", "sweep", str(same), "--out", str(out)]) == 0


def test_a_failing_task_is_recorded_and_the_sweep_goes_on(tmp_path, capsys):
    """A user error found only when the task runs (a garment mask's face indices are checked
    against the body, which only the task builds) fails that task: exit 1, its row says why."""
    (tmp_path / "sleeve.toml").write_text(SLEEVE)
    (tmp_path / "mask.txt").write_text("0\n99999999\n")
    (tmp_path / "bad.toml").write_text('problem = "sleeve.toml"\n[[runs]]\nname = "nope"\n'
                                       '"garment.mask" = "mask.txt"\n')
    assert main(["-q", "sweep", str(tmp_path / "bad.toml"), "--out", str(tmp_path / "out"), "--workers", "1"]) == 1
    (row,) = _csv(tmp_path / "out")
    assert row["task"] == "nope" and row["status"] == "failed" and "face indices outside" in row["error"]
    assert "face indices outside" in (tmp_path / "out" / "sweep.md").read_text()
    capsys.readouterr()


def test_dry_run_checks_activation_clutch_names(tmp_path, capsys):
    """An activation naming no clutch of the task's layout is refused before anything runs,
    --dry-run included, naming the task, the motion and the clutches there are."""
    (tmp_path / "sleeve.toml").write_text(SLEEVE)
    (tmp_path / "bad.toml").write_text('problem = "sleeve.toml"\n[[runs]]\nname = "nope"\n'
                                       '"motions.activation"."arm_flexion.right" = ["no_such_clutch"]\n')
    for extra in (["--dry-run"], []):
        assert main(["sweep", str(tmp_path / "bad.toml"), "--out", str(tmp_path / "out"), *extra]) == 2
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and "task 'nope'" in err and "unknown clutch 'no_such_clutch'" in err
        assert "the clutches are: elbow_outer.R" in err
    assert not (tmp_path / "out").exists()


BASE = 'problem = "sleeve.toml"\n'


@pytest.mark.parametrize("text, message", [
    (BASE + '[grid]\n"design.budget" = [0.1, 0.2]\n',
     '[grid] "design.budget" = 0.1: [design]: unknown field \'budget\'; allowed: '),
    (BASE + '[grid]\n"body.phenotype.weight" = [0.3, 2.0]\n',
     '[grid] "body.phenotype.weight" = 2.0: phenotype weight = 2.0 is outside [0, 1]'),
    (BASE + '[grid]\n"body.phenotype.waist" = [0.3]\n', "unknown phenotype parameter 'waist'"),
    (BASE + '[grid]\n"design.target_area" = []\n', '[grid] "design.target_area" = [] is empty'),
    (BASE + '[grid]\n"design.target_area" = 0.2\n', "must be a list of values (an axis)"),
    (BASE + '[grid]\n"materials.preset" = ["paper", "steel"]\n', "preset = 'steel'; allowed: paper, reference"),
    (BASE + '[grid]\n"solver.workers" = [1, 2]\n', "give kgarment sweep --workers N instead"),
    ('problem = "missing.toml"\n[grid]\n"design.target_area" = [0.2]\n', "problem file not found"),
    ('example = "no_such_example"\n[grid]\n"design.target_area" = [0.2]\n', "unknown example 'no_such_example'"),
    ('[grid]\n"design.target_area" = [0.2]\n', "give one base problem"),
    (BASE, "give the variations as [grid]"),
    (BASE + '[[runs]]\nname = "a"\n[[runs]]\nname = "a"\n"design.er" = 0.2\n', "two tasks are named 'a'"),
    (BASE + '[[runs]]\nname = "../up"\n', "must be a folder name"),
    (BASE + 'budget = 3\n[grid]\n"design.target_area" = [0.2]\n', "unknown field 'budget'; allowed: problem"),
])
def test_bad_sweep_files(tmp_path, capsys, text, message):
    (tmp_path / "sleeve.toml").write_text(SLEEVE)
    (tmp_path / "s.toml").write_text(text)
    assert main(["sweep", str(tmp_path / "s.toml"), "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("kgarment: error: sweep file") and message in err, err
    assert not (tmp_path / "out").exists()  # nothing written


def test_without_ray_one_line(tmp_path, capsys, monkeypatch):
    import sys

    monkeypatch.setitem(sys.modules, "ray", None)  # import ray -> ImportError
    (tmp_path / "sleeve.toml").write_text(SLEEVE)
    (tmp_path / "s.toml").write_text(SWEEP)
    assert main(["sweep", str(tmp_path / "s.toml"), "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "pip install 'kgarment[sweep]'" in err
    assert not (tmp_path / "out").exists()


def test_grid_and_runs_expand(tmp_path):
    """Nested tables and dotted keys name the same fields; the grid is the cartesian
    product in axis order; [set] applies to every task; names are readable and safe."""
    (tmp_path / "sleeve.toml").write_text(SLEEVE)
    (tmp_path / "a.toml").write_text(BASE + '[set]\n"design.max_iterations" = 3\n[grid]\n'
                                     '"design.target_area" = [0.6, 0.7]\nbody.phenotype.weight = [0.3, 0.7, 0.9]\n')
    sw = load_sweep(tmp_path / "a.toml")
    assert sw.axes == ("design.target_area", "body.phenotype.weight")
    assert [t.name for t in sw.tasks][:3] == ["target_area=0.6,weight=0.3", "target_area=0.6,weight=0.7",
                                              "target_area=0.6,weight=0.9"]
    assert len(sw.tasks) == 2 * 3
    assert all(t.problem.design.beso.max_iterations == 3 and t.problem.solver.workers == 1 for t in sw.tasks)
    assert {(t.problem.design.beso.target_area, t.problem.body.phenotype.weight) for t in sw.tasks} == \
        {(a, w) for a in (0.6, 0.7) for w in (0.3, 0.7, 0.9)}
    (tmp_path / "b.toml").write_text(BASE + '[[runs]]\nname = "ref"\nmaterials.preset = "reference"\n'
                                     '[[runs]]\n"design.target_area" = 0.5\n')
    sw = load_sweep(tmp_path / "b.toml")
    assert [t.name for t in sw.tasks] == ["ref", "target_area=0.5"]
    assert sw.axes == ("materials.preset", "design.target_area")


def test_task_names():
    assert task_name([(("design", "target_area"), 0.1)], [("design", "target_area")]) == "target_area=0.1"
    axes = [("a", "x"), ("b", "x")]  # the same last part: one more part each
    assert task_name([(axes[0], 1), (axes[1], 2)], axes) == "a.x=1,b.x=2"
    assert task_name([(("motions", "use"), ["arms_forward", "arms_raise"])], [("motions", "use")]) == \
        "use=arms_forward+arms_raise"
    assert task_name([(("g", "t"), "a/b c")], [("g", "t")]) == "t=a_b_c"  # no separators, no spaces
    long = task_name([(("g", "t"), "x" * 300)], [("g", "t")])
    assert len(long) == 100 and long != task_name([(("g", "t"), "x" * 301)], [("g", "t")])
    assert task_name([], []) == "base"


def test_the_shipped_sweep_examples_parse(capsys):
    from kgarment.problem import examples_dir

    files = sorted((examples_dir() / "sweeps").glob("*.toml"))
    assert files
    for f in files:
        sw = load_sweep(f)
        assert sw.tasks and all(t.problem.solver.workers == 1 for t in sw.tasks)
    assert main(["examples"]) == 0
    assert "sweep files" in capsys.readouterr().out


def test_help_does_not_import_ray():
    """Ray is an optional extra, imported only when a sweep runs tasks."""
    import subprocess
    import sys

    code = ("import sys; from kgarment.cli import build_parser; build_parser().format_help(); "
            "print('ray' in sys.modules, 'kgarment.sweep' in sys.modules)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.split() == ["False", "False"]


def test_dry_run_refuses_what_the_run_would(tmp_path, capsys):
    """--dry-run checks --out as the sweep itself does: a file, a folder of the user's."""
    (tmp_path / "sleeve.toml").write_text(SLEEVE)
    (tmp_path / "s.toml").write_text(SWEEP)
    (tmp_path / "afile").write_text("mine")
    (tmp_path / "mine").mkdir()
    (tmp_path / "mine" / "notes.txt").write_text("mine")
    for out, message in (("afile", "is a file, not a folder"), ("mine", "a folder of files kgarment did not write")):
        assert main(["sweep", str(tmp_path / "s.toml"), "--out", str(tmp_path / out), "--dry-run"]) == 2
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and message in err, err
    assert (tmp_path / "afile").read_text() == "mine" and [p.name for p in (tmp_path / "mine").iterdir()] == ["notes.txt"]
