"""The fabrication pipeline: clean-up, patches and flattening, layout, and every output file."""

from __future__ import annotations

import dataclasses
import logging
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from kgarment.case.values import design_values
from kgarment.clutch import ClutchStrip
from kgarment.errors import KgarmentError
from kgarment.fabricate.bom import write_bom, write_report
from kgarment.fabricate.cleanup import CleanupOptions, CleanupResult, clean_design
from kgarment.fabricate.cutfiles import write_dxf, write_svg
from kgarment.fabricate.export3d import face_patch_index, write_3d
from kgarment.fabricate.layout import Sheet, layout_sheet
from kgarment.fabricate.panels import garment_panels
from kgarment.fabricate.patterns import PatternOptions, PatternSet, make_patterns
from kgarment.fabricate.placement import placement_sheet, render_placement_3d, write_placement
from kgarment.fabricate.preview import PAPERS, write_pdf, write_png
from kgarment.garment import Garment
from kgarment.io import atomic_save_npz

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class FabricationOptions:
    """cleanup, patterns : the two stages' options; smooth_iterations : Taubin iterations on
    the outlines (0: raw triangle edges); sheet_width : mm; paper : "a4" or "letter";
    allowance : seam allowance around every piece and panel, mm (0: none, as for heat-pressed
    film; sewn fabric wants about 10)."""

    cleanup: CleanupOptions = field(default_factory=CleanupOptions)
    patterns: PatternOptions = field(default_factory=PatternOptions)
    smooth_iterations: int = 10
    sheet_width: float = 600.0
    paper: str = "a4"
    allowance: float = 0.0

    def __post_init__(self):
        if not 0 <= self.allowance <= 100:
            raise KgarmentError(f"seam allowance {self.allowance!r} mm must be in [0, 100]")
        if self.paper not in PAPERS:
            raise KgarmentError(f"paper {self.paper!r}; allowed: {', '.join(PAPERS)}")
        if not self.sheet_width > 0:
            raise KgarmentError(f"sheet width {self.sheet_width!r} mm must be > 0")


@dataclass(frozen=True)
class Fabrication:
    """Everything the fabrication step made.

    garment : the Garment; strips : its clutches; design : (m,) float, the design as given
    (1 reinforced, 1e-3 soft); cleanup : what the clean-up did; patterns : the flat patches
    and seams; sheet : the cutting layout (mm); options : the options used; panels : the
    base garment's flat panels; loads : the cleaned design's per-clutch LoadReport (None: not
    evaluated); body : the body the garment was cut from (for the 3D picture), or None.
    """

    garment: Garment
    strips: tuple[ClutchStrip, ...]
    design: np.ndarray
    cleanup: CleanupResult
    patterns: PatternSet
    sheet: Sheet
    options: FabricationOptions
    panels: tuple = ()
    loads: object = None
    body: object = None

    @property
    def clean_design(self) -> np.ndarray:
        """(m,) float: the cleaned design in the design loop's values (1 or 1e-3)."""
        return design_values(self.cleanup.after)


def check_design_mesh(path, garment) -> None:
    """A design ``.npz`` that stores its mesh (``faces``, ``rest_vertices``) must have been
    made for this garment (other files carry no mesh and pass)."""
    path = Path(path)
    if path.suffix != ".npz" or not path.is_file():
        return
    with np.load(path) as z:
        faces = z["faces"] if "faces" in z.files else None
        rest = z["rest_vertices"] if "rest_vertices" in z.files else None
    if faces is not None and (faces.shape != garment.faces.shape or not np.array_equal(faces, garment.faces)):
        raise KgarmentError(f"{path} was made for another garment mesh ({len(faces)} faces) than the "
                            f"problem's {garment.name} ({garment.n_faces} faces)")
    if rest is not None and rest.shape == garment.rest_vertices.shape \
            and np.abs(rest - garment.rest_vertices).max() > 1e-6:
        raise KgarmentError(f"{path} was made on another body (its garment's rest shape differs)")


