"""The studio's page logic with a live server but no browser: simulations, optimisation,
runs, failures that keep every edit, and the ``kgarment studio`` command."""

from __future__ import annotations

import dataclasses
import re
import signal
import socket
import subprocess
import sys
import time
import urllib.request

import numpy as np
import pytest

pytest.importorskip("viser")

from kgarment.errors import KgarmentError
from kgarment.studio.session import Opened


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def problem():
    from kgarment.problem import GarmentSpec, Problem, SolverSpec

    return Problem(motions=("arm_flexion.right",), garment=GarmentSpec("arm_sleeve.right", subdivision=0),
                   solver=SolverSpec(preset="reference"))


@pytest.fixture()
def studio(anny_body, tmp_path):
    from kgarment.studio.app import Studio

    s = Studio(Opened("default", problem()), port=free_port(), session=tmp_path / "session",
               runs=tmp_path / "runs", body=anny_body)
    yield s
    s.stop()


def paint(studio, faces=(200, 300), radius=0.03):
    studio.settings.tool, studio.settings.radius = "paint reinforcement", radius
    for f in faces:
        studio.click_face(f)


def last(studio):
    return studio.messages[-1]


def test_failed_jobs_keep_every_edit(studio, monkeypatch):
    import kgarment.studio.evaluate as ev
    import kgarment.studio.optimise as op

    paint(studio)
    design, rev = studio.state.design.copy(), studio.state.revision

    def explode(*a, **k):
        raise RuntimeError("the solver exploded")

    monkeypatch.setattr(ev, "evaluate", explode)
    job = studio.simulate("A")
    assert job.wait(30) and job.status == "failed"
    assert last(studio) == ("simulation failed: RuntimeError: the solver exploded", True)
    monkeypatch.setattr(op, "run_optimisation", lambda *a, **k: (_ for _ in ()).throw(KgarmentError("no budget")))
    job = studio.optimise()
    assert job.wait(30) and job.status == "failed" and last(studio) == ("optimisation failed: no budget", True)
    assert "Error" in studio.panel.message.content
    assert np.array_equal(studio.state.design, design) and studio.state.revision == rev and studio.state.dirty


def test_bad_input_is_a_message_and_changes_nothing(studio, tmp_path):
    from test_studio import fake_run

    st = studio.state
    paint(studio)
    rev = st.revision
    studio.guarded(studio.click_ray, (0.0, -5.0, 3.0), (0.0, 0.0, 1.0))  # into the sky
    assert "not on the garment" in last(studio)[0]
    studio.settings.tool = "move clutch"
    studio.guarded(studio.click_face, 10)
    assert "select a clutch first" in last(studio)[0]
    studio.guarded(studio.simulate, "B")
    assert "no design B" in last(studio)[0]
    studio.guarded(studio.stop_optimisation)
    assert "no optimisation" in last(studio)[0]
    studio.guarded(studio.add_clutch_at_landmarks, "upper_back", "chest")
    assert "from the garment" in last(studio)[0]
    (tmp_path / "bad.toml").write_text("[garment\n")
    studio.guarded(studio.open, str(tmp_path / "bad.toml"))
    assert "unsaved changes" in last(studio)[0]  # first press: a warning
    studio.guarded(studio.open, str(tmp_path / "bad.toml"))
    assert "not valid TOML" in last(studio)[0] and last(studio)[1]
    other = dataclasses.replace(problem(), garment=dataclasses.replace(problem().garment, subdivision=1))
    fake_run(tmp_path / "run1", other, np.ones((2, 2252), bool))
    studio.guarded(studio.open_run, str(tmp_path / "run1"))
    assert "subdivision 1" in last(studio)[0] and studio.run is None
    studio.guarded(studio.load_b, str(tmp_path / "run1"))
    assert "subdivision 1" in last(studio)[0] and studio.compare is None
    assert studio.state is st and st.revision == rev and st.dirty


def test_select_move_aim_delete_undo(studio):
    st = studio.state
    strip = st.strips()[0]
    face = int(strip.bind_face[strip.centerline[0]])
    studio.settings.tool = "select"
    studio.click_face(face)
    assert studio.selected == strip.name and studio.panel.clutch.value == strip.name
    assert studio.panel.length.value == pytest.approx(strip.length)
    studio.edit_selected(length=0.05)
    assert st.clutch(strip.name).length == 0.05
    before = st.strips()[0].vertices[0].copy()
    studio.settings.tool = "move clutch"
    studio.click_face(face + 4)
    assert not np.allclose(st.strips()[0].vertices[0], before)
    studio.delete_selected()
    assert strip.name not in st.clutch_names() and studio.selected is None
    studio.undo()
    assert strip.name in st.clutch_names()
    studio.settings.tool = "place clutch"
    studio.click_face(100)
    assert studio.pending_start is not None
    studio.click_face(102)
    assert studio.pending_start is None and studio.selected == "clutch"


