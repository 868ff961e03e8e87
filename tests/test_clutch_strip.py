"""Clutch strip meshes (kgarment.clutch.mesh) and building them from specs."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

from kgarment.clutch import (
    MIN_SEGMENT,
    ClutchError,
    ClutchSpec,
    ClutchStrip,
    MeshTopology,
    build_clutch,
    build_strip,
    trace_path,
)
from kgarment.clutch.samples import flat_sheet, open_prism, prism_point

R, SIDES = 0.05, 24


@pytest.fixture(scope="module")
def sheet():
    V, F = flat_sheet(0.3, 40, jitter=0.3, thin=True, seed=2)
    return V, F, MeshTopology(V, F)


@pytest.fixture(scope="module")
def prism():
    V, F = open_prism(R, 0.3, SIDES, 60)
    return V, F, MeshTopology(V, F)


def strip_area(s: ClutchStrip) -> float:
    return float(trimesh.Trimesh(s.vertices, s.faces, process=False).area)


def check_structure(s: ClutchStrip, V, F, topo):
    r = len(s.centerline)
    assert r >= 2 and s.vertices.shape == (3 * r, 3) and s.faces.shape == (4 * (r - 1), 3)
    assert s.faces.dtype == np.int64 and s.bind_face.dtype == np.int64
    assert s.faces.min() == 0 and s.faces.max() == 3 * r - 1
    assert np.array_equal(s.centerline, np.arange(r))
    assert np.array_equal(s.anchors, [0, r, 2 * r, r - 1, 2 * r - 1, 3 * r - 1])
    assert np.allclose(s.bind_bary.sum(axis=1), 1.0) and s.bind_bary.min() >= 0
    # bound to the rest garment: reproduces the vertices exactly
    assert np.abs(s.bound_positions(V, F) - s.vertices).max() <= 1e-12
    # wound like the garment
    n = trimesh.Trimesh(s.vertices, s.faces, process=False).face_normals
    nb = topo.normal[s.bind_face[s.faces[:, 0]]]
    assert np.all(np.einsum("ij,ij->i", n, nb) > 0.5)
    # anchors: the rows are width apart (straight across on a developable surface)
    assert np.allclose(np.linalg.norm(s.vertices[s.anchors[1]] - s.vertices[s.anchors[2]]),
                       s.width, rtol=2e-2)


def test_flat_strip_is_the_exact_rectangle(sheet):
    V, F, topo = sheet
    d = np.array([1.0, 0.45, 0.0]) / np.linalg.norm([1.0, 0.45])
    spec = ClutchSpec("forearm", (0.08, 0.1, 0.0), d, 0.12, width=0.012)
    s = build_clutch(spec, V, F, topo)
    check_structure(s, V, F, topo)
    assert s.name == "forearm" and s.length == 0.12 and s.width == 0.012 and s.prestrain == 1.0
    assert abs(strip_area(s) - 0.12 * 0.012) < 1e-9 * 0.12 * 0.012
    left = np.array([-d[1], d[0], 0.0])  # normal (+z) x direction
    r = len(s.centerline)
    x0 = np.array([0.08, 0.1, 0.0])
    assert np.allclose(s.vertices[[0, r - 1]], [x0, x0 + 0.12 * d], atol=1e-12, rtol=0)
    assert np.allclose(s.vertices[r:2 * r] - s.vertices[:r], 0.006 * left, atol=1e-12, rtol=0)
    assert np.allclose(s.vertices[2 * r:] - s.vertices[:r], -0.006 * left, atol=1e-12, rtol=0)


def test_short_segments_are_merged(sheet):
    V, F, topo = sheet
    hit = topo.closest_point([0.08, 0.1, 0])
    path = trace_path(V, F, hit.face, hit.bary, [1, 0.45, 0], 0.12, topology=topo)
    seg = np.diff(path.arclength)
    assert seg.min() < 1e-4  # the sliver triangles make tiny segments ...
    s = build_strip(path, 0.01, topo, name="c")
    c = s.vertices[s.centerline]
    kept = np.linalg.norm(np.diff(c, axis=0), axis=1)
    assert kept.min() >= MIN_SEGMENT - 1e-12  # ... which the strip does not have
    assert np.isclose(kept.sum(), 0.12) and len(s.centerline) < len(path.points)


def test_cylinder_strip_area(prism):
    V, F, topo = prism
    for u0, z0, alpha, length in [(0.01, 0.05, 0.3, 0.15), (0.1, 0.1, 1.3, 0.12),
                                   (0.2, 0.2, -0.05, 0.2), (0.05, 0.03, np.pi / 2, 0.1)]:
        chord = 2 * R * np.sin(np.pi / SIDES)
        k = int(u0 // chord)
        along = prism_point((k + 1) * chord, 0, R, SIDES) - prism_point(k * chord, 0, R, SIDES)
        d = np.cos(alpha) * along / chord + np.sin(alpha) * np.array([0, 0, 1.0])
        s = build_clutch(ClutchSpec("helix", prism_point(u0, z0, R, SIDES), d, length), V, F,
                         topo)
        check_structure(s, V, F, topo)
        assert abs(strip_area(s) / (length * 0.01) - 1) < 0.015


def test_strip_follows_a_moving_garment(prism):
    V, F, topo = prism
    s = build_clutch(ClutchSpec("c", prism_point(0.01, 0.1, R, SIDES), [0.2, 0.1, 1], 0.1,
                                prestrain=0.9), V, F, topo)
    rot = trimesh.transformations.rotation_matrix(0.7, [1, 2, 3])[:3, :3]
    moved = V @ rot.T + [0.1, -0.2, 0.3]
    assert np.abs(s.bound_positions(moved, F) - (s.vertices @ rot.T + [0.1, -0.2, 0.3])).max() \
        < 1e-12
    rest = s.rest_vertices()
    c = s.vertices[s.centerline].mean(axis=0)
    assert np.allclose(rest - c, 0.9 * (s.vertices - c))


def test_too_wide_strip_is_an_error(sheet, prism):
    V, F, topo = sheet
    with pytest.raises(ClutchError, match=r"clutch 'hem' is wider than the garment: its right side"):
        build_clutch(ClutchSpec("hem", (0.05, 0.004, 0), [1, 0, 0], 0.1), V, F, topo)
    s = build_clutch(ClutchSpec("hem", (0.05, 0.006, 0), [1, 0, 0], 0.1), V, F, topo)
    assert abs(s.vertices[2 * len(s.centerline):, 1] - 0.001).max() < 1e-12
    V, F, topo = prism
    with pytest.raises(ClutchError, match="clutch 'cuff' is wider than the garment"):
        build_clutch(ClutchSpec("cuff", prism_point(0, 0.29, R, SIDES), [1, 0, 0], 0.06,
                                width=0.03), V, F, topo)


def test_clipped_clutch(sheet):
    V, F, topo = sheet
    with pytest.raises(ClutchError, match=r"clutch 'c' leaves the garment after 10.0 cm of "
                                          r"15.0 cm"):
        build_clutch(ClutchSpec("c", (0.2, 0.1, 0), [1, 0, 0], 0.15), V, F, topo)
    s = build_clutch(ClutchSpec("c", (0.2, 0.1, 0), [1, 0, 0], 0.15, clip=True), V, F, topo)
    assert np.isclose(s.length, 0.1) and np.isclose(s.vertices[len(s.centerline) - 1, 0], 0.3)
