"""Linear zero-rest-length springs between affine combinations of vertices.

Every spring j has a residual ``r_j = sum_t c_jt x[i_jt] - b_j`` (3-vector) with at most
four terms and energy ``k_j / 2 |r_j|^2``.  Stacked, ``E = 1/2 sum_j k_j |A_j x - b_j|^2``
with a constant sparse operator A (S, N) acting on x (N, 3), so the gradient is
``A^T K (A x - b)`` and the Hessian ``kron(A^T K A, I3)`` is constant.

Groups:

* ``attach``: centroid of an attached garment face -> target centroid (1/3, 1/3, 1/3);
* ``anchor``: each of a clutch's 6 anchor vertices -> its barycentric point on the garment
  (``x_c - sum_a b_a x_garment[a]``, b = 0);
* ``tie``: the clutch's other centre-line vertices -> their garment points (weak).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch

GROUPS = ("attach", "anchor", "tie")


@dataclass(frozen=True)
class SpringSet:
    """index : (S, 4) int64 vertex ids; coef : (S, 4) float64 (0 for padding);
    group : (S,) int64 into :data:`GROUPS`; target : (S, 3) b_j in m."""

    index: np.ndarray
    coef: np.ndarray
    group: np.ndarray
    target: np.ndarray

    @property
    def size(self) -> int:
        return len(self.group)

    @staticmethod
    def empty() -> SpringSet:
        return SpringSet(np.zeros((0, 4), np.int64), np.zeros((0, 4)), np.zeros(0, np.int64), np.zeros((0, 3)))

    @staticmethod
    def concat(parts: list[SpringSet]) -> SpringSet:
        parts = [p for p in parts if p.size] or [SpringSet.empty()]
        return SpringSet(
            index=np.concatenate([p.index for p in parts]),
            coef=np.concatenate([p.coef for p in parts]),
            group=np.concatenate([p.group for p in parts]),
            target=np.concatenate([p.target for p in parts]),
        )

    def operator(self, n_vertices: int):
        """The sparse operator A, (S, N) scipy CSR."""
        import scipy.sparse as sp

        rows = np.repeat(np.arange(self.size), 4)
        return sp.csr_matrix((self.coef.ravel(), (rows, self.index.ravel())), shape=(self.size, n_vertices))


def attachment_springs(faces: np.ndarray, attach_faces: np.ndarray, targets: np.ndarray) -> SpringSet:
    """Garment face centroids -> targets.  faces : (m, 3); attach_faces : (a,); targets : (a, 3)."""
    af = np.asarray(attach_faces, dtype=np.int64).reshape(-1)
    tg = np.asarray(targets, dtype=np.float64).reshape(-1, 3)
    if len(af) != len(tg):
        raise ValueError(f"{len(af)} attached faces but {len(tg)} targets")
    idx = np.zeros((len(af), 4), np.int64)
    idx[:, :3] = np.asarray(faces, dtype=np.int64)[af]
    idx[:, 3] = idx[:, 0]
    coef = np.zeros((len(af), 4))
    coef[:, :3] = 1.0 / 3.0
    return SpringSet(idx, coef, np.zeros(len(af), np.int64), tg)


def binding_springs(vertex_ids: np.ndarray, garment_faces: np.ndarray, bind_face: np.ndarray,
                    bind_bary: np.ndarray, group: str) -> SpringSet:
    """Clutch vertices (global ids (s,)) -> barycentric points on garment faces.

    garment_faces : (m, 3); bind_face : (s,); bind_bary : (s, 3).
    """
    vid = np.asarray(vertex_ids, dtype=np.int64)
    s = len(vid)
    idx = np.empty((s, 4), np.int64)
    idx[:, 0] = vid
    idx[:, 1:] = np.asarray(garment_faces, dtype=np.int64)[np.asarray(bind_face, dtype=np.int64)]
    coef = np.empty((s, 4))
    coef[:, 0] = 1.0
    coef[:, 1:] = -np.asarray(bind_bary, dtype=np.float64)
    return SpringSet(idx, coef, np.full(s, GROUPS.index(group), np.int64), np.zeros((s, 3)))


def springs(x: torch.Tensor, index: torch.Tensor, coef: torch.Tensor, target: torch.Tensor,
            k: torch.Tensor, order: int = 0):
    """Energy per spring (S,) J and, for order >= 1, the gradient on x (N, 3) N.

    x : (N, 3); index : (S, 4) long; coef : (S, 4); target : (S, 3); k : (S,) N/m.
    The (constant) Hessian is assembled separately from ``coef`` and ``k``.
    """
    r = (coef[:, :, None] * x[index]).sum(1) - target  # (S, 3)
    e = 0.5 * k * (r * r).sum(1)
    if order == 0:
        return e, None
    fr = k[:, None] * r
    grad = torch.zeros_like(x)
    grad.index_add_(0, index.reshape(-1), (coef[:, :, None] * fr[:, None, :]).reshape(-1, 3))
    return e, grad
