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
import urllib.error
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
    from kgarment.problem import GarmentSpec, MaterialSpec, Problem

    return Problem(motions=("arm_flexion.right",), garment=GarmentSpec("arm_sleeve.right", subdivision=0),
                   materials=MaterialSpec(preset="reference"))


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
        studio.edit.click_face(f)


def last(studio):
    return studio.messages[-1]


def test_failed_jobs_keep_every_edit(studio, monkeypatch):
    import kgarment.studio.optimise as op
    import kgarment.studio.simulations as sim

    paint(studio)
    design, rev = studio.state.design.copy(), studio.state.revision

    def explode(*a, **k):
        raise RuntimeError("the solver exploded")

    monkeypatch.setattr(sim, "simulate_design", explode)
    job = studio.sims.simulate("A")
    assert job.wait(30) and job.status == "failed"
    assert last(studio) == ("simulation failed: RuntimeError: the solver exploded", True)
    monkeypatch.setattr(op, "run_design", lambda *a, **k: (_ for _ in ()).throw(KgarmentError("no budget")))
    job = studio.optimiser.optimise()
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
    studio.guarded(studio.edit.click_face, 10)
    assert "select a clutch first" in last(studio)[0]
    studio.guarded(studio.sims.simulate, "B")
    assert "no design B" in last(studio)[0]
    studio.guarded(studio.optimiser.stop)
    assert "no optimisation" in last(studio)[0]
    studio.guarded(studio.edit.add_clutch_at_landmarks, "upper_back", "chest")
    assert "from the garment" in last(studio)[0]
    (tmp_path / "runs").mkdir()  # the page reads under the studio's folders (--runs here)
    (tmp_path / "runs" / "bad.toml").write_text("[garment\n")
    studio.guarded(studio.open, str(tmp_path / "runs" / "bad.toml"))
    assert "unsaved changes" in last(studio)[0]  # first press: a warning
    studio.guarded(studio.open, str(tmp_path / "runs" / "bad.toml"))
    assert "not valid TOML" in last(studio)[0] and last(studio)[1]
    other = dataclasses.replace(problem(), garment=dataclasses.replace(problem().garment, subdivision=1))
    fake_run(tmp_path / "runs" / "run1", other, np.ones((2, 2252), bool))
    studio.guarded(studio.optimiser.open, str(tmp_path / "runs" / "run1"))
    assert "subdivision 1" in last(studio)[0] and studio.optimiser.run is None
    studio.guarded(studio.sims.load_b, str(tmp_path / "runs" / "run1"))
    assert "subdivision 1" in last(studio)[0] and studio.sims.design_b is None
    assert studio.state is st and st.revision == rev and st.dirty


def test_select_move_aim_delete_undo(studio):
    st, edit = studio.state, studio.edit
    strip = st.strips()[0]
    face = int(strip.bind_face[strip.centerline[0]])
    studio.settings.tool = "select"
    edit.click_face(face)
    assert edit.selected == strip.name and studio.panel.clutch.value == strip.name
    assert studio.panel.length.value == pytest.approx(strip.length)
    edit.edit_selected(length=0.05)
    assert st.clutch(strip.name).length == 0.05
    before = st.strips()[0].vertices[0].copy()
    studio.settings.tool = "move clutch"
    edit.click_face(face + 4)
    assert not np.allclose(st.strips()[0].vertices[0], before)
    edit.delete_selected()
    assert strip.name not in st.clutch_names() and edit.selected is None
    edit.undo()
    assert strip.name in st.clutch_names()
    studio.settings.tool = "place clutch"
    edit.click_face(100)
    assert edit.pending_start is not None
    edit.click_face(102)
    assert edit.pending_start is None and edit.selected == "clutch"


