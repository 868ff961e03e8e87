"""Portable clutch files: round trips, other meshes of the same surface, malformed files."""

from __future__ import annotations

import json

import numpy as np
import pytest
import trimesh

from kgarment.clutch import (
    ClutchError,
    ClutchSpec,
    MeshTopology,
    build_clutch,
    load_clutches,
    save_clutches,
)
from kgarment.clutch.samples import open_prism


def mesh_pair(V, F):
    """The mesh and its midpoint subdivision (the same surface, 4x the faces)."""
    V2, F2 = trimesh.remesh.subdivide(V, F)
    return (V, F, MeshTopology(V, F)), (np.asarray(V2, float), np.asarray(F2, np.int64),
                                        MeshTopology(V2, F2))


@pytest.fixture(scope="module")
def spheres():
    m = trimesh.creation.icosphere(subdivisions=3, radius=0.1)
    return mesh_pair(np.asarray(m.vertices, float), np.asarray(m.faces, np.int64))


@pytest.fixture(scope="module")
def prisms():
    return mesh_pair(*open_prism(0.05, 0.3, 16, 30))


def specs_on(topo):
    return [
        ClutchSpec("upper_back", (10, (0.2, 0.3, 0.5)), {"bary": (0.4, -0.1, -0.3)}, 0.135,
                   width=0.01, prestrain=0.95),
        ClutchSpec("elbow", (200, (0.6, 0.2, 0.2)), {"bary_point": (0.2, 0.6, 0.2)}, 0.08),
        ClutchSpec("forearm", tuple(topo.V[topo.F[300]].mean(axis=0)), (0.0, 0.3, 1.0), 0.1,
                   width=0.012, clip=True),
    ]


@pytest.mark.parametrize("suffix", [".toml", ".json"])
@pytest.mark.parametrize("which", ["spheres", "prisms"])
def test_round_trip_and_onto_a_subdivided_mesh(tmp_path, suffix, which, request):
    (V, F, topo), (V2, F2, topo2) = request.getfixturevalue(which)
    specs = specs_on(topo)
    path = tmp_path / f"clutches{suffix}"
    save_clutches(path, specs, V, F, topology=topo)
    assert b"face" not in path.read_bytes()  # no face ids in the file
    loaded = load_clutches(path)
    assert [s.name for s in loaded] == ["upper_back", "elbow", "forearm"]
    assert loaded[2] == specs[2]  # given in 3D: stored as it is
    assert [(s.length, s.width, s.prestrain, s.clip) for s in loaded] == \
        [(s.length, s.width, s.prestrain, s.clip) for s in specs]
    for spec, back in zip(specs, loaded):
        ref = build_clutch(spec, V, F, topo)
        same = build_clutch(back, V, F, topo)
        other = build_clutch(back, V2, F2, topo2)
        ends = ref.vertices[ref.centerline[[0, -1]]]
        assert np.abs(same.vertices[same.centerline[[0, -1]]] - ends).max() < 1e-9
        assert np.abs(other.vertices[other.centerline[[0, -1]]] - ends).max() < 1e-3
        assert np.abs(other.vertices[other.anchors] - ref.vertices[ref.anchors]).max() < 1e-3
    # saving again gives the same file
    again = tmp_path / f"again{suffix}"
    save_clutches(again, loaded)
    assert load_clutches(again) == loaded


def test_strips_are_saved_by_rest_coordinates(tmp_path, spheres, prisms):
    for (V, F, topo), (V2, F2, topo2) in (spheres, prisms):
        strips = [build_clutch(s, V, F, topo) for s in specs_on(topo)]
        save_clutches(tmp_path / "strips.toml", strips)
        for strip, spec in zip(strips, load_clutches(tmp_path / "strips.toml")):
            other = build_clutch(spec, V2, F2, topo2)
            assert spec.name == strip.name and spec.prestrain == strip.prestrain
            assert np.isclose(other.length, strip.length)
            a, b = strip.vertices[strip.anchors], other.vertices[other.anchors]
            assert np.abs(a - b).max() < 1e-3


