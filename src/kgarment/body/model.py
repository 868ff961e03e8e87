"""The :class:`Body`: a rest mesh, its rig and its posed versions, in metres, Z up."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from kgarment.errors import KgarmentError, unknown


def vertex_normals(vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Area-weighted unit vertex normals.

    vertices : (n, 3) float array, metres; faces : (m, 3) int array.
    Returns (n, 3) unit normals (outward for a consistently wound closed mesh).
    """
    tri = vertices[faces]
    fn = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])  # (m, 3), |fn| = 2 area
    vn = np.zeros_like(vertices)
    for k in range(3):
        np.add.at(vn, faces[:, k], fn)
    norm = np.linalg.norm(vn, axis=1, keepdims=True)
    return vn / np.maximum(norm, 1e-300)


@dataclass(frozen=True)
class Body:
    """A body mesh with skinning weights and one posed copy per motion.

    Attributes
    ----------
    rest_vertices : (n, 3) float64, metres, Z up, facing -Y.
    faces : (m, 3) int64, outward winding.
    bone_names : tuple of B str (empty for an unrigged mesh sequence).
    bone_parents : (B,) int64, -1 for the root.
    skin_indices, skin_weights : (n, k) int64 / float64, the k most influential bones of
        each vertex and their weights (rows sum to 1); (n, 0) when unrigged.
    rest_joints : (B, 3) float64, bone head positions in the rest pose.
    motion_names : tuple of K str.
    posed_vertices : (K, n, 3) float64, the body in each motion's target pose.
    posed_joints : (K, B, 3) float64, bone heads in each target pose.
    source : str, a short description of where the body came from.
    """

    rest_vertices: np.ndarray
    faces: np.ndarray
    bone_names: tuple[str, ...]
    bone_parents: np.ndarray
    skin_indices: np.ndarray
    skin_weights: np.ndarray
    rest_joints: np.ndarray
    motion_names: tuple[str, ...]
    posed_vertices: np.ndarray
    posed_joints: np.ndarray
    source: str = ""

    @property
    def n_vertices(self) -> int:
        return int(self.rest_vertices.shape[0])

    @property
    def rigged(self) -> bool:
        return len(self.bone_names) > 0

    def motion_index(self, motion: str) -> int:
        if motion == "rest":
            return -1
        if motion not in self.motion_names:
            raise unknown("motion", motion, ("rest",) + self.motion_names)
        return self.motion_names.index(motion)

    def vertices(self, motion: str = "rest") -> np.ndarray:
        """(n, 3) vertices in the target pose of ``motion`` ("rest" for the rest pose)."""
        i = self.motion_index(motion)
        return self.rest_vertices if i < 0 else self.posed_vertices[i]

    def joints(self, motion: str = "rest") -> np.ndarray:
        """(B, 3) bone head positions in the target pose of ``motion``."""
        i = self.motion_index(motion)
        return self.rest_joints if i < 0 else self.posed_joints[i]

    def normals(self, motion: str = "rest") -> np.ndarray:
        """(n, 3) unit outward vertex normals in the given pose."""
        return vertex_normals(self.vertices(motion), self.faces)

    def bone_index(self, bone: str) -> int:
        if bone not in self.bone_names:
            raise unknown("bone", bone, self.bone_names)
        return self.bone_names.index(bone)

    def dominant_bone(self) -> np.ndarray:
        """(n,) int64: index of each vertex's most influential bone."""
        if not self.rigged:
            raise KgarmentError("this body has no rig (skinning weights); give the garment as a face mask")
        k = np.argmax(self.skin_weights, axis=1)
        return self.skin_indices[np.arange(self.n_vertices), k]

    def face_bone(self) -> np.ndarray:
        """(m,) int64: the dominant bone of each face (majority of its vertices, else vertex 0's)."""
        vb = self.dominant_bone()[self.faces]  # (m, 3)
        out = vb[:, 0].copy()
        agree12 = vb[:, 1] == vb[:, 2]
        out[agree12] = vb[agree12, 1]
        return out