def test_simulate_compare_and_colour(studio):
    st = studio.state
    paint(studio, faces=(100, 200, 300, 400, 500), radius=0.04)
    job = studio.sims.simulate("A")
    assert job.wait(240) and job.status == "done", job.message
    rows = studio.sims.a.rows
    assert [(r["motion"], r["state"]) for r in rows] == [("arm_flexion.right", "on"), ("arm_flexion.right", "off")]
    assert all(np.isfinite(r["rho"]) and r["rho"] > 0 for r in rows)
    assert "rho A" in studio.panel.results.content
    # the load each clutch carries, as in kgarment evaluate
    loads = studio.sims.a.loads
    assert {r["clutch"] for r in loads} == set(st.clutch_names()) and all(np.isfinite(r["tension_N"]) for r in loads)
    assert "share / needed A / N" in studio.panel.results.content
    studio.settings.motion, studio.settings.mode = "arm_flexion.right", "energy density"
    studio.redraw()
    assert "J/m" in studio.panel.legend.content
    # the shown garment is the simulated equilibrium, not the skin-tight pose
    assert not np.allclose(studio.garment_positions(), st.base_garment.vertices("arm_flexion.right"))
    studio.sims.pin_as_b()
    assert studio.sims.b is not None and "rho B" in studio.panel.results.content
    paint(studio, faces=(50,))
    assert "before the latest edits" in studio.panel.results.content
    studio.settings.mode = "compare"
    colors, legend = studio.garment_colors()
    assert "A only" in legend and colors.shape == (st.n_faces, 3)


def test_force_over_the_motion_on_the_painted_garment(studio):
    """The page's force over the motion is ``evaluate --path``'s on the studio's own garment:
    frames from rest ON and OFF, the work counted from rest, a picture and a table; with
    the attachments painted away from the cuff, the frames hold the painted faces."""
    from kgarment.evaluate.path import PathReport

    st = studio.state
    paint(studio, faces=(100, 200, 300, 400, 500), radius=0.04)
    with pytest.raises(KgarmentError, match="frames from rest"):
        studio.sims.force_path(0)
    job = studio.sims.force_path(2)
    assert job.wait(300) and job.status == "done", job.message
    label, revision, rep = studio.sims.path
    assert isinstance(rep, PathReport) and label == "A" and revision == st.revision
    assert sorted({(f.state, f.t) for f in rep.frames}) == [("off", 0.0), ("off", 0.5), ("off", 1.0),
                                                             ("on", 0.0), ("on", 0.5), ("on", 1.0)]
    row = rep.summary()[0]  # the first clutch; the work is per motion
    on = {f.t: f.energy_J for f in rep.curve("arm_flexion.right", "on")}
    assert row["work_on_J"] == pytest.approx(on[1.0] - on[0.0])
    assert "Force over the motion, design A" in studio.panel.path_results.content
    assert studio.panel.sim_status.content == ""  # the last "frame 2/2" line went with the job
    assert studio.panel.path_plot.image.shape[0] > 100 and studio.panel.path_plot.image.std() > 0
    assert "path" in studio.sims.to_json()
    paint(studio, faces=(50,))
    assert "before the latest edits" in studio.panel.path_results.content


def test_the_motion_frames_take_the_painted_attachments(studio):
    from kgarment.case.frames import REST, frame_motions

    st = studio.state
    attached = np.zeros(st.n_faces, bool)
    attached[:40] = True
    motions, _ = frame_motions(st.problem, ["arm_flexion.right"], 1, rest=True, attached=attached)
    assert set(motions[REST].attach_faces) == set(np.flatnonzero(attached))
    with pytest.raises(KgarmentError, match="attachment flags"):
        frame_motions(st.problem, ["arm_flexion.right"], 1, attached=attached[:-1])


def test_one_evaluator_per_configuration(studio):
    """Edits of the design or the budget keep the evaluator (and the fully reinforced
    equilibria it holds); other attachments make another one. Evaluations solve to
    min([solver] tol, 1e-4)."""
    from kgarment.studio.simulations import SimInputs

    sims, st = studio.sims, studio.state
    first = sims.evaluator(SimInputs.of(st))
    assert first.case.solver.tol == min(st.problem.solver.tol, 1e-4)
    paint(studio)
    st.set_budget(0.3)
    assert sims.evaluator(SimInputs.of(st)) is first
    studio.settings.tool = "erase attachments"
    studio.edit.click_face(int(np.flatnonzero(st.attached)[0]))
    assert sims.evaluator(SimInputs.of(st)) is not first
    st.undo()
    assert sims.evaluator(SimInputs.of(st)) is first


