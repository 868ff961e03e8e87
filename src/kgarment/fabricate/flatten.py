"""Flattening a patch to the plane: LSCM, then ARAP (libigl), scaled to keep lengths.

LSCM (least-squares conformal maps) gives a fold-free start whose scale is arbitrary; ARAP
(as-rigid-as-possible, local/global iterations) then pulls every triangle towards its 3D
shape, so lengths are kept where the patch is developable. Either result is scaled by the
least-squares factor that best keeps the 3D edge lengths, and mirrored if needed so the 2D
pattern shows the garment's outside (faces counter-clockwise).
"""

from __future__ import annotations

import logging
from dataclasses import dataclass

import numpy as np

from kgarment.errors import KgarmentError
from kgarment.garment.topology import boundary_loops, triangle_areas

log = logging.getLogger(__name__)
METHODS = ("arap", "lscm")


@dataclass(frozen=True)
class Flattening:
    """A patch in the plane and how much it is distorted.

    uv : (n, 2) float64, metres, one point per patch vertex.
    method : "arap" or "lscm".
    scale : the factor applied to the raw parametrisation.
    area_3d, area_2d : m^2 (sum of triangle areas).
    edge_ratio : (e,) 2D length / 3D length of every patch edge (``PatchMesh.edges()``).
    face_strain : (f,) max(sigma_max - 1, 1 - sigma_min) of each triangle's 3D->2D map.
    flipped : number of triangles turned over in the plane (should be 0).
    """

    uv: np.ndarray
    method: str
    scale: float
    area_3d: float
    area_2d: float
    edge_ratio: np.ndarray
    face_strain: np.ndarray
    flipped: int

    @property
    def area_distortion(self) -> float:
        """|A_2D / A_3D - 1| for the whole patch."""
        return abs(self.area_2d / self.area_3d - 1.0)

    @property
    def max_length_distortion(self) -> float:
        """max over edges of |l_2D / l_3D - 1| (inf when a triangle flipped)."""
        if self.flipped:
            return float("inf")
        return float(np.abs(self.edge_ratio - 1.0).max()) if len(self.edge_ratio) else 0.0


def _igl():
    try:
        import igl
    except ImportError:  # pragma: no cover - the fabrication extra installs it
        raise KgarmentError("flattening needs libigl: pip install 'kgarment[fabrication]'") from None
    return igl


