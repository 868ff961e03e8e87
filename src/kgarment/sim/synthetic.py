"""Synthetic scenes for tests and benchmarks (no body model needed).

* a cylinder "limb" body with analytic normals and a skin-tight tube garment on it
  (a periodic (theta, z) grid, 2 triangles per cell), clutch strips laid along the tube in
  parameter space (so their barycentric binding is exact), and a stretch + twist motion;
* a sphere body (``trimesh.creation.icosphere``) with a flat square sheet.
"""

from __future__ import annotations

import numpy as np

from kgarment.clutch.strip import ClutchStrip
from kgarment.sim.model import Motion


def cylinder_body(radius: float, z0: float, z1: float, n_theta: int, n_z: int):
    """Open cylinder surface about the z axis: vertices (nb, 3), normals (nb, 3), faces."""
    th = np.linspace(0.0, 2 * np.pi, n_theta, endpoint=False)
    z = np.linspace(z0, z1, n_z)
    T, Z = np.meshgrid(th, z, indexing="ij")
    v = np.stack([radius * np.cos(T), radius * np.sin(T), Z], -1).reshape(-1, 3)
    n = np.stack([np.cos(T), np.sin(T), np.zeros_like(T)], -1).reshape(-1, 3)
    return v, n, _grid_faces(n_theta, n_z)


def _grid_faces(n_theta: int, n_z: int) -> np.ndarray:
    i, j = np.meshgrid(np.arange(n_theta), np.arange(n_z - 1), indexing="ij")
    i, j = i.ravel(), j.ravel()
    ip = (i + 1) % n_theta
    a, b, c, d = i * n_z + j, ip * n_z + j, ip * n_z + j + 1, i * n_z + j + 1
    return np.concatenate([np.stack([a, b, c], 1), np.stack([a, c, d], 1)])


