"""Renders, the mesh-sequence backend and the command line, as a user meets them."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh
from cli_runner import run_cli

from kgarment.body import load_mesh_sequence
from kgarment.cli import main
from kgarment.errors import KgarmentError
from kgarment.render import render_png, render_scene
from kgarment.render.raster import Layer


def _image(path):
    from PIL import Image

    return np.asarray(Image.open(path).convert("RGB"))


def test_render_png_size_and_content(tmp_path):
    s = trimesh.creation.icosphere(3)
    p = render_png([Layer(s.vertices, s.faces, (1.0, 0.0, 0.0, 1.0), cull=True)], tmp_path / "a.png",
                   views=("front", "left"), height_px=200)
    im = _image(p)
    assert im.shape[0] == 200
    red = (im[..., 0] > 120) & (im[..., 1] < 60) & (im[..., 2] < 60)
    # two disks: the sphere fills a fair share of each panel
    assert 0.2 < red.mean() < 0.8


def test_render_png_draws_the_nearer_face_over_the_farther(tmp_path):
    """Two squares seen from the front (camera towards -y): a red one 1 m nearer than a
    blue one, half overlapping it. Given in either order, the overlap must be red; the
    blue square's uncovered half stays blue."""
    sq = np.array([[0, 0, 0], [1, 0, 0], [1, 0, 1], [0, 0, 1]], float)
    faces = np.array([[0, 1, 2], [0, 2, 3]])
    red = Layer(sq + [0.5, -1.0, 0.0], faces, (1.0, 0.0, 0.0, 1.0))
    blue = Layer(sq, faces, (0.0, 0.0, 1.0, 1.0))
    for k, layers in enumerate(([red, blue], [blue, red])):
        im = _image(render_png(layers, tmp_path / f"{k}.png", views=("front",), height_px=200))
        is_red = (im[..., 0] > 100) & (im[..., 2] < 60)
        is_blue = (im[..., 2] > 100) & (im[..., 0] < 60)
        # the picture spans 1.5 m; red covers 2/3 of the squares' width, blue the first third
        cols_red, cols_blue = is_red.any(axis=0).sum(), is_blue.any(axis=0).sum()
        assert cols_red == pytest.approx(2 * cols_blue, rel=0.1)


def test_render_scene_with_values(tmp_path, anny_body, shirt0):
    vals = np.linspace(0, 1, shirt0.n_faces)
    p = render_scene(tmp_path / "s.png", anny_body.vertices("arms_raise"), anny_body.faces,
                     shirt0.vertices("arms_raise"), shirt0.faces, shirt0.attached, face_values=vals,
                     views=("front",), height_px=300, value_label="J/m^2")
    im = _image(p)
    assert im.shape[0] == 300 and (im.std(axis=(0, 1)) > 10).all()


def _write_seq(tmp_path, n_motions=2, bad=False):
    s = trimesh.creation.icosphere(2)
    s.export(tmp_path / "rest.obj")
    paths = {}
    for k in range(n_motions):
        v = s.vertices * (1 + 0.1 * (k + 1))
        f = s.faces[:-1] if bad and k == 1 else s.faces
        trimesh.Trimesh(v, f, process=False).export(tmp_path / f"m{k}.ply")
        paths[f"m{k}"] = tmp_path / f"m{k}.ply"
    return s, paths


def test_mesh_sequence_backend(tmp_path):
    s, paths = _write_seq(tmp_path)
    b = load_mesh_sequence(tmp_path / "rest.obj", paths)
    assert b.motion_names == ("m0", "m1") and not b.rigged
    np.testing.assert_allclose(b.vertices("m1"), s.vertices * 1.2, atol=1e-6)
    np.testing.assert_array_equal(b.faces, s.faces)


def test_mesh_sequence_mismatch_and_missing(tmp_path):
    _, paths = _write_seq(tmp_path, bad=True)
    with pytest.raises(KgarmentError, match="does not share the rest mesh's topology"):
        load_mesh_sequence(tmp_path / "rest.obj", paths)
    with pytest.raises(KgarmentError, match="mesh file not found"):
        load_mesh_sequence(tmp_path / "nope.obj", {})


@pytest.mark.parametrize("cmd", [[], ["motions"], ["garments"], ["render"], ["demo"], ["clutches"], ["simulate"], ["design"], ["evaluate"], ["examples"], ["fabricate"], ["studio"]])
def test_help_everywhere(cmd, capsys):
    with pytest.raises(SystemExit) as e:
        main(cmd + ["--help"])
    assert e.value.code == 0
    assert "usage: kgarment" in capsys.readouterr().out


def test_version(capsys):
    with pytest.raises(SystemExit):
        main(["--version"])
    assert capsys.readouterr().out.startswith("kgarment ")


@pytest.mark.parametrize("toml, message", [
    ('[motions]\nuse = ["moonwalk"]\n', "unknown motion 'moonwalk'; valid:"),
    ('[body]\nphenotype = { weight = 1.5 }\n', "phenotype weight = 1.5 is outside [0, 1]"),
    ('[garment]\ntemplate = "cape"\n', "unknown garment 'cape'; valid:"),
    ('[garment]\nsubdivision = 7\n', "subdivision = 7; allowed: 0, 1, 2, 3"),
    ('[motions.define.w]\nrotations = [{ bone = "elbow", axis = "q", degrees = 3 }]\n', "unknown axis"),
    ('[garmnet]\n', "unknown field 'garmnet'"),
    ('[body\n', "is not valid TOML"),
    ('[body]\nmodel = "meshes"\nrest = "missing.obj"\nmotions = {}\n', "file not found"),
])
def test_bad_problem_files_exit_2_with_one_line(tmp_path, toml, message):
    (tmp_path / "p.toml").write_text(toml)
    rc, out, err = run_cli(["render", "p.toml"], tmp_path)
    assert rc == 2
    assert err.count("\n") == 1 and "Traceback" not in err
    assert message in err


