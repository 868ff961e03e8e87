"""Fabrication: from a design to cut files, as the paper's authors did by hand in Blender.

Stages (each a module, arrays in and frozen dataclasses out):

``cleanup``    islands, holes and thin features removed on the face graph (clutch ends
               and attachment rings protected)
``patches``    the reinforcement as edge-connected manifold pieces, and seams cut in them
``flatten``    LSCM then ARAP (libigl), scaled to keep lengths; distortion measures
``patterns``   pieces flattened, and cut along short seams while too distorted
``outline``    the jagged boundary smoothed into curves
``layout``     the 1:1 cutting sheet in millimetres with buttons, arrows, notches and a
               seam allowance; ``annotate`` its legend, clutch notes and labels (placed
               by ``labels`` so that none overlap)
``panels``     the base garment's panels (front, back, sleeves), flattened;
``placement``  where every piece and clutch goes on them, flat (1:1) and in 3D
``cutfiles``   SVG and DXF; ``tiling`` and ``preview`` the tiled PDF; ``export3d`` GLB/OBJ/PLY;
``bom``        bill of materials and report; ``pipeline`` all of it

Typical use::

    fab = fabricate(garment, strips, design, body=body)  # design (m,): 1 reinforced, 1e-3 soft
    fab = with_loads(fab, evaluator.evaluate(fab.clean_design, loads=True).loads)  # optional
    write_fabrication(fab, "runs/fab")
"""

from kgarment.fabricate.cleanup import CleanupOptions, CleanupResult, clean_design
from kgarment.fabricate.flatten import Flattening, flatten
from kgarment.fabricate.layout import Piece, Sheet, layout_sheet
from kgarment.fabricate.patches import PatchMesh, patch_mesh, split_patches
from kgarment.fabricate.patterns import Patch, PatternOptions, PatternSet, Seam, make_patterns
from kgarment.fabricate.pipeline import (
    Fabrication,
    FabricationOptions,
    check_design_mesh,
    fabricate,
    with_loads,
    write_fabrication,
)

__all__ = [
    "CleanupOptions",
    "CleanupResult",
    "Fabrication",
    "FabricationOptions",
    "Flattening",
    "Patch",
    "PatchMesh",
    "PatternOptions",
    "PatternSet",
    "Piece",
    "Seam",
    "Sheet",
    "check_design_mesh",
    "clean_design",
    "fabricate",
    "flatten",
    "layout_sheet",
    "make_patterns",
    "patch_mesh",
    "split_patches",
    "with_loads",
    "write_fabrication",
]
