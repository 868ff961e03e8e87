"""The clutch strip mesh as the simulator consumes it."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class ClutchStrip:
    """One electrostatic clutch as a thin triangle strip bound to the garment.

    Attributes
    ----------
    name : str
        The clutch's name (from the problem file).
    vertices : (nc, 3) float64 array
        Positions on the garment's *rest* surface, metres.
    faces : (mc, 3) int64 array
        Triangles of the strip, indices into ``vertices``; 4 per segment.
    bind_face : (nc,) int64 array
        Garment face that each clutch vertex lies on.
    bind_bary : (nc, 3) float64 array
        Barycentric coordinates of each clutch vertex in ``bind_face``
        (rows sum to 1); ``garment_x[garment_faces[bind_face]]`` weighted by these
        gives the clutch vertex's place on any deformed garment.
    anchors : (6,) int64 array
        The 6 anchor vertices, 3 at each end (indices into ``vertices``).
    centerline : (r,) int64 array
        Vertices of the centre row, start to end.
    length, width : float
        Requested length and width, metres.
    prestrain : float
        Rest-shape scale factor in (0, 1]; < 1 makes the strip start taut.
    """

    name: str
    vertices: np.ndarray
    faces: np.ndarray
    bind_face: np.ndarray
    bind_bary: np.ndarray
    anchors: np.ndarray
    centerline: np.ndarray
    length: float
    width: float
    prestrain: float = 1.0

    def rest_vertices(self) -> np.ndarray:
        """(nc, 3) rest shape for the strip's energy: ``vertices`` scaled by ``prestrain``
        about the centroid of the centre line."""
        c = self.vertices[self.centerline].mean(axis=0)
        return c + self.prestrain * (self.vertices - c)

    def bound_positions(self, garment_x: np.ndarray, garment_faces: np.ndarray) -> np.ndarray:
        """(nc, 3) clutch vertex positions carried by a garment configuration.

        garment_x : (n, 3) garment vertex positions; garment_faces : (m, 3).
        """
        tri = garment_x[garment_faces[self.bind_face]]  # (nc, 3, 3)
        return np.einsum("ij,ijk->ik", self.bind_bary, tri)
