"""Fabrication: flattening, patches and seams, clean-up, cut files, buttons, PDF scale, 3D files."""
# ruff: noqa: F811  (pytest fixtures imported from test_fabricate_support)

from __future__ import annotations

import xml.etree.ElementTree as ET

import numpy as np
import pytest
import trimesh
from test_fabricate_support import band_design, sleeve, sleeve_clutches  # noqa: F401  (fixtures)

from kgarment.fabricate import (
    CleanupOptions,
    PatternOptions,
    clean_design,
    fabricate,
    flatten,
    make_patterns,
)
from kgarment.fabricate.cleanup import clutch_end_faces
from kgarment.fabricate.outline import inside, point_segment_distance, polygon_area, smooth_outline
from kgarment.fabricate.patches import patch_mesh, split_patches


def cylinder(radius=0.05, height=0.2, arc=2.0, nu=30, nv=15, closed=False):
    """A (chordal) cylinder patch: vertices (n, 3), faces (f, 3); ``closed`` makes a ring."""
    th = np.linspace(0, 2 * np.pi, nu, endpoint=False) if closed else np.linspace(0, arc, nu)
    z = np.linspace(0, height, nv)
    T, Z = np.meshgrid(th, z)
    V = np.stack([radius * np.cos(T), radius * np.sin(T), Z], -1).reshape(-1, 3)
    F = []
    for i in range(nv - 1):
        for j in range(nu if closed else nu - 1):
            a, b = i * nu + j, i * nu + (j + 1) % nu
            F += [[a, b, b + nu], [a, b + nu, a + nu]]
    return V, np.array(F)


# ---------------------------------------------------------------- flattening


@pytest.mark.parametrize("method", ["arap", "lscm"])
def test_developable_patch_flattens_isometrically(method):
    V, F = cylinder()
    fl = flatten(V, F, method)
    assert fl.flipped == 0
    assert fl.area_2d == pytest.approx(fl.area_3d, rel=1e-6)
    assert fl.max_length_distortion < 1e-6
    # the 2D pattern shows the outside: every triangle counter-clockwise
    from kgarment.fabricate.flatten import signed_areas

    assert (signed_areas(fl.uv, F) > 0).all()


def test_sleeve_band_area_within_one_percent(sleeve, band_design):
    solid = band_design[0] > 0.5
    solid[band_design[1]] = False
    pats = make_patterns(sleeve.rest_vertices, sleeve.faces, solid)
    total = sum(p.flat.area_3d for p in pats.patches)
    assert total == pytest.approx(sleeve.face_areas()[solid].sum(), rel=1e-9)
    for p in pats.patches:
        assert p.flat.area_2d == pytest.approx(p.flat.area_3d, rel=0.01)
        assert p.flat.max_length_distortion <= 0.05
        assert p.flat.flipped == 0


def test_ring_is_opened_along_one_short_seam():
    V, F = cylinder(closed=True)
    pats = make_patterns(V, F, np.ones(len(F), bool))
    assert len(pats.patches) == 1 and len(pats.seams) == 1
    assert pats.seams[0].kind == "hole"
    assert pats.seams[0].length(V) == pytest.approx(0.2, rel=1e-6)  # straight up the cylinder
    p = pats.patches[0]
    assert len(p.mesh.loops()) == 1
    assert p.flat.max_length_distortion < 1e-6
    assert p.flat.area_2d == pytest.approx(p.flat.area_3d, rel=1e-6)


def test_distorted_patch_is_split_and_gets_better():
    s = trimesh.creation.icosphere(3)
    V = 0.1 * s.vertices
    cap = V[s.faces].mean(axis=1)[:, 2] > 0.03
    whole = split_patches(V, s.faces, cap)[0]
    before = flatten(whole.vertices, whole.faces).max_length_distortion
    pats = make_patterns(V, s.faces, cap, PatternOptions(max_distortion=0.05, max_cuts=6))
    assert len(pats.patches) > 1 and all(sm.kind == "split" for sm in pats.seams)
    worst = max(p.flat.max_length_distortion for p in pats.patches)
    assert worst < 0.5 * before
    faces = np.sort(np.concatenate([p.mesh.garment_face for p in pats.patches]))
    assert np.array_equal(faces, np.flatnonzero(cap))  # every face on exactly one patch