def test_optimise_scrub_export_and_reopen(studio, tmp_path):
    from kgarment.design import load_design

    opt = studio.optimiser
    run = tmp_path / "runs" / "r1"
    job = opt.optimise("r1", max_iterations=2)  # a name: under the studio's --runs folder
    assert job.wait(300) and job.status == "done", job.message
    assert opt.run.n_iterations == 2 and opt.k == 1 and studio.settings.mode == "run"
    # only the problem's motions, although the shared test body is posed in more
    assert {k for k in opt.run.metrics[0] if k.startswith("rho[")} == {
        "rho[arm_flexion.right:on]", "rho[arm_flexion.right:off]"}
    assert (run / "checkpoint.npz").is_file() and (run / "final" / "design.npz").is_file()
    assert studio.panel.plot.image.shape[2] == 3
    opt.show_iteration(0)
    opt.use_iteration()
    assert studio.state.design.all()  # iteration 0 is the fully reinforced garment
    studio.edit.undo()
    assert not studio.state.design.any()
    opt.show_iteration(1)
    out = str(opt.export_iteration("it1"))
    assert out == str(tmp_path / "runs" / "exports" / "it1.npz")
    assert np.array_equal(load_design(out, studio.state.n_faces) > 0.5, opt.run.design(1))
    assert np.array_equal(load_design(f"{run}@1", studio.state.n_faces), load_design(out, studio.state.n_faces))
    opt.use_iteration(as_b=True)
    assert studio.sims.design_b.label == "r1@1"
    studio.save()
    studio.open(str(tmp_path / "session"))
    assert opt.run is not None and opt.run.folder == run and studio.sims.design_b.label == "r1@1"
    studio.open(str(run))  # a run folder opens as a problem with its last design
    assert np.array_equal(studio.state.design, load_design(out, studio.state.n_faces) > 0.5)


def test_stopped_optimisation_resumes_on_the_command_line_with_its_attachments(studio, tmp_path):
    """A run started in the page and stopped there continues with ``kgarment design
    --resume``, on the painted attachments (the driver reads attachments.npz back)."""
    from kgarment.design import load_design_history, open_run, run_status

    studio.settings.tool, studio.settings.radius = "erase attachments", 0.03
    st = studio.state
    ring = np.flatnonzero(st.attached)
    studio.edit.click_face(int(ring[0]))
    painted = st.attached.copy()
    assert 0 < painted.sum() < st.base_garment.attached.sum()
    run = tmp_path / "runs" / "stopped"
    job = studio.optimiser.optimise("stopped", max_iterations=2)
    job.cancel()  # checked after every iteration: the run stops after iteration 0
    assert job.wait(300) and job.status == "cancelled", job.message
    assert "kgarment design --resume" in last(studio)[0]
    assert run_status(run) == "unfinished" and (run / "attachments.npz").is_file()
    dr = open_run(None, run, resume=True)
    assert np.array_equal(dr.garment.attached, painted) and dr.state.iteration == 1
    done = subprocess.run([sys.executable, "-m", "kgarment.cli", "--quiet", "design", "--resume", str(run)],
                          capture_output=True, text=True, check=False)
    assert done.returncode == 0, done.stdout + done.stderr
    assert run_status(run) == "finished" and len(load_design_history(run)) == 2