def fabricate(garment, strips, design: np.ndarray, options: FabricationOptions = FabricationOptions(),
              title: str = "", body=None, loads=None) -> Fabrication:
    """Clean ``design`` (m,) (> 0.5 = reinforced) on ``garment`` (a Garment, with its clutch
    strips), cut the reinforcement into flat patches and lay them out at 1:1; flatten the
    base garment's panels (split by the bones of ``body`` when given). loads : the cleaned
    design's LoadReport, or None (see :func:`with_loads`)."""
    design = np.asarray(design, dtype=np.float64).reshape(-1)
    if design.shape != (garment.n_faces,):
        raise KgarmentError(f"the design has {design.size} faces, the garment {garment.name!r} {garment.n_faces}")
    strips = tuple(strips)
    c = clean_design(garment.faces, garment.rest_vertices, design, strips, garment.attached, options.cleanup)
    if not c.after.any():
        raise KgarmentError("the design has no reinforced face left to cut (after the clean-up)")
    pats = make_patterns(garment.rest_vertices, garment.faces, c.after, options.patterns)
    log.debug("%d patches, %d seams", len(pats.patches), len(pats.seams))
    sheet = layout_sheet(pats, garment, strips, options.sheet_width, smooth_iterations=options.smooth_iterations,
                         title=title or f"kgarment {garment.name}", allowance=options.allowance, loads=loads)
    return Fabrication(garment, strips, design, c, pats, sheet, options, garment_panels(garment, body), loads, body)


def with_loads(fab: Fabrication, loads) -> Fabrication:
    """The fabrication with the cleaned design's per-clutch loads (a LoadReport from
    ``Evaluator.evaluate(design, loads=True)``): the sheet is labelled again, clutches that
    carry no load flagged."""
    o = fab.options
    sheet = layout_sheet(fab.patterns, fab.garment, fab.strips, o.sheet_width, smooth_iterations=o.smooth_iterations,
                         title=fab.sheet.title, allowance=o.allowance, loads=loads)
    return dataclasses.replace(fab, sheet=sheet, loads=loads)


def write_fabrication(fab: Fabrication, out, evaluation=None) -> list[Path]:
    """Write every file into the folder ``out`` (created; existing files are replaced):
    cut_patterns.svg/.dxf/.pdf/.png (a preview), placement.svg/.png, placement_3d.png,
    design_clean.glb/.obj/.ply/.npz, bom.md/.csv, report.md/.json.
    evaluation : (rows before, rows after), each ``StateEvaluation.row()`` dicts of the one
    design evaluator (``kgarment.design.Evaluator``), or None."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    g = fab.garment
    files = [write_svg(fab.sheet, out / "cut_patterns.svg"), write_dxf(fab.sheet, out / "cut_patterns.dxf"),
             write_pdf(fab.sheet, out / "cut_patterns.pdf", fab.options.paper),
             write_png(fab.sheet, out / "cut_patterns.png")]
    if fab.panels:
        files += write_placement(placement_sheet(fab.panels, fab.patterns, fab.strips, fab.sheet.clutches,
                                                 fab.options.allowance), out, fab.sheet.title)
        files.append(render_placement_3d(out / "placement_3d.png", g, fab.patterns, fab.strips, fab.sheet.clutches,
                                         fab.body))
    files += write_3d(g.rest_vertices, g.faces, fab.patterns, fab.strips, out / "design_clean")
    atomic_save_npz(out / "design_clean.npz", design=fab.clean_design, original=fab.design, faces=g.faces,
                    rest_vertices=g.rest_vertices, patch=face_patch_index(g.n_faces, fab.patterns))
    files.append(out / "design_clean.npz")
    files += write_bom(fab, out)
    files += write_report(fab, out, evaluation, files + [out / "report.md", out / "report.json"])
    return files