class Tube:
    """A tube garment of radius R over z in [z0, z1] on an (n_theta x n_z) vertex grid."""

    def __init__(self, radius: float, z0: float, z1: float, n_theta: int, n_z: int):
        self.radius, self.z0, self.z1, self.n_theta, self.n_z = radius, z0, z1, n_theta, n_z
        self.vertices, _, self.faces = cylinder_body(radius, z0, z1, n_theta, n_z)
        self.n_cells = n_theta * (n_z - 1)

    def locate(self, theta: np.ndarray, z: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Face ids (p,) and barycentric coordinates (p, 3) of parameter points."""
        u = np.mod(theta, 2 * np.pi) / (2 * np.pi) * self.n_theta
        v = (np.asarray(z) - self.z0) / (self.z1 - self.z0) * (self.n_z - 1)
        i = np.minimum(np.floor(u).astype(int), self.n_theta - 1)
        j = np.clip(np.floor(v).astype(int), 0, self.n_z - 2)
        s, t = u - i, v - j
        cell = i * (self.n_z - 1) + j
        lower = s >= t  # triangle (a, b, c): a=(0,0) b=(1,0) c=(1,1)
        face = np.where(lower, cell, cell + self.n_cells)
        bary = np.where(lower[:, None], np.stack([1 - s, s - t, t], 1), np.stack([1 - t, s, t - s], 1))
        return face, bary

    def ring_faces(self, j: int) -> np.ndarray:
        """Faces of the j-th row of cells (0 = bottom)."""
        cells = np.arange(self.n_theta) * (self.n_z - 1) + j
        return np.concatenate([cells, cells + self.n_cells])

    def clutch(self, name: str, theta: float, za: float, zb: float, width: float,
               n_seg: int, prestrain: float = 1.0) -> ClutchStrip:
        """A straight strip along z at angle ``theta`` from ``za`` to ``zb``."""
        dth = width / 2.0 / self.radius
        zs = np.linspace(za, zb, n_seg + 1)
        th = np.array([theta - dth, theta, theta + dth])
        T, Z = np.meshgrid(th, zs, indexing="ij")  # rows: left, centre, right
        return self._strip(name, T, Z, zb - za, width, prestrain)

    def hoop(self, name: str, z: float, theta0: float, theta1: float, width: float,
             n_seg: int, prestrain: float = 1.0) -> ClutchStrip:
        """A strip round the tube at height ``z`` from angle ``theta0`` to ``theta1``."""
        th = np.linspace(theta0, theta1, n_seg + 1)
        Z = np.array([z - width / 2.0, z, z + width / 2.0])[:, None] * np.ones_like(th)
        return self._strip(name, np.broadcast_to(th, Z.shape), Z, self.radius * (theta1 - theta0), width, prestrain)

    def _strip(self, name: str, T: np.ndarray, Z: np.ndarray, length: float, width: float,
               prestrain: float) -> ClutchStrip:
        """The strip of three rows (3, r) of parameter points (angle ``T``, height ``Z``):
        side, centre, side; 4 triangles per segment, its ends' rows the anchors."""
        face, bary = self.locate(T.ravel(), Z.ravel())
        verts = np.einsum("ij,ijk->ik", bary, self.vertices[self.faces[face]])
        r = T.shape[1]
        n_seg = r - 1
        L, C, R = 0, r, 2 * r
        f = []
        for s in range(n_seg):
            f += [[L + s, L + s + 1, C + s + 1], [L + s, C + s + 1, C + s],
                  [C + s, C + s + 1, R + s + 1], [C + s, R + s + 1, R + s]]
        anchors = np.array([L, C, R, L + n_seg, C + n_seg, R + n_seg])
        return ClutchStrip(name=name, vertices=verts, faces=np.array(f), bind_face=face,
                           bind_bary=bary, anchors=anchors, centerline=np.arange(C, C + r),
                           length=length, width=width, prestrain=prestrain)

    def motion(self, name: str, stretch: float, twist: float, body_res: tuple[int, int] = (96, 60),
               margin: float = 0.05) -> Motion:
        """Bottom ring held, top ring moved by ``stretch`` (fraction of the length) along z
        and rotated by ``twist`` radians; skin-tight initial guess interpolating both, kept
        where it is (not moved onto the cylinder's contact surface: tests compare this
        analytic start with hand calculations)."""
        bv, bn, bf = cylinder_body(self.radius, self.z0 - margin, self.z1 + margin, *body_res)
        X = self.vertices
        s = (X[:, 2] - self.z0) / (self.z1 - self.z0)
        x0 = _twist_stretch(X, s, stretch * (self.z1 - self.z0), twist, self.radius)
        bottom, top = self.ring_faces(0), self.ring_faces(self.n_z - 2)
        faces = np.concatenate([bottom, top])
        targets = x0[self.faces[faces]].mean(1)
        return Motion.create(name, x0, bv, bn, faces, targets, bf, on_surface=False)


def _twist_stretch(X, s, dz, twist, radius):
    ang = np.arctan2(X[:, 1], X[:, 0]) + twist * s
    r = np.hypot(X[:, 0], X[:, 1])
    return np.stack([r * np.cos(ang), r * np.sin(ang), X[:, 2] + dz * s], 1)


def sphere_body(radius: float = 0.1, subdivisions: int = 4):
    """Icosphere about the origin: vertices, outward normals, faces."""
    import trimesh

    s = trimesh.creation.icosphere(subdivisions=subdivisions, radius=radius)
    v = np.asarray(s.vertices, dtype=np.float64)
    return v, v / np.linalg.norm(v, axis=1, keepdims=True), np.asarray(s.faces, dtype=np.int64)


def square_sheet(size: float, n: int, z: float = 0.0):
    """Flat n x n vertex grid in the plane z, centred on the z axis: vertices, faces."""
    t = np.linspace(-size / 2, size / 2, n)
    X, Y = np.meshgrid(t, t, indexing="ij")
    v = np.stack([X.ravel(), Y.ravel(), np.full(X.size, z)], 1)
    i, j = np.meshgrid(np.arange(n - 1), np.arange(n - 1), indexing="ij")
    a = (i * n + j).ravel()
    f = np.concatenate([np.stack([a, a + n, a + n + 1], 1), np.stack([a, a + n + 1, a + 1], 1)])
    return v, f