def test_simulate_compare_and_colour(studio):
    st = studio.state
    paint(studio, faces=(100, 200, 300, 400, 500), radius=0.04)
    job = studio.simulate("A")
    assert job.wait(240) and job.status == "done", job.message
    rows = studio.eval_a.rows
    assert [(r["motion"], r["state"]) for r in rows] == [("arm_flexion.right", "on"), ("arm_flexion.right", "off")]
    assert all(np.isfinite(r["rho"]) and r["rho"] > 0 for r in rows)
    assert "rho A" in studio.panel.results.content
    studio.settings.motion, studio.settings.mode = "arm_flexion.right", "energy density"
    studio.redraw()
    assert "J/m" in studio.panel.legend.content
    # the shown garment is the simulated equilibrium, not the skin-tight pose
    assert not np.allclose(studio.garment_positions(), st.base_garment.vertices("arm_flexion.right"))
    studio.pin_as_b()
    assert studio.eval_b is not None and "rho B" in studio.panel.results.content
    paint(studio, faces=(50,))
    assert "before the latest edits" in studio.panel.results.content
    studio.settings.mode = "compare"
    colors, legend = studio.garment_colors()
    assert "A only" in legend and colors.shape == (st.n_faces, 3)


def test_optimise_scrub_export_and_reopen(studio, tmp_path):
    from kgarment.simulate import load_design

    run = tmp_path / "runs" / "r1"
    job = studio.optimise(str(run), max_iterations=2)
    assert job.wait(300) and job.status == "done", job.message
    assert studio.run.n_iterations == 2 and studio.run_k == 1 and studio.settings.mode == "run"
    # only the problem's motions, although the shared test body is posed in more
    assert {k for k in studio.run.metrics[0] if k.startswith("rho[")} == {
        "rho[arm_flexion.right:on]", "rho[arm_flexion.right:off]"}
    assert (run / "checkpoint.npz").is_file() and (run / "final" / "design.npz").is_file()
    assert studio.panel.plot.image.shape[2] == 3
    studio.show_iteration(0)
    studio.use_iteration()
    assert studio.state.design.all()  # iteration 0 is the fully reinforced garment
    studio.undo()
    assert not studio.state.design.any()
    studio.show_iteration(1)
    out = studio.export_iteration(str(tmp_path / "it1"))
    assert np.array_equal(load_design(out, studio.state.n_faces) > 0.5, studio.run.design(1))
    assert np.array_equal(load_design(f"{run}@1", studio.state.n_faces), load_design(out, studio.state.n_faces))
    studio.use_iteration(as_b=True)
    assert studio.compare[0] == "r1@1"
    studio.save()
    studio.open(str(tmp_path / "session"))
    assert studio.run is not None and studio.run.folder == run and studio.compare[0] == "r1@1"
    studio.open(str(run))  # a run folder opens as a problem with its last design
    assert np.array_equal(studio.state.design, load_design(out, studio.state.n_faces) > 0.5)


def test_cli_serves_the_page(tmp_path, anny_body):
    """``kgarment studio`` prints the URL, serves the page, and stops on Ctrl-C."""
    (tmp_path / "p.toml").write_text('[garment]\ntemplate = "arm_sleeve.right"\nsubdivision = 0\n'
                                     '[motions]\nuse = ["arm_flexion.right"]\n')
    port = free_port()
    code = ("import argparse, sys\nfrom kgarment.cli_studio import add_parser\n"
            "ap = argparse.ArgumentParser(); sub = ap.add_subparsers()\n"
            "def common(sp):\n    sp.add_argument('problem', nargs='?'); sp.add_argument('--device', default='cpu')\n"
            "add_parser(sub, common)\nargs = ap.parse_args(sys.argv[1:])\nsys.exit(args.func(args))\n")
    # the default SIGINT disposition in the child: a test run started in the background
    # (nohup make test &) inherits SIGINT ignored, and Python then never raises KeyboardInterrupt
    proc = subprocess.Popen([sys.executable, "-c", code, "studio", "p.toml", "--port", str(port)], cwd=tmp_path,
                            stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
                            preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    try:
        url, lines = None, []
        t0 = time.time()
        while url is None and time.time() - t0 < 120:
            line = proc.stdout.readline()
            if not line:
                break
            lines.append(line)
            m = re.search(r"open (http://127\.0\.0\.1:\d+)", line)
            url = m.group(1) if m else None
        assert url == f"http://127.0.0.1:{port}", "".join(lines)
        html = urllib.request.urlopen(url, timeout=10).read().decode()
        assert "<html" in html.lower()
    finally:
        proc.send_signal(signal.SIGINT)
        rest, _ = proc.communicate(timeout=60)  # keep reading: a full pipe would block the server's exit
        rc = proc.returncode
    assert rc == 0, "".join(lines) + rest
    bad = subprocess.run([sys.executable, "-c", code, "studio", "missing.toml"], cwd=tmp_path,
                         capture_output=True, text=True, check=False)
    assert bad.returncode == 1 and "not found" in bad.stderr


def test_studio_rho_equals_kgarment_evaluate(anny_body):
    """The studio's simulation gives the numbers of ``kgarment evaluate`` (same solves)."""
    from kgarment.cli_design import evaluate_design
    from kgarment.problem import build_clutches
    from kgarment.studio.evaluate import evaluate
    from kgarment.studio.session import build_state

    p = problem()
    p = dataclasses.replace(p, design=dataclasses.replace(p.design, objective="compliance"))
    st = build_state(Opened("problem", p), anny_body)
    d = np.zeros(st.n_faces, bool)
    d[::3] = True
    mine = evaluate(p, st.body, st.garment, build_clutches(p, st.body, st.base_garment), d)
    theirs = evaluate_design(p, st.design_values(d))
    assert [(r["motion"], r["state"]) for r in mine.rows] == [(r["motion"], r["state"]) for r in theirs]
    for a, b in zip(mine.rows, theirs):
        assert a["rho"] == pytest.approx(b["rho"], rel=1e-6)
        assert a["energy_full"] == pytest.approx(b["energy_full"], rel=1e-6)
