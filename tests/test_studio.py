"""Studio logic without a browser: brush, placement, edits with undo, sessions, runs, views."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from kgarment.clutch.errors import ClutchError
from kgarment.errors import KgarmentError
from kgarment.studio import brush, placement, view
from kgarment.studio.session import (
    Opened,
    build_state,
    export_design,
    load_session,
    read_source,
    save_session,
)

MOTIONS = ("arm_flexion.right", "arms_raise.right")


def sleeve_problem(**design):
    from kgarment.problem import DesignSpec, GarmentSpec, Problem

    return Problem(motions=MOTIONS, garment=GarmentSpec("arm_sleeve.right", subdivision=0),
                   design=dataclasses.replace(DesignSpec(), **design))


@pytest.fixture()
def state(anny_body):
    return build_state(Opened("default", sleeve_problem()), anny_body)


def grid(nx=4, ny=4, z=0.0, offset=0):
    """A flat (nx x ny) quad grid of 0.01 m cells in the plane z, split into triangles."""
    xs, ys = np.meshgrid(np.arange(nx + 1) * 0.01, np.arange(ny + 1) * 0.01, indexing="ij")
    V = np.stack([xs.ravel(), ys.ravel(), np.full(xs.size, z)], axis=1)
    F = []
    for i in range(nx):
        for j in range(ny):
            a, b, c, d = i * (ny + 1) + j, (i + 1) * (ny + 1) + j, (i + 1) * (ny + 1) + j + 1, i * (ny + 1) + j + 1
            F += [[a, b, c], [a, c, d]]
    return V, np.array(F) + offset


# ----- brush ------------------------------------------------------------------------------
def test_ray_hit_face_bary_distance():
    V, F = grid()
    hit = brush.ray_hit((0.013, 0.002, 1.0), (0, 0, -2.0), V, F)
    assert hit is not None and hit.distance == pytest.approx(1.0)
    assert np.allclose(hit.point, [0.013, 0.002, 0.0])
    assert np.allclose(hit.bary @ V[F[hit.face]], hit.point)
    assert brush.ray_hit((0.5, 0.5, 1.0), (0, 0, -1), V, F) is None  # beside the mesh
    assert brush.ray_hit((0.01, 0.01, 1.0), (0, 0, 1), V, F) is None  # pointing away
    assert brush.ray_hit((0.01, 0.01, 1.0), (0, 0, 0), V, F) is None  # no direction


def test_ray_hit_takes_the_nearest_of_two_sheets():
    V1, F1 = grid(z=0.0)
    V2, F2 = grid(z=0.01, offset=len(V1))
    V, F = np.vstack([V1, V2]), np.vstack([F1, F2])
    assert brush.ray_hit((0.015, 0.015, 1.0), (0, 0, -1), V, F).face >= len(F1)
    assert brush.ray_hit((0.015, 0.015, -1.0), (0, 0, 1), V, F).face < len(F1)


def test_surface_brush_stays_on_its_sheet_euclidean_does_not():
    V1, F1 = grid(z=0.0)
    V2, F2 = grid(z=0.005, offset=len(V1))
    V, F = np.vstack([V1, V2]), np.vstack([F1, F2])
    g = brush.FaceGraph(V, F)
    p = g.centroids[5]
    surface = brush.brush_faces(g, 5, p, 0.012)
    everywhere = brush.brush_faces(g, 5, p, 0.012, mode="euclidean")
    assert len(surface) > 1 and (surface < len(F1)).all()
    assert (everywhere >= len(F1)).any() and set(surface) < set(everywhere)
    assert list(brush.brush_faces(g, 5, p, 0.0)) == [5]
    small, big = brush.brush_faces(g, 5, p, 0.01), brush.brush_faces(g, 5, p, 0.03)
    assert set(small) <= set(big)
    with pytest.raises(ValueError, match="not a face"):
        brush.brush_faces(g, len(F), p, 0.01)
    with pytest.raises(ValueError, match="radius"):
        brush.brush_faces(g, 0, p, -1.0)


def test_apply_and_coverage():
    mask, changed = brush.apply(np.zeros(4, bool), [1, 2], True)
    assert changed == 2 and mask.tolist() == [False, True, True, False]
    assert brush.apply(mask, [1], True)[1] == 0
    assert brush.coverage(mask, np.array([1.0, 1.0, 2.0, 0.0])) == pytest.approx(0.75)
    o, d = brush.camera_ray((0, 0, 1), (0, 0, -1))
    assert np.allclose(o, [0, 0, 1]) and np.allclose(d, [0, 0, -1])


def test_click_in_a_posed_view_maps_to_the_rest_garment(state):
    g = state.base_garment
    x = g.vertices("arm_flexion.right")
    face = 123
    tri = x[g.faces[face]]
    c = tri.mean(axis=0)
    n = np.cross(tri[1] - tri[0], tri[2] - tri[0])
    n /= np.linalg.norm(n)
    hit = brush.ray_hit(c + 0.3 * n, -n, x, g.faces)
    assert hit.face == face and np.allclose(hit.bary, 1 / 3, atol=1e-6)
    assert np.allclose(state.rest_point(hit.face, hit.bary), g.rest_vertices[g.faces[face]].mean(axis=0))


# ----- placement --------------------------------------------------------------------------
def test_unique_names():
    assert placement.unique_name([], "a") == "a"
    assert placement.unique_name(["a", "a2"], "a") == "a3"
    assert placement.unique_name(["clutch"], " ") == "clutch2"


def test_clutch_from_two_clicked_points(state):
    g, c = state.base_garment, state.graph.centroids
    s = c[100]
    t = c[np.argmin(np.abs(np.linalg.norm(c - s, axis=1) - 0.03))]  # a click 3 cm away
    spec = placement.clutch_from_points("c", s, t, length=0.05, width=0.012)
    strip = placement.build(spec, state.topology, state.landmarks)
    start = strip.vertices[strip.centerline[0]]
    assert np.linalg.norm(start - s) < 1e-6
    from kgarment.clutch import strip_start_direction

    n = state.topology.normal[strip.bind_face[strip.centerline[0]]]
    want = (t - s) - ((t - s) @ n) * n  # the click's direction in the start face
    assert strip_start_direction(strip) @ (want / np.linalg.norm(want)) > 0.95
    assert strip.length == pytest.approx(0.05) and strip.width == pytest.approx(0.012)
    with pytest.raises(ClutchError, match="direction point is the start point"):
        placement.clutch_from_points("c", s, s)
    moved = placement.moved(spec, t, state.topology, state.landmarks)
    assert np.allclose(moved.start, t) and moved.length == spec.length
    aimed = placement.aimed(spec, g.rest_vertices[g.faces[60]].mean(0), state.topology, state.landmarks)
    assert np.allclose(aimed.start, s) and not np.allclose(aimed.direction, spec.direction)
    assert placement.nearest_clutch([strip], s + 0.001) == "c"
    assert placement.nearest_clutch([strip], s + 0.5) is None


def test_clutch_from_landmarks_and_off_garment(state):
    spec = placement.clutch_from_landmarks("x", "elbow_outer.R", "forearm_inner.R", length=0.06)
    assert placement.build(spec, state.topology, state.landmarks).length == pytest.approx(0.06)
    with pytest.raises(ClutchError, match="from the garment"):
        placement.build(placement.clutch_from_landmarks("y", "upper_back", "chest"), state.topology, state.landmarks)
    with pytest.raises(ClutchError, match="both"):
        placement.clutch_from_landmarks("z", "chest", "chest")


# ----- edits with undo --------------------------------------------------------------------
def test_paint_erase_coverage_and_undo(state):
    g, c = state.base_garment, state.graph.centroids
    assert state.coverage() == 0.0 and not state.dirty
    n = state.paint(200, c[200], 0.03)
    assert n > 1 and state.coverage() > 0 and state.dirty
    cov = state.coverage()
    state.paint(300, c[300], 0.03, record=False)  # the same stroke: one undo step
    assert state.coverage() > cov
    state.paint(200, c[200], 0.01, value=False)
    assert state.undo() and state.undo()
    assert state.coverage() == 0.0
    assert not state.undo()
    state.paint(10, c[10], 0.02, layer="attached", value=False)
    assert state.attached.sum() < g.attached.sum()
    with pytest.raises(KgarmentError, match="layer"):
        state.paint(10, c[10], 0.02, layer="nope")
    rev = state.revision
    with pytest.raises(KgarmentError, match="not a face"):
        state.paint(g.n_faces + 5, c[0], 0.02)
    assert state.revision == rev


def test_clutch_edits_validate_first(state):
    names = state.clutch_names()
    assert names == ["elbow_outer.R", "elbow_inner.R"]  # the sleeve's default layout
    X = state.base_garment.rest_vertices
    axis = np.linalg.svd(X - X.mean(0))[2][0]  # along the arm
    s = state.graph.centroids[100]
    t = s + 0.03 * axis
    state.add_clutch(placement.clutch_from_points("mine", s, t, length=0.05))
    rev = state.revision
    with pytest.raises(ClutchError, match="exists already"):
        state.add_clutch(placement.clutch_from_points("mine", s, t))
    with pytest.raises(ClutchError):  # 40 cm does not fit on the sleeve without clipping
        state.edit_clutch("mine", length=0.4)
    assert state.revision == rev and state.clutch("mine").length == 0.05
    assert state.edit_clutch("mine", length=0.08).length == pytest.approx(0.08)
    state.edit_clutch("mine", name="renamed")
    assert "renamed" in state.clutch_names() and "mine" not in state.clutch_names()
    state.delete_clutch("renamed")
    assert state.clutch_names() == names
    state.undo()
    assert "renamed" in state.clutch_names()
    with pytest.raises(KgarmentError, match="no clutch named"):
        state.delete_clutch("nothing")
    with pytest.raises(KgarmentError, match="budget"):
        state.set_budget(1.5)
    state.set_budget(0.2)
    assert state.problem.design.beso.target_area == 0.2


# ----- sessions ---------------------------------------------------------------------------
def test_session_round_trip(state, tmp_path, anny_body):
    from kgarment.design import load_design
    from kgarment.problem import clutch_specs, load_problem

    c = state.graph.centroids
    state.paint(200, c[200], 0.03)
    state.paint(5, c[5], 0.02, layer="attached", value=False)
    g = state.base_garment
    s, t = g.rest_vertices[g.faces[100]].mean(0), g.rest_vertices[g.faces[140]].mean(0)
    state.add_clutch(placement.clutch_from_points("mine", s, t, length=0.05))
    state.set_budget(0.2)
    compare = ("B", ~state.design)
    paths = save_session(state, tmp_path / "s", settings={"motion": "arms_raise.right", "none": None},
                         compare=compare, results={"A": {"rows": []}})
    assert not state.dirty and {p.name for p in paths} >= {"studio.toml", "problem.toml", "clutches.toml",
                                                          "design.npz", "attachments.npz", "compare.npz"}
    # every piece is a normal kgarment file
    p = load_problem(tmp_path / "s" / "problem.toml")
    assert p.design.beso.target_area == 0.2 and p.garment == state.problem.garment
    assert [x.name for x in clutch_specs(p, anny_body)] == state.clutch_names()
    assert np.array_equal(load_design(str(tmp_path / "s" / "design.npz"), g.n_faces) > 0.5, state.design)
    # and the session reopens to the same layers
    opened = read_source(tmp_path / "s")
    assert opened.kind == "session" and opened.settings["motion"] == "arms_raise.right"
    again = build_state(opened, anny_body)
    assert np.array_equal(again.design, state.design) and np.array_equal(again.attached, state.attached)
    assert again.clutch_names() == state.clutch_names()
    for a, b in zip(again.strips(), state.strips()):
        assert np.allclose(a.vertices, b.vertices, atol=1e-6)
    assert np.array_equal(opened.compare[1], compare[1]) and opened.results == {"A": {"rows": []}}


def test_session_without_clutches_stays_without(state, tmp_path, anny_body):
    for n in state.clutch_names():
        state.delete_clutch(n)
    save_session(state, tmp_path / "s")
    assert build_state(read_source(tmp_path / "s"), anny_body).clutches == []


def test_bad_sources_are_one_line_errors(state, tmp_path):
    (tmp_path / "other").mkdir()
    (tmp_path / "other" / "keep.txt").write_text("x")
    with pytest.raises(KgarmentError, match="other files"):
        save_session(state, tmp_path / "other")
    (tmp_path / "bad.toml").write_text("[garment\n")
    with pytest.raises(KgarmentError, match="not valid TOML"):
        read_source(tmp_path / "bad.toml")
    (tmp_path / "unknown.toml").write_text("[garment]\ncolour = 1\n")
    with pytest.raises(KgarmentError, match="unknown field"):
        read_source(tmp_path / "unknown.toml")
    with pytest.raises(KgarmentError, match="not found"):
        read_source(tmp_path / "missing.toml")
    with pytest.raises(KgarmentError, match="neither"):
        read_source(tmp_path / "other")
    (tmp_path / "sess").mkdir()
    (tmp_path / "sess" / "studio.toml").write_text('format = "something"\n')
    with pytest.raises(KgarmentError, match="format"):
        load_session(tmp_path / "sess")
    with pytest.raises(KgarmentError, match="faces"):
        build_state(Opened("problem", state.problem, design=np.ones(7)), state.body)


def test_export_design_reads_back(state, tmp_path):
    from kgarment.design import load_design

    d = np.zeros(state.n_faces, bool)
    d[:100] = True
    out = export_design(tmp_path / "d.npz", d, state.base_garment, iteration=3)
    assert out == tmp_path / "d.npz"
    assert np.array_equal(load_design(str(out), state.n_faces) > 0.5, d)
    with pytest.raises(KgarmentError, match="faces"):
        export_design(tmp_path / "e.npz", d[:10], state.base_garment)


# ----- runs -------------------------------------------------------------------------------
def fake_run(folder, problem, designs):
    """A minimal run folder: problem.toml and designs.npz (as kgarment design writes them)."""
    import json

    import tomli_w

    from kgarment.io import atomic_save_npz
    from kgarment.problem import problem_to_dict

    folder.mkdir(parents=True)
    (folder / "problem.toml").write_text(tomli_w.dumps(problem_to_dict(problem)))
    atomic_save_npz(folder / "designs.npz", designs=np.array([np.packbits(d) for d in designs]),
                    n_faces=np.array(designs.shape[1]))
    rows = [{"iteration": k, "area": float(d.mean()), "objective": 0.1 * k, "rho[m:on]": 1.0, "rho[m:off]": 0.5}
            for k, d in enumerate(designs)]
    (folder / "metrics.json").write_text(json.dumps(rows))
    return folder


def test_runs_open_check_and_scrub(state, tmp_path):
    from kgarment.body import Phenotype
    from kgarment.problem import GarmentSpec
    from kgarment.studio.runs import check_compatible, progress_image, read_run

    m = state.n_faces
    designs = np.ones((3, m), bool)
    designs[1, ::2] = False
    designs[2, ::3] = False
    run = read_run(fake_run(tmp_path / "r", state.problem, designs))
    check_compatible(run, state.problem, m)
    assert run.n_iterations == 3 and np.array_equal(run.design(1), designs[1])
    assert "iteration 2" in run.summary(2) and "m:on 1.00" in run.summary(2)
    with pytest.raises(KgarmentError, match="0..2"):
        run.design(5)
    other = dataclasses.replace(state.problem, garment=GarmentSpec("arm_sleeve.right", subdivision=1))
    run2 = read_run(fake_run(tmp_path / "r2", other, np.ones((1, 2252), bool)))
    with pytest.raises(KgarmentError, match="subdivision 1 .2252 faces.*subdivision 0 .563 faces"):
        check_compatible(run2, state.problem, m)
    import kgarment.problem as kp

    fat = dataclasses.replace(state.problem, body=kp.BodySpec("anny", Phenotype(weight=0.9)))
    run3 = read_run(fake_run(tmp_path / "r3", fat, designs))
    with pytest.raises(KgarmentError, match="different body"):
        check_compatible(run3, state.problem, m)
    with pytest.raises(KgarmentError, match="not a run folder"):
        read_run(tmp_path)
    img = progress_image(run.metrics)
    assert img.ndim == 3 and img.shape[2] == 3 and img.dtype == np.uint8
    assert progress_image([]).shape == img.shape


# ----- views ------------------------------------------------------------------------------
def test_strain_colours_and_glb():
    V, F = grid(2, 2)
    R = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])
    assert np.allclose(view.face_strain(V, F, V @ R.T + 3.0), 0.0, atol=1e-12)
    assert np.allclose(view.face_strain(V, F, V * [1.1, 1.0, 1.0]), 0.1)
    assert np.allclose(view.interpolate(V, V + 1, 0.25), V + 0.25)
    rgb, lo, hi = view.scalar_colors(np.linspace(0, 1, 8), vmin=0.0, vmax=1.0)
    assert rgb.shape == (8, 3) and rgb.dtype == np.uint8 and (lo, hi) == (0.0, 1.0)
    d = np.array([True, False, True, False, False, False, False, False])
    a = np.array([False, True, True, False, False, False, False, False])
    assert (view.design_colors(d, a)[0] == view.REINFORCED).all() and (view.design_colors(d, a)[1] == view.ATTACHED).all()
    c = view.compare_colors(d, a)
    assert (c[0] == view.ONLY_A).all() and (c[1] == view.ONLY_B).all() and (c[2] == view.BOTH).all()
    assert view.glb_bytes(V, F, np.zeros((len(F), 3), np.uint8))[:4] == b"glTF"
    assert "J/m" in view.legend("energy density", 0.0, 2.0)


def test_energy_view_shares_one_scale_for_on_and_off(state):
    """ON and OFF of one motion are drawn on one colour scale (with a scale each, a garment
    storing 10x less OFF looked the same as ON)."""
    from types import SimpleNamespace

    from kgarment.studio.scene import garment_colors
    from kgarment.studio.settings import Settings

    m = state.n_faces
    motion = state.problem.motions[0]
    on = np.linspace(0.0, 10.0, m)
    a = SimpleNamespace(density={(motion, "on"): on, (motion, "off"): on / 10}, garment_x={},
                        states=lambda: {"on", "off"})
    s = Settings()
    s.mode, s.motion = "energy density", motion
    colours = {}
    for clutches in ("on", "off"):
        s.clutches_on = clutches == "on"
        colours[clutches], legend = garment_colors(state, s, state.base_garment.rest_vertices, a=a, design_b=None,
                                                   run=None, k=0)
        assert f"{np.percentile(on, 99):.3g}" in legend  # the ON maximum, for OFF too
    assert colours["off"].astype(int).sum() < colours["on"].astype(int).sum()  # OFF is darker
