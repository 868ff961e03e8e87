"""Cut sheets a person can sew from: labels, clutch load flags, seam allowance, PDF tiles,
the placement sheet (issue #21)."""
# ruff: noqa: F811  (pytest fixtures imported from test_fabricate_support)

from __future__ import annotations

import argparse
import re
import xml.etree.ElementTree as ET
from types import SimpleNamespace

import numpy as np
import pytest
from test_fabricate_support import band_design, sleeve, sleeve_clutches  # noqa: F401  (fixtures)

from kgarment.fabricate import FabricationOptions, fabricate, with_loads, write_fabrication

NS = {"s": "http://www.w3.org/2000/svg"}
ALLOWANCE = 8.0


@pytest.fixture(scope="module")
def fab_out(sleeve, sleeve_clutches, band_design, tmp_path_factory):
    fab = fabricate(sleeve, sleeve_clutches[1], band_design[0], FabricationOptions(allowance=ALLOWANCE))
    out = tmp_path_factory.mktemp("sheets")
    write_fabrication(fab, out)
    return fab, out


def _rendered_text_boxes(svg):
    """(texts, boxes (k, 4) mm) of every <text> of an SVG, measured by rendering each text
    with matplotlib's Agg renderer (FreeType) at its font size, centred as the SVG says."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    root = ET.parse(svg).getroot()
    fig = plt.figure(dpi=254)  # 10 px per mm
    r = fig.canvas.get_renderer()
    texts, boxes = [], []
    for el in root.iterfind(".//s:text", NS):
        assert el.get("text-anchor") == "middle" and el.get("dominant-baseline") == "middle"
        size = float(el.get("font-size"))
        t = fig.text(0, 0, el.text, fontsize=size * 72 / 25.4, family="sans-serif",
                     weight="bold" if "bold" in el.get("class", "") else "normal")
        e = t.get_window_extent(renderer=r)
        w, h = e.width / 10, e.height / 10
        x, y = float(el.get("x")), float(el.get("y"))
        texts.append(el.text)
        boxes.append([x - w / 2, y - h / 2, x + w / 2, y + h / 2])
    plt.close(fig)
    return texts, np.array(boxes)


def test_no_two_labels_overlap_and_every_clutch_is_named(fab_out):
    fab, out = fab_out
    texts, boxes = _rendered_text_boxes(out / "cut_patterns.svg")
    a, b = np.triu_indices(len(boxes), 1)
    overlap = (boxes[a, 0] < boxes[b, 2]) & (boxes[b, 0] < boxes[a, 2]) & \
              (boxes[a, 1] < boxes[b, 3]) & (boxes[b, 1] < boxes[a, 3])
    assert not overlap.any(), [(texts[i], texts[j]) for i, j in zip(a[overlap], b[overlap])]
    # no text over a button circle
    root = ET.parse(out / "cut_patterns.svg").getroot()
    for c in root.iterfind(".//s:circle", NS):
        x, y, r = (float(c.get(k)) for k in ("cx", "cy", "r"))
        hit = (boxes[:, 0] < x + r) & (x - r < boxes[:, 2]) & (boxes[:, 1] < y + r) & (y - r < boxes[:, 3])
        assert not hit.any(), [texts[i] for i in np.flatnonzero(hit)]
    joined = "\n".join(texts)
    for c in fab.strips:
        assert c.name in joined
    # both ends of the elbow clutch lie on the band: each labelled beside its buttons
    ends = [t for t in texts if t.startswith("C1 ") and t.split()[2] in ("start", "end")]
    assert sorted(t.split()[2] for t in ends) == ["end", "start"]
    assert "load not evaluated" in joined  # no evaluation given


def test_unloaded_clutch_is_flagged(fab_out, tmp_path):
    from kgarment.evaluate.loads import ClutchLoad, LoadReport, MotionEnergy

    fab, _ = fab_out
    name = fab.strips[0].name
    idle = LoadReport((ClutchLoad("arm_flexion.right", name, 0.02, 0.4, False),),
                      (MotionEnergy("arm_flexion.right", 2.0, 1.0),))
    flagged = with_loads(fab, idle)
    assert flagged.sheet.clutches[0].loaded is False
    assert any(lab.kind == "clutch" and "(no load)" in lab.text for lab in flagged.sheet.labels)
    write_fabrication(flagged, tmp_path)
    assert "NO LOAD" in (tmp_path / "bom.csv").read_text() and "NO LOAD" in (tmp_path / "cut_patterns.svg").read_text()
    busy = LoadReport((ClutchLoad("arm_flexion.right", name, 0.9, 12.0, True),), idle.garment)
    loaded = with_loads(fab, busy).sheet
    assert loaded.clutches[0].loaded is True and not any("no load" in lab.text for lab in loaded.labels)


def test_seam_allowance_is_the_requested_distance(fab_out):
    import ezdxf
    from shapely import Polygon

    fab, out = fab_out
    for p in fab.sheet.pieces:
        assert p.allowance and p.cut_lines is p.allowance
        sew, cut = Polygon(p.outlines[0]).buffer(0), Polygon(p.allowance[0])
        assert cut.contains(sew)
        # every point of the cut line lies the allowance from the sew line (one-sided: inside a
        # concave notch the sew line is further from the cut line)
        d = [sew.exterior.distance(cut.exterior.interpolate(t, normalized=True)) for t in np.linspace(0, 1, 200)]
        assert min(d) == pytest.approx(ALLOWANCE, abs=0.05) and max(d) == pytest.approx(ALLOWANCE, abs=0.05)
    svg = (out / "cut_patterns.svg").read_text()
    assert 'class="sew"' in svg and f"{ALLOWANCE:g} mm seam allowance" in svg
    doc = ezdxf.readfile(out / "cut_patterns.dxf")
    assert doc.layers.get("CUT").dxf.lineweight == 0  # hairlines for the cutter
    sew_lines = [e for e in doc.modelspace().query("LWPOLYLINE") if e.dxf.layer == "SEW"]
    assert len(sew_lines) == sum(len(p.outlines) for p in fab.sheet.pieces)


def test_pdf_has_the_whole_grid_with_consecutive_names(fab_out):
    from kgarment.fabricate.tiling import slivers, tile_name, tiling

    fab, out = fab_out
    grid = tiling(fab.sheet, "a4")
    pdf = (out / "cut_patterns.pdf").read_bytes()
    assert len(re.findall(rb"/Type\s*/Page\b(?!s)", pdf)) == 1 + grid.nx * grid.ny  # assembly map + tiles
    names = [t.name for t in grid.tiles]
    assert names == [f"{chr(65 + r)}{c + 1}" for r in range(grid.ny) for c in range(grid.nx)]
    assert tile_name(26, 0) == "AA1"
    marks = grid.registration_marks()
    for t in grid.tiles:  # registration marks on every tile, inside its overlap bands
        inside = (marks[:, 0] > t.x) & (marks[:, 0] < t.x + t.w) & (marks[:, 1] > t.y) & (marks[:, 1] < t.y + t.h)
        assert inside.sum() >= 4
    assert slivers(fab.sheet, grid) == []


def test_grid_is_shifted_rather_than_leave_a_sliver():
    from kgarment.fabricate.tiling import MARGIN_MM, OVERLAP_MM, PAPERS, slivers, tiling

    w = PAPERS["a4"][0] - 2 * MARGIN_MM
    width = w + 30.0  # a grid from x = 0 would hold the last 30 mm of the piece alone
    piece = np.array([[10.0, 10.0], [width - 10, 10.0], [width - 10, 200.0], [10.0, 200.0]])
    sheet = SimpleNamespace(width=width, height=210.0, square=np.array([[10.0, 10], [20, 10], [20, 20], [10, 20],
                                                                        [10, 10]]),
                            pieces=[SimpleNamespace(cut_lines=(piece,))], labels=())
    grid = tiling(sheet, "a4")
    assert slivers(sheet, grid) == [] and not any(t.empty for t in grid.tiles)
    assert grid.tiles[0].x < -OVERLAP_MM  # the grid moved left


def test_placement_draws_every_piece_and_clutch(fab_out, sleeve, anny_body):
    from kgarment.fabricate.panels import face_regions, garment_panels
    from kgarment.fabricate.placement import placement_sheet

    fab, out = fab_out
    assert (out / "placement.svg").stat().st_size > 0 and (out / "placement_3d.png").stat().st_size > 0
    _, names = face_regions(sleeve, anny_body)
    assert names == ["sleeve.R"]  # an arm sleeve is one sleeve panel
    panels = garment_panels(sleeve, anny_body)
    assert sum(p.patch.flat.area_3d for p in panels) == pytest.approx(sleeve.face_areas().sum(), rel=1e-9)
    ps = placement_sheet(panels, fab.patterns, fab.strips, fab.sheet.clutches)
    texts = [lab.text for lab in ps.labels]
    assert {p.label for p in fab.patterns.patches} <= set(texts) and "C1" in texts
    # without a rig, front and back halves
    _, halves = face_regions(sleeve)
    assert halves == ["front", "back"]


def test_negative_allowance_is_refused(capsys):
    from kgarment.cli.fabricate import add_parsers

    ap = argparse.ArgumentParser(prog="kgarment")
    add_parsers(ap.add_subparsers(dest="command"))
    with pytest.raises(SystemExit) as e:
        ap.parse_args(["fabricate", "run", "--allowance", "-2"])
    assert e.value.code == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert "--allowance" in err[-1] and "outside [0" in err[-1]