def test_bowtie_vertex_is_split():
    V = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [-1, 0, 0], [0, -1, 0.0]])
    F = np.array([[0, 1, 2], [0, 3, 4]])
    p = patch_mesh(V, F, np.arange(2))
    assert len(p.vertices) == 6 and sorted(p.garment_vertex.tolist()) == [0, 0, 1, 2, 3, 4]
    assert len(split_patches(V, F, np.ones(2, bool))) == 2  # edge-connected pieces


def test_smoothing_keeps_shape_and_area():
    t = np.linspace(0, 2 * np.pi, 80, endpoint=False)
    r = 50 + 2 * (np.arange(80) % 2)  # a zigzag circle, mm
    poly = np.stack([r * np.cos(t), r * np.sin(t)], 1)
    sm = smooth_outline(poly)
    rr = np.linalg.norm(sm, axis=1)
    assert np.ptp(rr) < 0.5 * np.ptp(r)  # the zigzag is gone
    assert polygon_area(sm) == pytest.approx(polygon_area(poly), rel=0.03)
    assert inside(np.array([[0.0, 0.0], [80.0, 0.0]]), sm).tolist() == [True, False]


# ---------------------------------------------------------------- clean-up


def test_cleanup_removes_island_keeps_band(sleeve, sleeve_clutches, band_design):
    design, island = band_design
    no_opening = CleanupOptions(min_width=0.0)
    c = clean_design(sleeve.faces, sleeve.rest_vertices, design, sleeve_clutches[1], sleeve.attached, no_opening)
    assert c.islands_removed == 1 and not c.after[island]
    assert c.after[design > 0.5].sum() == (design > 0.5).sum() - 1
    assert c.area_after < c.area_before
    # with the default 1 cm minimum width a few teeth of the band's jagged edge go too
    d = clean_design(sleeve.faces, sleeve.rest_vertices, design, sleeve_clutches[1], sleeve.attached)
    assert d.islands_removed == 1 and d.after[design > 0.5].mean() > 0.9
    assert not (d.after & ~c.after).any()


def test_cleanup_never_removes_what_touches_a_clutch(sleeve, sleeve_clutches):
    strips = sleeve_clutches[1]
    ends = clutch_end_faces(strips, sleeve.n_faces)
    # only the faces under the clutch ends: two tiny islands, thinner than any minimum width
    harsh = CleanupOptions(min_island_area=1.0, max_hole_area=0.0, min_width=0.1)
    c = clean_design(sleeve.faces, sleeve.rest_vertices, ends, strips, sleeve.attached, harsh)
    assert c.after[ends].all()
    # without the clutches the same islands go
    c2 = clean_design(sleeve.faces, sleeve.rest_vertices, ends, (), None, harsh)
    assert not c2.after.any()