def signed_areas(uv: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """(f,) signed areas of 2D triangles uv (n, 2) / faces (f, 3), positive = counter-clockwise."""
    a, b, c = uv[faces[:, 0]], uv[faces[:, 1]], uv[faces[:, 2]]
    return 0.5 * ((b[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1]) - (b[:, 1] - a[:, 1]) * (c[:, 0] - a[:, 0]))


def face_jacobians(V: np.ndarray, F: np.ndarray, uv: np.ndarray) -> np.ndarray:
    """(f, 2, 2) Jacobians of the affine map from each 3D triangle (in its own orthonormal
    frame) to its 2D image. V (n, 3), F (f, 3), uv (n, 2)."""
    e1 = V[F[:, 1]] - V[F[:, 0]]
    e2 = V[F[:, 2]] - V[F[:, 0]]
    x, y = triangle_frames(V, F)
    P = np.stack([np.stack([(e1 * x).sum(1), (e1 * y).sum(1)], 1),
                  np.stack([(e2 * x).sum(1), (e2 * y).sum(1)], 1)], axis=2)  # columns: e1, e2 in 2D frame
    Q = np.stack([uv[F[:, 1]] - uv[F[:, 0]], uv[F[:, 2]] - uv[F[:, 0]]], axis=2)
    return Q @ np.linalg.inv(P)


def triangle_frames(V: np.ndarray, F: np.ndarray):
    """Per-face orthonormal tangent frames: (x (f, 3), y (f, 3)), x along the first edge."""
    e1 = V[F[:, 1]] - V[F[:, 0]]
    e2 = V[F[:, 2]] - V[F[:, 0]]
    x = e1 / np.linalg.norm(e1, axis=1, keepdims=True).clip(1e-300)
    nrm = np.cross(e1, e2)
    y = np.cross(nrm / np.linalg.norm(nrm, axis=1, keepdims=True).clip(1e-300), x)
    return x, y


def _lscm(igl, V, F):
    loops = boundary_loops(F)
    bnd = np.concatenate(loops) if loops else np.arange(len(V))
    d = np.linalg.norm(V[bnd][:, None] - V[bnd][None], axis=-1) if len(bnd) <= 2000 else None
    if d is not None:
        i, j = np.unravel_index(np.argmax(d), d.shape)
    else:  # far apart enough: the extreme points along the longest bounding-box axis
        ax = np.argmax(np.ptp(V[bnd], axis=0))
        i, j = np.argmin(V[bnd, ax]), np.argmax(V[bnd, ax])
    b = np.array([bnd[i], bnd[j]], dtype=np.int64)
    bc = np.array([[0.0, 0.0], [float(np.linalg.norm(V[b[1]] - V[b[0]])), 0.0]])
    out = igl.lscm(V, F, b, bc)  # libigl >= 2.6: (uv, Q)
    uv = next(a for a in (out if isinstance(out, tuple) else (out,)) if isinstance(a, np.ndarray))
    return np.asarray(uv, dtype=np.float64)[:, :2]


def _arap(igl, V, F, uv0, iterations):
    data = igl.ARAPData()
    data.max_iter = int(iterations)
    b = np.array([int(F[0, 0])], dtype=np.int32)
    igl.arap_precomputation(V, F, 2, b, data)
    return np.asarray(igl.arap_solve(uv0[b], data, uv0.copy()), dtype=np.float64)


def flatten(V: np.ndarray, F: np.ndarray, method: str = "arap", iterations: int = 50) -> Flattening:
    """Flatten a disk-like triangle mesh.

    V : (n, 3) rest vertices, metres; F : (f, 3) int64, one connected manifold piece
    (holes allowed). method : "arap" (LSCM start, then ARAP) or "lscm".
    iterations : ARAP local/global iterations.
    """
    if method not in METHODS:
        raise KgarmentError(f"flattening method {method!r}; allowed: {', '.join(METHODS)}")
    igl = _igl()
    V = np.ascontiguousarray(V, dtype=np.float64)
    F = np.ascontiguousarray(F, dtype=np.int64)
    uv = _lscm(igl, V, F)
    if signed_areas(uv, F).sum() < 0:
        uv[:, 0] *= -1
    if method == "arap" and len(F) > 1:
        uv = _arap(igl, V, F, uv, iterations)
    if not np.isfinite(uv).all():
        raise KgarmentError("flattening failed (non-finite coordinates); the patch may be degenerate")
    e = np.unique(np.sort(np.stack([F, np.roll(F, -1, axis=1)], -1).reshape(-1, 2), axis=1), axis=0)
    l3 = np.linalg.norm(V[e[:, 0]] - V[e[:, 1]], axis=1)
    l2 = np.linalg.norm(uv[e[:, 0]] - uv[e[:, 1]], axis=1)
    scale = float((l3 * l2).sum() / max((l2 * l2).sum(), 1e-300))
    uv = (uv - uv.mean(axis=0)) * scale
    sa = signed_areas(uv, F)
    if sa.sum() < 0:  # show the outside of the garment
        uv[:, 0] *= -1
        sa = -sa
    s = np.linalg.svd(face_jacobians(V, F, uv), compute_uv=False)
    strain = np.maximum(s[:, 0] - 1.0, 1.0 - s[:, 1])
    a3 = float(triangle_areas(V, F).sum())
    return Flattening(uv, method, scale, a3, float(np.abs(sa).sum()), l2 * scale / l3.clip(1e-300), strain,
                      int((sa <= 0).sum()))
