"""The body: shapes, units, orientation, motions measured on joint positions, the cache."""

from __future__ import annotations

import numpy as np
import pytest

from kgarment.body import Phenotype, builtin_motions, load_anny_body
from kgarment.body.motions import Motion, Rotation, resolve_axis
from kgarment.errors import KgarmentError


def _j(body, motion, bone):
    return body.joints(motion)[body.bone_index(bone)]


def _elbow_angle(body, motion, side):
    s, e, w = (_j(body, motion, f"{b}.{side}") for b in ("upperarm02", "lowerarm01", "lowerarm02"))
    u, v = s - e, w - e
    return np.degrees(np.arccos(u @ v / np.linalg.norm(u) / np.linalg.norm(v)))


def test_shapes_and_units(anny_body):
    b = anny_body
    n = b.n_vertices
    assert b.rest_vertices.shape == (n, 3) and b.faces.shape[1] == 3
    assert b.posed_vertices.shape == (len(b.motion_names), n, 3)
    assert b.skin_indices.shape == b.skin_weights.shape == (n, b.skin_indices.shape[1])
    np.testing.assert_allclose(b.skin_weights.sum(1), 1.0, atol=1e-6)
    height = np.ptp(b.rest_vertices[:, 2])
    assert 1.4 < height < 2.0, "metres, Z up"
    # faces -Y: the toes stick out towards -Y from the heels
    toe, foot = _j(b, "rest", "toe1-1.L"), _j(b, "rest", "foot.L")
    assert toe[1] < foot[1]
    # outward winding: positive enclosed volume
    tri = b.rest_vertices[b.faces]
    vol = np.einsum("ij,ij->i", tri[:, 0], np.cross(tri[:, 1], tri[:, 2])).sum() / 6
    assert 0.03 < vol < 0.15  # m^3, a human body
    nrm = b.normals()
    np.testing.assert_allclose(np.linalg.norm(nrm, axis=1), 1.0, atol=1e-9)


def test_rest_pose_is_an_a_pose(anny_body):
    b = anny_body
    d = _j(b, "rest", "wrist.L") - _j(b, "rest", "upperarm01.L")
    assert 20 < np.degrees(np.arctan2(-d[2], d[0])) < 60  # arms about 45 degrees down


def test_arms_raise_lifts_wrists(anny_body):
    for side in "LR":
        lift = _j(anny_body, "arms_raise", f"wrist.{side}")[2] - _j(anny_body, "rest", f"wrist.{side}")[2]
        assert lift > 0.20


def test_arms_forward_moves_wrists_forward(anny_body):
    for side in "LR":
        d = _j(anny_body, "arms_forward", f"wrist.{side}") - _j(anny_body, "rest", f"wrist.{side}")
        assert d[1] < -0.15 and d[2] > 0.0


def test_bend_forward_moves_head_forward_and_down(anny_body):
    d = _j(anny_body, "bend_forward", "head") - _j(anny_body, "rest", "head")
    assert d[1] < -0.15 and d[2] < -0.05


def test_elbow_flexion_and_extension_by_configured_amount(anny_body):
    for side in "LR":
        rest = _elbow_angle(anny_body, "rest", side)
        assert rest - _elbow_angle(anny_body, "arm_flexion", side) == pytest.approx(46.0, abs=1e-6)
        assert _elbow_angle(anny_body, "arm_extension", side) - rest == pytest.approx(40.0, abs=1e-6)


def test_one_sided_variants_move_one_side(anny_body):
    b = anny_body
    left = _j(b, "arms_raise.left", "wrist.L")[2] - _j(b, "rest", "wrist.L")[2]
    right_still = np.linalg.norm(_j(b, "arms_raise.left", "wrist.R") - _j(b, "rest", "wrist.R"))
    assert left > 0.2 and right_still < 1e-9
    # the right variant is the mirror image of the left one (Anny is left-right symmetric)
    mir = np.array([-1.0, 1.0, 1.0])
    pl = _j(b, "arms_raise.left", "wrist.L") * mir
    pr = _j(b, "arms_raise.right", "wrist.R")
    assert np.linalg.norm(pl - pr) < 0.01


def test_knee_flexion_moves_ankle_back_and_up(anny_body):
    d = _j(anny_body, "knee_flexion", "foot.L") - _j(anny_body, "rest", "foot.L")
    assert d[1] > 0.1 and d[2] > 0.05


def test_twist_turns_shoulders_left(anny_body):
    d = _j(anny_body, "torso_twist_left", "shoulder01.L") - _j(anny_body, "rest", "shoulder01.L")
    assert d[1] > 0.02  # the left shoulder goes back when turning left


def test_motion_interpolation():
    m = Motion("m", ((Rotation("a", "x", 10.0),), (Rotation("a", "x", 30.0), Rotation("b", "y", 20.0))))
    assert {r.degrees for r in m.at(0.0)} == {0.0}
    assert {(r.bone, r.degrees) for r in m.at(1.0)} == {("a", 30.0), ("b", 20.0)}
    half = {r.bone: r.degrees for r in m.at(0.5)}
    assert half == {"a": 10.0, "b": 0.0}
    assert {r.bone: r.degrees for r in m.at(0.75)} == {"a": 20.0, "b": 10.0}


def test_hinge_axis_is_perpendicular(anny_body):
    b = anny_body
    ax = resolve_axis(Rotation("lowerarm01.L", "hinge", 1.0), b.bone_names, b.bone_parents, b.rest_joints)
    up = _j(b, "rest", "lowerarm01.L") - _j(b, "rest", "upperarm02.L")
    assert abs(ax @ up) < 1e-9 and abs(np.linalg.norm(ax) - 1) < 1e-12


def test_cache_is_hit_on_second_load(tmp_path, monkeypatch):
    monkeypatch.setenv("KGARMENT_CACHE_DIR", str(tmp_path))
    m = [builtin_motions()["arm_flexion.left"]]
    first = load_anny_body(m, Phenotype(height=0.7))
    assert any(tmp_path.rglob("pose-*.npz")) and any(tmp_path.rglob("rest.npz"))
    from kgarment.body import anny_backend

    def boom(self):
        raise AssertionError("Anny was loaded although the cache should have been hit")

    monkeypatch.setattr(anny_backend._AnnyModel, "model", boom)
    second = load_anny_body(m, Phenotype(height=0.7))
    np.testing.assert_array_equal(first.posed_vertices, second.posed_vertices)


def test_phenotype_changes_the_body(anny_body, tmp_path, monkeypatch):
    monkeypatch.setenv("KGARMENT_CACHE_DIR", str(tmp_path))
    tall = load_anny_body([], Phenotype(height=1.0))
    assert np.ptp(tall.rest_vertices[:, 2]) > np.ptp(anny_body.rest_vertices[:, 2]) + 0.05


@pytest.mark.parametrize("value", [-0.1, 1.5])
def test_phenotype_out_of_range(value):
    with pytest.raises(KgarmentError, match=r"outside \[0, 1\]"):
        Phenotype(weight=value)


def test_unknown_bone_is_a_user_error(anny_body):
    bad = Motion("bad", ((Rotation("elbow.X", "x", 10.0),),))
    with pytest.raises(KgarmentError, match="unknown bone 'elbow.X'; valid: .*lowerarm01.L"):
        load_anny_body([bad])
