"""Coarse-to-fine design (design.refine): the subdivision maps, and a tiny run end to end
(its control screen at the coarse level)."""

from __future__ import annotations

import json

import numpy as np
import pytest
from tiny_problems import TINY_SLEEVE

from kgarment.case.levels import parent_faces, vertex_map
from kgarment.cli import main
from kgarment.constants import target_reached
from kgarment.design import load_design_history
from kgarment.errors import KgarmentError
from kgarment.garment import make_garment
from kgarment.garment.topology import triangle_areas
from kgarment.problem import parse_problem


def test_the_maps_are_the_garments_own_subdivision(anny_body):
    """Level 0 mapped up is level 1 exactly: vertices (old ones, then edge midpoints) and
    faces, and every level-1 face lies in its parent with a quarter of its area."""
    g0 = make_garment(anny_body, "arm_sleeve.right", 0)
    for level in (1, 2):
        g = make_garment(anny_body, "arm_sleeve.right", level)
        S = vertex_map(g0.faces, g0.n_vertices, g.n_faces)
        np.testing.assert_allclose(S @ g0.rest_vertices, g.rest_vertices, atol=1e-12)
        parent = parent_faces(g.n_faces, g0.n_faces)
        a0, a = triangle_areas(g0.rest_vertices, g0.faces), triangle_areas(g.rest_vertices, g.faces)
        np.testing.assert_allclose(np.bincount(parent, weights=a), a0, rtol=1e-9)
        np.testing.assert_allclose(a, a0[parent] / 4**level, rtol=1e-9)
        # each child's centroid is inside its parent (barycentric coordinates >= 0)
        P = g0.rest_vertices[g0.faces[parent]]
        c = g.rest_vertices[g.faces].mean(axis=1)
        n = np.cross(P[:, 1] - P[:, 0], P[:, 2] - P[:, 0])
        for i in range(3):
            e = np.cross(P[:, (i + 2) % 3] - P[:, (i + 1) % 3], c - P[:, (i + 1) % 3])
            assert np.all(np.einsum("ij,ij->i", e, n) > 0)
    with pytest.raises(ValueError):
        parent_faces(g0.n_faces * 3, g0.n_faces)


def test_levels_are_checked():
    with pytest.raises(KgarmentError, match="below the garment's subdivision 1"):
        parse_problem({"garment": {"subdivision": 1}, "design": {"levels": [1]}})
    with pytest.raises(KgarmentError, match="increasing levels"):
        parse_problem({"garment": {"subdivision": 2}, "design": {"levels": [1, 0]}})
    with pytest.raises(KgarmentError, match="list of subdivision levels"):
        parse_problem({"design": {"levels": 0}})
    p = parse_problem({"garment": {"subdivision": 2}, "design": {"levels": [0, 1]}})
    assert p.design.levels == (0, 1) and p.design.flat()["levels"] == [0, 1]
    assert "levels" not in parse_problem({}).design.flat()  # earlier runs' files unchanged


SLEEVE = TINY_SLEEVE.replace("subdivision = 0", "subdivision = 1") + """[design]
levels = [0]
target_area = 0.6
er = 0.15
ar_max = 0.05
max_iterations = 8
window = 2
"""


def test_a_coarse_to_fine_run(tmp_path, anny_body, monkeypatch):
    """The evolution runs at level 0 (RUN/level0) until the target area; the run itself is
    at level 1: its iteration 0 is the full garment, its iteration 1 the coarse design
    mapped face to face (the same reinforced area share), and it goes on to its end."""
    monkeypatch.chdir(tmp_path)
    (tmp_path / "p.toml").write_text(SLEEVE)
    assert main(["-q", "design", "p.toml", "--out", "run"]) == 0
    run = tmp_path / "run"
    coarse = json.loads((run / "level0" / "metrics.json").read_text())
    fine = json.loads((run / "metrics.json").read_text())
    assert coarse[0]["area"] == fine[0]["area"] == 1.0
    # the coarse run stops at its first iteration at the target area
    assert target_reached(coarse[-1]["area"], 0.6, 0.15)
    assert not any(target_reached(r["area"], 0.6, 0.15) for r in coarse[:-1])
    h0, h1 = load_design_history(run / "level0"), load_design_history(run)
    assert h1.shape[1] == 4 * h0.shape[1]
    assert h1.shape[0] >= 2 and len(fine) == h1.shape[0]
    # iteration 1 is the coarse run's next design, face to face; same area share
    with np.load(run / "level0" / "checkpoint.npz") as z:
        nxt, target = np.asarray(z["design"]) > 0.5, float(z["target"])
    np.testing.assert_array_equal(h1[1], nxt[parent_faces(h1.shape[1], h0.shape[1])])
    g0 = make_garment(anny_body, "arm_sleeve.right", 0)
    a0 = triangle_areas(g0.rest_vertices, g0.faces)
    assert fine[1]["target"] == target and fine[1]["area"] == pytest.approx(a0[nxt].sum() / a0.sum(), rel=1e-9)
    assert (run / "final" / "design.npz").is_file()
    # the control screen ran once, at the coarsest level, into the run's own folder
    (c,) = json.loads((run / "control.json").read_text())
    assert c["motion"] == "arm_flexion.right" and c["subdivision"] == 0 and c["full_on_J"] >= c["full_off_J"] > 0
    assert not (run / "level0" / "control.json").exists()
    # the run reports itself finished, and a second call reuses it
    assert main(["-q", "design", "p.toml", "--out", "run"]) == 2
