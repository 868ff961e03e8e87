"""Headless pictures of bodies, garments and clutches."""

from kgarment.render.raster import STANDARD_VIEWS, VIEWS, Layer, render_png
from kgarment.render.scene import face_colors, faces_near, render_design, render_poses, render_scene

__all__ = ["STANDARD_VIEWS", "VIEWS", "Layer", "face_colors", "faces_near", "render_design", "render_png", "render_poses", "render_scene"]