def test_missing_problem_file(tmp_path):
    rc, _, err = run_cli(["render", "nothere.toml"], tmp_path)
    assert rc == 2 and "problem file not found" in err


def test_unknown_bone_in_user_motion(tmp_path, anny_body):
    (tmp_path / "p.toml").write_text(
        '[motions]\nuse = ["w"]\n[motions.define.w]\nrotations = [{ bone = "elbow", axis = "x", degrees = 3 }]\n')
    rc, _, err = run_cli(["render", "p.toml"], tmp_path)
    assert rc == 2 and "unknown bone 'elbow'; valid:" in err


def test_motions_rejects_a_user_motion_with_an_unknown_bone(tmp_path, anny_body):
    """`kgarment motions p.toml` checks the problem's own motions on Anny's rig, as `render` does."""
    (tmp_path / "p.toml").write_text(
        '[motions]\nuse = ["arms_raise"]\n[motions.define.w]\nrotations = [{ bone = "elbow", axis = "x", degrees = 3 }]\n')
    rc, out, err = run_cli(["motions", "p.toml"], tmp_path)
    assert rc == 2 and err.count("\n") == 1 and "[motions.define.w]: unknown bone 'elbow'; valid:" in err
    assert out == ""
    (tmp_path / "p.toml").write_text(
        '[motions]\nuse = ["arms_raise"]\n[motions.define.w]\nrotations = [{ bone = "lowerarm01.L", axis = "x", degrees = 3 }]\n')
    rc, out, err = run_cli(["motions", "p.toml"], tmp_path)
    assert rc == 0, err
    assert [line.split()[0] for line in out.splitlines()][-1] == "w"


def test_render_command_with_user_motion(tmp_path, anny_body):
    (tmp_path / "p.toml").write_text(
        '[motions]\nuse = ["wave"]\n[motions.define.wave]\n'
        'rotations = [{ bone = "upperarm01.L", axis = "-y", degrees = 60 }]\n'
        '[garment]\ntemplate = "arm_sleeve.left"\nsubdivision = 0\n')
    rc, out, err = run_cli(["render", "p.toml", "--views", "front", "--out", "pics"], tmp_path)
    assert rc == 0, err
    assert (tmp_path / "pics" / "arm_sleeve.left_wave.png").is_file()
    assert "motions: wave" in out


def test_motions_lists_the_paper_motions(tmp_path):
    rc, out, _ = run_cli(["motions"], tmp_path)
    assert rc == 0
    for m in ("arms_forward", "arms_raise", "arm_flexion", "arm_extension", "bend_forward", "knee_flexion"):
        assert m in out


def test_clutches_show_and_suggest(tmp_path, anny_body):
    (tmp_path / "p.toml").write_text(
        '[garment]\ntemplate = "arm_sleeve.right"\nsubdivision = 0\n'
        '[motions]\nuse = ["arm_flexion"]\n'
        '[clutches]\nlayout = "arm_flexion"\n'
        '[[clutches.clutch]]\nname = "extra"\nstart = "forearm_inner.R"\ntowards = "elbow_inner.R"\nlength = 0.03\n')
    rc, out, err = run_cli(["clutches", "show", "p.toml", "--out", "c"], tmp_path)
    assert rc == 0, err
    assert "elbow_outer.R" in out and "extra" in out
    assert (tmp_path / "c" / "clutches.png").is_file()
    rc, out, err = run_cli(["clutches", "suggest", "p.toml", "--count", "1", "--length", "0.05", "--out", "c"], tmp_path)
    assert rc == 0, err
    from kgarment.clutch import load_clutches

    assert [s.name for s in load_clutches(tmp_path / "c" / "suggested.toml")] == ["suggested0"]
    # elbow flexion stretches the sleeve over the elbow, where the clutch goes: it is felt
    assert "arm_flexion: can be felt through suggested0" in out
    rc, _, err = run_cli(["clutches", "show", "p.toml", "--out", "c"], tmp_path)
    assert rc == 2 and "use --force" in err


@pytest.mark.parametrize("clutch, message", [
    ('name = "x"\nstart = "nowhere"\ndirection = [1, 0, 0]\nlength = 0.05\n', "unknown landmark"),
    ('name = "x"\nstart = "elbow_outer.R"\ndirection = [1, 0, 0]\nlength = -1\n', "length"),
    ('name = "x"\nstart = [0, 0, 5]\ndirection = [1, 0, 0]\nlength = 0.05\n', "from the garment"),
    ('name = "x"\nstart = "elbow_outer.R"\ndirection = [1, 0, 0]\nlength = 0.05\nwidth = 0.5\n', "x"),
])
def test_bad_clutches_exit_2(tmp_path, anny_body, clutch, message):
    (tmp_path / "p.toml").write_text('[garment]\ntemplate = "arm_sleeve.right"\nsubdivision = 0\n'
                                     '[motions]\nuse = ["arm_flexion"]\n[[clutches.clutch]]\n' + clutch)
    rc, _, err = run_cli(["clutches", "show", "p.toml", "--out", "c"], tmp_path)
    assert rc == 2 and "Traceback" not in err and message in err and "'x'" in err
