"""ClutchSpec: the ways to give a start and a direction, and validation."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

from kgarment.clutch import (
    BaryDirection,
    ClutchError,
    ClutchSpec,
    MeshTopology,
    SurfacePoint,
    Towards,
    build_clutch,
    resolve_start,
)
from kgarment.clutch.samples import flat_sheet


@pytest.fixture(scope="module")
def sphere():
    m = trimesh.creation.icosphere(subdivisions=4, radius=0.1)
    V, F = np.asarray(m.vertices, float), np.asarray(m.faces, np.int64)
    return V, F, MeshTopology(V, F)


@pytest.fixture(scope="module")
def sheet():
    V, F = flat_sheet(0.3, 30, jitter=0.2, seed=4)
    return V, F, MeshTopology(V, F)


LANDMARKS = {"shoulder": (0.0, 0.0, 0.1), "elbow": (0.1, 0.0, 0.0), "wrist": (0.0, 0.1, 0.0)}


def test_start_and_direction_forms_give_the_same_clutch(sphere):
    V, F, topo = sphere
    f = 123
    b = np.array([0.2, 0.5, 0.3])
    x0 = b @ V[F[f]]
    P = V[F[f]]
    db = np.array([0.3, -0.1, -0.2])
    d3 = db @ P
    ref = build_clutch(ClutchSpec("c", (f, b), {"bary": db}, 0.1), V, F, topo)
    lm = {"here": x0 + 0.004 * topo.normal[f], "there": x0 + 0.05 * d3 / np.linalg.norm(d3)}
    forms = [
        ClutchSpec("c", SurfacePoint(f, tuple(b)), BaryDirection(tuple(db)), 0.1),
        ClutchSpec("c", (f, list(b)), {"bary_point": b + 0.1 * db}, 0.1),
        ClutchSpec("c", {"face": f, "bary": b}, 7.0 * d3 + 0.3 * topo.normal[f], 0.1),
        ClutchSpec("c", x0 + 0.004 * topo.normal[f], d3, 0.1),  # 4 mm off: snapped
        ClutchSpec("c", "here", {"towards": "there"}, 0.1),
        ClutchSpec("c", "here", Towards(tuple(x0 + 1e-3 * d3)), 0.1),
    ]
    for spec in forms:
        s = build_clutch(spec, V, F, topo, landmarks=lm)
        assert np.abs(s.vertices - ref.vertices).max() < 1e-12
    st = resolve_start(forms[3], V, F, topo)
    assert np.allclose(st.point, x0) and np.isclose(np.linalg.norm(st.direction), 1)


def test_spec_is_normalised_and_hashable():
    s = ClutchSpec("a", np.array([0.1, 0.2, 0.3]), [1, 0, 0], 0.1, width=0.02, prestrain=0.95)
    assert s.start == (0.1, 0.2, 0.3) and s.direction == (1.0, 0.0, 0.0)
    assert s == ClutchSpec("a", (0.1, 0.2, 0.3), (1.0, 0.0, 0.0), 0.1, 0.02, 0.95)
    assert hash(s) == hash(ClutchSpec("a", (0.1, 0.2, 0.3), (1.0, 0.0, 0.0), 0.1, 0.02, 0.95))
    assert ClutchSpec("b", (3, (1, 0, 0)), {"towards": "elbow"}, 1).start == SurfacePoint(
        3, (1.0, 0.0, 0.0))


@pytest.mark.parametrize(
    "kwargs, match",
    [
        ({"length": 0.0}, r"clutch 'bad': field 'length' must be > 0"),
        ({"length": -0.1}, r"clutch 'bad': field 'length' must be > 0"),
        ({"length": "long"}, r"clutch 'bad': field 'length' must be a number"),
        ({"width": 0.0}, r"clutch 'bad': field 'width' must be > 0"),
        ({"width": -0.01}, r"clutch 'bad': field 'width' must be > 0"),
        ({"width": float("nan")}, r"clutch 'bad': field 'width' must be > 0"),
        ({"prestrain": 0.0}, r"clutch 'bad': field 'prestrain' must be in \(0, 1\]"),
        ({"prestrain": 1.2}, r"clutch 'bad': field 'prestrain' must be in \(0, 1\]"),
        ({"start": (1, 2)}, r"clutch 'bad': field 'start'"),
        ({"start": (0, (0.5, 0.6, 0.1))}, r"clutch 'bad': field 'start': barycentric"),
        ({"direction": (0, 0, 0)}, r"clutch 'bad': field 'direction' is the zero vector"),
        ({"direction": {"bary": (1, 0, 0)}}, r"clutch 'bad': field 'direction'.*sum to 0"),
        ({"direction": {"to": "x"}}, r"clutch 'bad': field 'direction'"),
        ({"clip": "yes"}, r"clutch 'bad': field 'clip'"),
    ],
)
def test_bad_fields(kwargs, match):
    args = {"name": "bad", "start": (0.1, 0.1, 0.0), "direction": (1, 0, 0), "length": 0.1}
    args.update(kwargs)
    with pytest.raises(ClutchError, match=match):
        ClutchSpec(**args)


def test_bad_placements(sphere, sheet):
    V, F, topo = sphere
    with pytest.raises(ClutchError, match=r"clutch 'far': start point is 3.0 cm from the garment"):
        build_clutch(ClutchSpec("far", (0, 0, 0.13), (1, 0, 0), 0.1), V, F, topo)
    with pytest.raises(ClutchError, match=r"clutch 'lm': unknown landmark 'knee' in field "
                                          r"'start'; valid names: elbow, shoulder, wrist"):
        build_clutch(ClutchSpec("lm", "knee", (1, 0, 0), 0.1), V, F, topo, landmarks=LANDMARKS)
    with pytest.raises(ClutchError, match=r"clutch 'lm': unknown landmark 'hip' in field "
                                          r"'direction'; valid names: elbow, shoulder, wrist"):
        build_clutch(ClutchSpec("lm", "elbow", {"towards": "hip"}, 0.1), V, F, topo,
                     landmarks=LANDMARKS)
    with pytest.raises(ClutchError, match=r"clutch 'lm'.*no landmarks were given"):
        build_clutch(ClutchSpec("lm", "elbow", (1, 0, 0), 0.1), V, F, topo)
    with pytest.raises(ClutchError, match=r"clutch 'n': field 'direction' is normal"):
        n = topo.normal[topo.closest_point(LANDMARKS["elbow"]).face]
        build_clutch(ClutchSpec("n", "elbow", n, 0.1), V, F, topo, landmarks=LANDMARKS)
    with pytest.raises(ClutchError, match=r"clutch 'f': field 'start': face 99999 is not a face"):
        build_clutch(ClutchSpec("f", (99999, (1, 0, 0)), (1, 0, 0), 0.1), V, F, topo)
    V, F, topo = sheet
    with pytest.raises(ClutchError, match=r"clutch 'edge' leaves the garment after 5.0 cm"):
        build_clutch(ClutchSpec("edge", (0.25, 0.1, 0), (1, 0, 0), 0.1), V, F, topo)
    with pytest.raises(ClutchError, match=r"clutch 'wide' is wider than the garment"):
        build_clutch(ClutchSpec("wide", (0.1, 0.02, 0), (1, 0, 0), 0.1, width=0.05), V, F, topo)
    other = MeshTopology(*flat_sheet(0.3, 10))
    with pytest.raises(ClutchError, match=r"clutch 'x': the topology was built for another mesh"):
        build_clutch(ClutchSpec("x", (0.1, 0.1, 0), (1, 0, 0), 0.1), V, F, other)
