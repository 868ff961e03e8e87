"""Garments: manifold templates, subdivision, attachment rings, face masks."""

from __future__ import annotations

import numpy as np
import pytest

from kgarment.errors import KgarmentError
from kgarment.garment import builtin_templates, garment_from_mask, make_garment
from kgarment.garment.topology import boundary_loops, manifold_problems, midpoint_subdivide


@pytest.mark.parametrize("name", list(builtin_templates()))
def test_templates_are_manifold_with_attachments(anny_body, name):
    g = make_garment(anny_body, name, 0)
    assert manifold_problems(g.rest_vertices, g.faces) == []
    t = builtin_templates()[name]
    assert set(t.attach) <= set(g.loops)
    ring = np.zeros(g.n_vertices, bool)
    for a in t.attach:
        ring[g.loops[a]] = True
    # one ring of faces: exactly the faces touching an attached loop
    np.testing.assert_array_equal(g.attached, ring[g.faces].any(1))
    # the ring is about one edge wide: its area ~ loop length x mean edge length
    edges = np.linalg.norm(g.rest_vertices[g.faces] - g.rest_vertices[np.roll(g.faces, 1, 1)], axis=2)
    length = sum(np.linalg.norm(np.diff(g.rest_vertices[np.r_[g.loops[a], g.loops[a][:1]]], axis=0), axis=1).sum()
                 for a in t.attach)
    ratio = g.face_areas()[g.attached].sum() / (length * edges.mean())
    assert 0.4 < ratio < 3.0


def test_shirt_has_free_neck_and_sleeves(shirt0):
    assert set(shirt0.loops) == {"hem", "cuff.L", "cuff.R", "opening0"}
    for free in ("cuff.L", "cuff.R", "opening0"):
        assert not shirt0.attached[np.isin(shirt0.faces, shirt0.loops[free]).any(1)].all()
    share = shirt0.attached.mean()
    assert 0.005 < share < 0.05


def test_subdivision_quadruples_and_keeps_area(anny_body, shirt0):
    g1 = make_garment(anny_body, "short_sleeve_shirt", 1)
    assert g1.n_faces == 4 * shirt0.n_faces
    assert g1.face_areas().sum() == pytest.approx(shirt0.face_areas().sum(), rel=1e-12)
    np.testing.assert_allclose(np.asarray(g1.embedding.sum(1)).ravel(), 1.0)
    # the attachment share halves with the edge length (one quad wide at any resolution)
    assert 0.3 < g1.attached.mean() / shirt0.attached.mean() < 0.7
    for k, m in enumerate(g1.motion_names):
        np.testing.assert_allclose(g1.initial[k], g1.embedding @ anny_body.vertices(m))
    # midpoint subdivision: every new vertex lies on a body face (its parent's plane)
    bf = anny_body.rest_vertices[anny_body.faces[g1.body_face]]
    nrm = np.cross(bf[:, 1] - bf[:, 0], bf[:, 2] - bf[:, 0])
    nrm /= np.linalg.norm(nrm, axis=1, keepdims=True)
    dist = np.einsum("ij,ij->i", g1.rest_vertices[g1.faces].mean(1) - bf[:, 0], nrm)
    assert np.abs(dist).max() < 1e-12


def test_subdivision_matrix_on_one_triangle():
    faces = np.array([[0, 1, 2]])
    new, S = midpoint_subdivide(faces, 3)
    V = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0]])
    W = S @ V
    assert new.shape == (4, 3) and W.shape == (6, 3)
    a = 0.5 * np.linalg.norm(np.cross(W[new[:, 1]] - W[new[:, 0]], W[new[:, 2]] - W[new[:, 0]]), axis=1)
    np.testing.assert_allclose(a, 0.125)
    # orientation preserved: all normals +z
    n = np.cross(W[new[:, 1]] - W[new[:, 0]], W[new[:, 2]] - W[new[:, 0]])
    assert (n[:, 2] > 0).all()


def test_manifold_check_names_problems():
    V = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [-1, 0, 0], [0, -1, 0], [1, 1, 0.0], [5, 5, 5]])
    bowtie = np.array([[0, 1, 2], [0, 3, 4]])
    assert any("bowtie" in p for p in manifold_problems(V[:5], bowtie))
    nonmanifold = np.array([[0, 1, 2], [1, 0, 4], [0, 1, 5]])
    assert any("more than two" in p for p in manifold_problems(V[:6], nonmanifold))
    flipped = np.array([[0, 1, 2], [0, 1, 4]])
    assert any("orientation" in p for p in manifold_problems(V[:5], flipped))
    degenerate = np.array([[0, 1, 2], [0, 1, 1]])
    assert any("degenerate" in p for p in manifold_problems(V[:3], degenerate))
    assert any("not used" in p for p in manifold_problems(V, np.array([[0, 1, 2]])))


def test_garment_from_face_mask(anny_body, shirt0):
    mask = np.zeros(len(anny_body.faces), bool)
    mask[shirt0.body_face] = True
    g = garment_from_mask(anny_body, mask, "mine", 0, attach=("all",))
    assert g.n_faces == shirt0.n_faces
    assert len(boundary_loops(g.faces)) == 4
    assert g.attached.any()
    with pytest.raises(KgarmentError, match="unknown attachment loop 'hem'"):
        garment_from_mask(anny_body, mask, "mine", 0, attach=("hem",))
    with pytest.raises(KgarmentError, match="entries"):
        garment_from_mask(anny_body, mask[:10], "mine", 0)


def test_unknown_garment(anny_body):
    with pytest.raises(KgarmentError, match="unknown garment 'cape'; valid: .*short_sleeve_shirt"):
        make_garment(anny_body, "cape")


def test_attachment_targets_follow_the_body(anny_body, shirt0):
    t = shirt0.attachment_targets("bend_forward")
    assert t.shape == (int(shirt0.attached.sum()), 3)