def test_landmarks_are_kept_by_name(tmp_path):
    spec = ClutchSpec("c", "shoulder", {"towards": "elbow"}, 0.1)
    save_clutches(tmp_path / "c.toml", [spec])
    assert load_clutches(tmp_path / "c.toml") == [spec]


def test_saving_face_based_specs_needs_the_mesh(tmp_path):
    with pytest.raises(ClutchError, match=r"clutch 'c' is given by face ids"):
        save_clutches(tmp_path / "c.toml", [ClutchSpec("c", (1, (1, 0, 0)), (1, 0, 0), 0.1)])
    with pytest.raises(ClutchError, match="duplicate clutch names"):
        save_clutches(tmp_path / "c.toml", [ClutchSpec("c", (0, 0, 0), (1, 0, 0), 0.1)] * 2)


GOOD = {"name": "c", "start": [0.0, 0.1, 0.0], "direction": [1.0, 0.0, 0.0], "length": 0.1}


@pytest.mark.parametrize(
    "change, match",
    [
        ({"length": None}, r"clutch 'c': field 'length' is missing"),
        ({"length": "10cm"}, r"clutch 'c': field 'length' must be a number"),
        ({"length": -1.0}, r"clutch 'c': field 'length' must be > 0"),
        ({"width": 0}, r"clutch 'c': field 'width' must be > 0"),
        ({"prestrain": 2.0}, r"clutch 'c': field 'prestrain' must be in"),
        ({"start": [0.0, 0.1]}, r"clutch 'c': field 'start' must be \[x, y, z\]"),
        ({"direction": "up"}, r"clutch 'c': field 'direction' must be \[x, y, z\]"),
        ({"towards": [0, 0, 1]}, r"clutch 'c': give exactly one of fields 'direction'"),
        ({"face": 3}, r"clutch 'c': unknown field\(s\) \['face'\]"),
        ({"name": 3}, r"clutch #0: field 'name'"),
        ({"clip": "no"}, r"clutch 'c': field 'clip' must be true or false"),
    ],
)
def test_malformed_files(tmp_path, change, match):
    rec = {k: v for k, v in {**GOOD, **change}.items() if v is not None}
    path = tmp_path / "bad.json"
    path.write_text(json.dumps({"format": "kgarment.clutches", "version": 1, "clutch": [rec]}))
    with pytest.raises(ClutchError, match=r"bad.json: " + match):
        load_clutches(path)


def test_malformed_documents(tmp_path):
    path = tmp_path / "bad.toml"
    path.write_text("[[clutch]]\nname = 'c'\nlength = \n")
    with pytest.raises(ClutchError, match=r"bad.toml: not a valid clutch file"):
        load_clutches(path)
    path.write_text("format = 'something else'\n")
    with pytest.raises(ClutchError, match=r"bad.toml: field 'format'"):
        load_clutches(path)
    path.write_text("version = 7\n")
    with pytest.raises(ClutchError, match=r"bad.toml: field 'version'"):
        load_clutches(path)
    path.write_text("clutch = 3\n")
    with pytest.raises(ClutchError, match=r"bad.toml: field 'clutch'"):
        load_clutches(path)
    rec = "[[clutch]]\nname = 'c'\nstart = [0, 0, 0]\ndirection = [1, 0, 0]\nlength = 0.1\n"
    path.write_text(rec + rec)
    with pytest.raises(ClutchError, match=r"bad.toml: duplicate clutch names \['c'\]"):
        load_clutches(path)
    path.write_text(rec)
    assert load_clutches(path) == [ClutchSpec("c", (0, 0, 0), (1, 0, 0), 0.1)]


def test_written_files_have_the_usual_permissions(tmp_path):
    """Atomic writes go through a private temporary file; the result is readable like a
    file opened for writing (0666 less the umask), not 0600."""
    import os
    import stat

    from kgarment.io import atomic_write_text

    mask = os.umask(0o022)
    os.umask(mask)
    path = atomic_write_text(tmp_path / "a.txt", "x")
    assert stat.S_IMODE(path.stat().st_mode) == 0o666 & ~mask
    with open(tmp_path / "b.txt", "w") as f:
        f.write("x")
    assert stat.S_IMODE(path.stat().st_mode) == stat.S_IMODE((tmp_path / "b.txt").stat().st_mode)