def test_cli_serves_the_page(tmp_path, anny_body):
    """``kgarment studio`` prints the URL, serves the page, and stops on Ctrl-C."""
    (tmp_path / "p.toml").write_text('[garment]\ntemplate = "arm_sleeve.right"\nsubdivision = 0\n'
                                     '[motions]\nuse = ["arm_flexion.right"]\n')
    port = free_port()
    cmd = [sys.executable, "-m", "kgarment.cli", "studio"]
    # the default SIGINT disposition in the child: a test run started in the background
    # (nohup make test &) inherits SIGINT ignored, and Python then never raises KeyboardInterrupt
    proc = subprocess.Popen(cmd + ["p.toml", "--port", str(port)], cwd=tmp_path,
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
            m = re.search(r"open (http://127\.0\.0\.1:\d+/\?token=\S+) in a browser", line)
            url = m.group(1) if m else None
        assert url is not None and url.startswith(f"http://127.0.0.1:{port}/?token="), "".join(lines)
        with pytest.raises(urllib.error.HTTPError, match="403"):  # the page without the token
            urllib.request.urlopen(f"http://127.0.0.1:{port}/", timeout=10)
        browser = urllib.request.build_opener(urllib.request.HTTPCookieProcessor())  # keeps the token's cookie
        html = browser.open(url, timeout=10).read().decode()
        assert "<html" in html.lower()
    finally:
        proc.send_signal(signal.SIGINT)
        rest, _ = proc.communicate(timeout=60)  # keep reading: a full pipe would block the server's exit
        rc = proc.returncode
    assert rc == 0, "".join(lines) + rest
    bad = subprocess.run(cmd + ["missing.toml"], cwd=tmp_path, capture_output=True, text=True, check=False)
    assert bad.returncode == 2 and "not found" in bad.stderr  # a user error: one line, status 2
    assert len(bad.stderr.strip().splitlines()) == 1, bad.stderr


def test_cli_overrides_cannot_change_the_garment_of_a_session(studio, tmp_path):
    """--subdivision/--garment on a session with a design: a one-line error; on its
    problem file they apply."""
    from kgarment.studio import read_source

    paint(studio)
    studio.save()
    opened = read_source(tmp_path / "session")
    with pytest.raises(KgarmentError, match="cannot change the garment of a session"):
        opened.with_overrides(subdivision=1)
    assert opened.with_overrides(motions=["arm_flexion.right"]).problem == opened.problem
    p = read_source(tmp_path / "session" / "problem.toml").with_overrides(subdivision=1).problem
    assert p.garment.subdivision == 1


def test_studio_rho_equals_kgarment_evaluate(anny_body):
    """The studio's simulation (one state at a time, its own garment and clutch strips)
    gives the numbers of ``kgarment evaluate`` (all states together, built from the problem)."""
    from kgarment.case.values import design_values
    from kgarment.evaluate import Evaluator
    from kgarment.studio.session import build_state
    from kgarment.studio.simulations import SimInputs, simulate_design

    p = problem()
    p = dataclasses.replace(p, design=dataclasses.replace(p.design, objective="compliance"))
    st = build_state(Opened("problem", p), anny_body)
    d = np.zeros(st.n_faces, bool)
    d[::3] = True
    mine = simulate_design(SimInputs.of(st).evaluator(), d, p.motions)
    theirs = Evaluator.from_problem(p).evaluate(design_values(d)).states
    assert [(r["motion"], r["state"]) for r in mine.rows] == [(r.motion, r.state) for r in theirs]
    for a, b in zip(mine.rows, theirs):
        assert a["rho"] == pytest.approx(b.rho, rel=1e-6)
        assert a["energy_full"] == pytest.approx(b.energy_full, rel=1e-6)


BAD_NAMES = ["../../x", "/tmp/abs", "sub/dir", "..", ".hidden", "", "a b", "x" * 101]


def test_the_page_writes_only_plain_names_under_its_folder(studio, tmp_path):
    """Exports, run folders and sessions typed in the page are plain names under --runs;
    anything else is refused and nothing is written."""
    before = sorted(p.relative_to(tmp_path) for p in tmp_path.rglob("*"))
    for name in BAD_NAMES:
        for action in (studio.export_a, studio.optimiser.export_iteration, studio.optimiser.optimise, studio.save):
            if action in (studio.optimiser.optimise, studio.save) and not name.strip():
                continue  # empty: a fresh dated run folder / the session's own folder
            with pytest.raises(KgarmentError, match="give a plain name"):
                action(name)
    assert sorted(p.relative_to(tmp_path) for p in tmp_path.rglob("*")) == before


def test_export_never_overwrites_without_a_second_press(studio, tmp_path):
    from kgarment.design import load_design

    exports = tmp_path / "runs" / "exports"
    exports.mkdir(parents=True)
    (exports / "notes.txt").write_text("mine")
    (exports / "keep.npz").write_bytes(b"mine")
    out = studio.export_a("notes.txt")  # a suffix is added, never swapped: notes.txt stays
    assert out == exports / "notes.txt.npz" and (exports / "notes.txt").read_text() == "mine"
    assert studio.export_a("keep") is None and (exports / "keep.npz").read_bytes() == b"mine"
    assert "exists: press the button again" in last(studio)[0]
    out = studio.export_a("keep.npz")  # the same file asked for again: replaced
    assert out == exports / "keep.npz"
    assert load_design(out, studio.state.n_faces).shape == (studio.state.n_faces,)


def test_cli_refuses_a_remote_host_without_allow_remote(tmp_path):
    bad = subprocess.run([sys.executable, "-m", "kgarment.cli", "studio", "--host", "0.0.0.0"], cwd=tmp_path,
                         capture_output=True, text=True, check=False)
    assert bad.returncode == 2 and "--allow-remote" in bad.stderr and "over plain HTTP" in bad.stderr
    assert len(bad.stderr.strip().splitlines()) == 1, bad.stderr


def test_activation_sets_pick_what_a_motion_switches_on(studio):
    """The Simulate tab's per-motion ON set ([motions.activation]): checked names, its own
    evaluator, followed by clutch renames and deletions, undone like every edit, and used
    by the simulation (a clutch left out of the set carries nothing in the ON state)."""
    from kgarment.studio.simulations import SimInputs

    st, sims, m = studio.state, studio.sims, "arm_flexion.right"
    assert st.clutch_names() == ["elbow_outer.R", "elbow_inner.R"] and st.activation_set(m) == st.clutch_names()
    first = sims.evaluator(SimInputs.of(st))
    studio.panel._set_activation(m, " elbow_outer.R ")
    assert st.problem.activation_of(m) == {"elbow_outer.R": 1.0}
    assert studio.panel.set_fields[m].value == "elbow_outer.R" and "switches on: elbow_outer.R" in last(studio)[0]
    ev = sims.evaluator(SimInputs.of(st))
    assert ev is not first and list(ev.case.on_activation(m)) == [1.0, 0.0]
    with pytest.raises(KgarmentError, match="unknown clutch 'nope'; the clutches are: elbow_outer.R, elbow_inner.R"):
        st.set_activation(m, ["nope"])
    st.edit_clutch("elbow_outer.R", name="outer")
    assert st.problem.activation_of(m) == {"outer": 1.0}
    st.undo()
    assert st.problem.activation_of(m) == {"elbow_outer.R": 1.0}
    st.delete_clutch("elbow_outer.R")
    assert st.problem.activation_of(m) is None  # left empty: every clutch again
    st.undo()
    paint(studio, faces=(100, 200, 300, 400, 500), radius=0.04)
    job = sims.simulate("A")
    assert job.wait(240) and job.status == "done", job.message
    tension = {r["clutch"]: r["tension_N"] for r in sims.a.loads}
    # an OFF clutch is plain cloth: (Y t)_off / (Y t)_on = 1.5% with the reference preset
    assert abs(tension["elbow_inner.R"]) < 0.05 * abs(tension["elbow_outer.R"])
    st.set_activation(m, st.clutch_names())  # every clutch: the default again, written nowhere
    assert st.problem.activation == ()
    studio.panel.refresh_status()
    assert studio.panel.set_fields[m].value == ""