def test_cleanup_fills_small_holes_but_not_under_a_clutch(sleeve, sleeve_clutches):
    from kgarment.fabricate.cleanup import clutch_faces
    from kgarment.garment.topology import face_adjacency

    strips = sleeve_clutches[1]
    under = clutch_faces(strips, sleeve.n_faces)
    adj = face_adjacency(sleeve.faces)
    free = np.flatnonzero(~under & ~sleeve.attached & ((adj @ under.astype(int)) == 0))
    hole = int(free[len(free) // 2])
    mid = int(np.flatnonzero(under & ~clutch_end_faces(strips, sleeve.n_faces))[0])
    solid = np.ones(sleeve.n_faces, bool)
    solid[[hole, mid]] = False
    opts = CleanupOptions(min_width=0.0)
    c = clean_design(sleeve.faces, sleeve.rest_vertices, solid, strips, sleeve.attached, opts)
    assert c.holes_filled == 1 and c.after[hole] and not c.after[mid]


def test_minimum_width_opens_thin_necks():
    V, F = cylinder(arc=2.0, nu=60, nv=40)  # a 10 x 20 cm patch, faces 1.7 x 5 mm
    cen = V[F].mean(axis=1)
    ang = np.arctan2(cen[:, 1], cen[:, 0])
    blobs = (ang < 0.6) | (ang > 1.4)  # two 3 cm wide blocks ...
    neck = np.abs(cen[:, 2] - 0.1) < 0.003  # ... joined by a 5 mm neck
    c = clean_design(F, V, blobs | neck, (), None, CleanupOptions(min_island_area=0, max_hole_area=0, min_width=0.01))
    from kgarment.evaluate.metrics import islands

    assert islands(F, blobs | neck) == 1
    assert c.faces_opened > 0 and islands(F, c.after) == 2  # the neck is cut, stubs may stay
    assert c.after[neck & ~blobs].mean() < 0.2 and c.after[blobs].mean() > 0.9


# ---------------------------------------------------------------- cut files and buttons


@pytest.fixture(scope="module")
def sleeve_fab(sleeve, sleeve_clutches, band_design, tmp_path_factory):
    from kgarment.fabricate import write_fabrication

    fab = fabricate(sleeve, sleeve_clutches[1], band_design[0])
    out = tmp_path_factory.mktemp("fab")
    write_fabrication(fab, out)
    return fab, out


def _svg(path):
    root = ET.parse(path).getroot()
    ns = {"s": "http://www.w3.org/2000/svg"}
    H = float(root.get("viewBox").split()[3])
    assert root.get("width").endswith("mm") and float(root.get("width")[:-2]) == float(root.get("viewBox").split()[2])

    def pts(el):
        a = np.array([[float(v) for v in p.split(",")] for p in el.get("points").split()])
        return np.stack([a[:, 0], H - a[:, 1]], 1)  # back to y up

    polys = {el.get("id"): pts(el) for el in root.iterfind(".//s:polygon", ns) if el.get("id")}
    circles = [(el.get("data-anchor"), np.array([float(el.get("cx")), H - float(el.get("cy"))]))
               for el in root.iterfind(".//s:circle", ns) if el.get("data-anchor")]  # not the legend's
    return polys, circles


def test_svg_and_dxf_agree_at_true_scale(sleeve_fab):
    import ezdxf

    fab, out = sleeve_fab
    polys, circles = _svg(out / "cut_patterns.svg")
    sq = polys["reference-square"]
    assert np.ptp(sq, axis=0) == pytest.approx([100.0, 100.0], abs=1e-3)
    doc = ezdxf.readfile(out / "cut_patterns.dxf")
    assert doc.header["$INSUNITS"] == 4
    msp = doc.modelspace()
    ref = [e for e in msp.query("LWPOLYLINE") if e.dxf.layer == "REFERENCE"]
    assert len(ref) == 1 and np.ptp(np.array(ref[0].get_points("xy")), axis=0) == pytest.approx([100, 100], abs=1e-6)
    for piece in fab.sheet.pieces:
        group = doc.groups.get(piece.label)
        cuts = [np.array(e.get_points("xy")) for e in group if e.dxftype() == "LWPOLYLINE" and e.dxf.layer == "CUT"]
        assert all(e.closed for e in group if e.dxftype() == "LWPOLYLINE" and e.dxf.layer == "CUT")
        assert len(cuts) == len(piece.outlines)
        for k, o in enumerate(piece.outlines):
            s = polys[f"{piece.label}-outline-{k}"]
            assert s.shape == o.shape and np.abs(s - o).max() < 2e-3  # SVG keeps 3 decimals (micrometres)
            assert min(np.abs(d - o).max() if d.shape == o.shape else np.inf for d in cuts) < 1e-9
        circles_ = [e for e in group if e.dxftype() == "CIRCLE"]
        dxf_buttons = np.array([(e.dxf.center.x, e.dxf.center.y) for e in circles_]).reshape(-1, 2)
        order = lambda a: a[np.lexsort(a.T[::-1])]
        assert np.abs(order(dxf_buttons) - order(piece.buttons)).max(initial=0) < 1e-9
    assert len(circles) == sum(len(p.buttons) for p in fab.sheet.pieces) > 0


def test_outline_area_matches_patch_at_scale(sleeve_fab):
    fab, _ = sleeve_fab
    for patch, piece in zip(fab.patterns.patches, fab.sheet.pieces):
        raw = abs(polygon_area(piece.raw_outlines[0])) * 1e-6  # mm^2 -> m^2
        assert raw == pytest.approx(patch.flat.area_2d, rel=1e-6)
        assert abs(polygon_area(piece.outlines[0])) * 1e-6 == pytest.approx(raw, rel=0.05)


def test_buttons_are_the_clutch_anchors_through_the_flattening(sleeve_fab, sleeve):
    fab, out = sleeve_fab
    _, circles = _svg(out / "cut_patterns.svg")
    svg = dict(circles)
    n = 0
    for patch, piece in zip(fab.patterns.patches, fab.sheet.pieces):
        V3 = patch.mesh.vertices
        loops = patch.mesh.loops()
        for c in fab.strips:
            for k, a in enumerate(c.anchors):
                f, bary = int(c.bind_face[a]), c.bind_bary[a]
                lf = patch.face_of(f)
                if lf is None:
                    continue
                name = f"{c.name}:{'start' if k < 3 else 'end'}{k % 3 + 1}"
                b = piece.buttons[piece.button_names.index(name)]
                assert np.abs(svg[name] - b).max() < 2e-3
                # the same barycentric point of the same triangle, flat
                tri2 = piece.to_sheet(patch.flat.uv[patch.mesh.faces[lf]])
                assert np.abs(bary @ tri2 - b).max() < 1e-9
                # the 3D anchor is that barycentric point on the rest garment
                p3 = bary @ sleeve.rest_vertices[sleeve.faces[f]]
                assert np.linalg.norm(p3 - c.vertices[a]) < 1e-6
                # inside the cut outline, as far from its edge as on the body (within 2 mm)
                assert inside(b[None], piece.raw_outlines[0])[0]
                d2 = point_segment_distance(b[None], piece.raw_outlines[0])[0]
                d3 = 1e3 * min(_dist3(p3, V3[lp]) for lp in loops[:1])
                assert d2 == pytest.approx(d3, abs=2.0)
                n += 1
    assert n == 6  # both ends of the elbow clutch lie on the band


def _dist3(p, loop):
    a, b = loop, np.roll(loop, -1, axis=0)
    ab = b - a
    t = np.clip(((p - a) * ab).sum(1) / (ab * ab).sum(1), 0, 1)
    return float(np.linalg.norm(p - (a + t[:, None] * ab), axis=1).min())


def test_pdf_tiles_are_true_scale(sleeve_fab):
    from kgarment.fabricate.preview import INCH, page_size, tile_figure, tiles

    fab, out = sleeve_fab
    pdf = (out / "cut_patterns.pdf").read_bytes()
    assert pdf.startswith(b"%PDF")
    pw, ph = page_size(fab.sheet, "a4")
    ts = tiles(fab.sheet, "a4")
    import re

    assert len(re.findall(rb"/Type\s*/Page\b(?!s)", pdf)) == 1 + len(ts)  # overview + tiles
    fig, ax = tile_figure(fab.sheet, ts[0], pw, ph, 0, len(ts))
    # 100 data units (mm) on the axes are 100 mm of paper
    x0, x1 = ax.transData.transform([[0, 0], [100, 100]]) / fig.dpi * INCH
    assert x1 - x0 == pytest.approx([100, 100], rel=1e-9)
    assert sorted(fig.get_size_inches() * INCH) == pytest.approx(sorted((210.0, 297.0)))


def test_3d_files_have_colours(sleeve_fab, sleeve):
    fab, out = sleeve_fab
    ply = trimesh.load(out / "design_clean.ply", process=False)
    n_clutch = sum(len(c.faces) for c in fab.strips)
    assert len(ply.faces) == sleeve.n_faces + n_clutch
    cols = ply.visual.face_colors
    assert len(np.unique(cols[: sleeve.n_faces], axis=0)) == len(fab.patterns.patches) + 1
    glb = trimesh.load(out / "design_clean.glb")
    assert set(glb.geometry) == {"garment", "clutches"}
    assert glb.geometry["garment"].visual.kind == "vertex"
    obj = (out / "design_clean.obj").read_text()
    first_v = next(line for line in obj.splitlines() if line.startswith("v "))
    assert len(first_v.split()) == 7  # x y z r g b
    with np.load(out / "design_clean.npz") as z:
        assert np.array_equal(z["design"] > 0.5, fab.cleanup.after)


def test_patches_are_turned_up():
    from types import SimpleNamespace

    from kgarment.fabricate import layout_sheet

    V, F = cylinder(nu=20, nv=10)  # axis along +Z: "up" runs straight up the patch
    pats = make_patterns(V, F, np.ones(len(F), bool))
    sheet = layout_sheet(pats, SimpleNamespace(loops={}), [])
    (piece,) = sheet.pieces
    y = piece.to_sheet(pats.patches[0].flat.uv)[:, 1]
    z = pats.patches[0].mesh.vertices[:, 2]
    assert np.allclose(y - 1000 * z, (y - 1000 * z).mean(), atol=1e-6)
    arrow = next(m for m in piece.marks if m.kind == "arrow")
    assert arrow.points[1, 1] > arrow.points[0, 1] and arrow.points[1, 0] == pytest.approx(arrow.points[0, 0])
    assert np.ptp(sheet.square[:, 0]) == np.ptp(sheet.square[:, 1]) == 100.0
