"""Headless pictures of bodies, garments and clutches."""

from kgarment.render.raster import STANDARD_VIEWS, VIEWS, Layer, render_png
from kgarment.render.scene import DESIGN_LEGEND, face_colors, render_scene

__all__ = ["DESIGN_LEGEND", "Layer", "STANDARD_VIEWS", "VIEWS", "face_colors", "render_png", "render_scene"]
