"""Landmarks and the default clutch layouts on the Anny body and its garments."""

from __future__ import annotations

import numpy as np
import pytest

from kgarment.clutch import MeshTopology, build_clutch
from kgarment.clutch.landmarks import body_landmarks, first_hit
from kgarment.clutch.layouts import LAYOUTS, default_layout, layout_names
from kgarment.errors import KgarmentError
from kgarment.garment import make_garment

GARMENT_FOR = {"arm_flexion": "arm_sleeve.right", "arm_extension": "arm_sleeve.right",
               "sleeve": "arm_sleeve.right", "shirt": "short_sleeve_shirt", "long_sleeve": "long_sleeve_shirt"}


def test_first_hit_against_a_plane():
    tri = np.array([[[0, 0, 1.0], [1, 0, 1], [0, 1, 1]], [[1, 1, 1.0], [0, 1, 1], [1, 0, 1]]])
    assert first_hit(np.array([0.3, 0.3, 0.0]), np.array([0, 0, 1.0]), tri) == pytest.approx(1.0)
    assert first_hit(np.array([0.3, 0.3, 0.0]), np.array([0, 0, -1.0]), tri) == np.inf


@pytest.mark.parametrize("side", ["L", "R"])
def test_layout_names_are_the_built_layouts_names(anny_body, side):
    """The names a sweep checks activations against without a body are the layouts' own."""
    for name in LAYOUTS:
        assert layout_names(name, side) == [s.name for s in default_layout(name, anny_body, side)], name
    with pytest.raises(KgarmentError, match="unknown clutch layout 'vest'"):
        layout_names("vest")


def test_landmarks_lie_on_the_body_where_expected(anny_body):
    L = body_landmarks(anny_body)
    v = anny_body.rest_vertices
    for name, p in L.items():
        assert np.min(np.linalg.norm(v - p, axis=1)) < 0.02, name  # on the surface (1 cm mesh)
    assert L["upper_back"][1] > 0 > L["chest"][1]  # back is +Y
    assert L["elbow_outer.L"][0] > 0 > L["elbow_outer.R"][0]
    np.testing.assert_allclose(L["elbow_outer.right"], L["elbow_outer.R"])


@pytest.mark.parametrize("layout", LAYOUTS)
def test_default_layouts_build_on_their_garments(anny_body, layout):
    specs = default_layout(layout, anny_body)
    for sub in (0, 1):
        g = make_garment(anny_body, GARMENT_FOR[layout], sub)
        topo = MeshTopology(g.rest_vertices, g.faces)
        strips = [build_clutch(s, g.rest_vertices, g.faces, topology=topo) for s in specs]
        for spec, strip in zip(specs, strips):
            assert strip.length == pytest.approx(spec.length, rel=1e-9)
            c = strip.vertices[strip.centerline]
            chords = np.linalg.norm(np.diff(c, axis=0), axis=1).sum()  # merged < 1 mm pieces
            assert chords == pytest.approx(spec.length, rel=3e-3)
            assert len(strip.anchors) == 6


def test_layout_clutches_land_in_the_same_place_across_subdivisions(anny_body):
    specs = default_layout("shirt", anny_body)
    ends = []
    for sub in (0, 1):
        g = make_garment(anny_body, "short_sleeve_shirt", sub)
        ends.append([(lambda c: c.vertices[c.centerline[[0, -1]]])(build_clutch(s, g.rest_vertices, g.faces)) for s in specs])
    # midpoint subdivision keeps the surface, so the walk is the same surface path
    for a, b in zip(*ends):
        assert np.abs(a - b).max() < 1e-3


def test_unknown_layout(anny_body):
    with pytest.raises(KgarmentError, match="unknown clutch layout 'vest'"):
        default_layout("vest", anny_body)


def test_principal_stretch_is_exact_for_an_affine_stretch():
    from kgarment.clutch.suggest import principal_stretch

    rng = np.random.default_rng(1)
    V = np.c_[rng.random((30, 2)), np.zeros(30)]
    from scipy.spatial import Delaunay

    F = Delaunay(V[:, :2]).simplices
    d = np.array([np.cos(0.4), np.sin(0.4), 0.0])
    A = np.eye(3) + 0.25 * np.outer(d, d)  # stretch 1.25 along d
    s = principal_stretch(V, V @ A.T, F)
    np.testing.assert_allclose(s.stretch, 1.25, rtol=1e-12)
    np.testing.assert_allclose(np.abs(s.direction @ d), 1.0, rtol=1e-12)


def test_suggestions_sit_on_high_strain_and_follow_it(anny_body):
    from kgarment.clutch.suggest import principal_stretch, suggest_clutches

    g = make_garment(anny_body, "short_sleeve_shirt", 0)
    specs = suggest_clutches(g, motions=["arms_forward", "bend_forward"], count=3, length=0.08)
    assert 1 <= len(specs) <= 3
    s = principal_stretch(g.rest_vertices, g.vertices("arms_forward"), g.faces)
    t = principal_stretch(g.rest_vertices, g.vertices("bend_forward"), g.faces)
    best = np.maximum(s.stretch, t.stretch)
    cent = g.rest_vertices[g.faces].mean(1)
    for spec in specs:
        strip = build_clutch(spec, g.rest_vertices, g.faces)
        mid = strip.vertices[strip.centerline[len(strip.centerline) // 2]]
        near = np.linalg.norm(cent - mid, axis=1) < 0.03
        assert best[near].mean() > np.percentile(best, 75)


def test_suggestions_take_the_motions_in_turn(anny_body):
    """Clutch k sits where motion k (round the motions) stretches the garment most, so every
    motion gets a clutch of its own (greedy over all motions together gave the one that
    stretches most every clutch)."""
    from kgarment.clutch.suggest import principal_stretch, suggest_clutches

    g = make_garment(anny_body, "short_sleeve_shirt", 0)
    motions = ["arms_forward", "bend_forward"]
    specs = suggest_clutches(g, motions=motions, count=2, length=0.08)
    assert len(specs) == 2
    cent = g.rest_vertices[g.faces].mean(1)
    for spec, motion in zip(specs, motions):
        s = principal_stretch(g.rest_vertices, g.vertices(motion), g.faces).stretch
        strip = build_clutch(spec, g.rest_vertices, g.faces)
        mid = strip.vertices[strip.centerline[len(strip.centerline) // 2]]
        near = np.linalg.norm(cent - mid, axis=1) < 0.03
        assert s[near].mean() > np.percentile(s, 90), motion
