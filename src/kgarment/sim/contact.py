"""Body contact through an IMLS implicit surface of the posed body (Oztireli et al. 2009).

For a point p and body vertices v_i with unit normals n_i::

    w_i(p) = (1 - |p - v_i|^2 / h_i)^4   (0 outside the support |p - v_i|^2 >= h_i)
    f(p)   = sum_i w_i n_i . (p - v_i) / sum_i w_i

over the 60 nearest body vertices, with a per-vertex support ``h_i`` (a *squared* length)
equal to twice the mean squared distance from v_i to its 6 nearest neighbours.  f > 0
outside the body.  The penalty on every garment and clutch vertex is
``k_c * min(f, 0)^2`` (inside only: the cloth slides along and lifts off freely).
A point that no support covers (sum w = 0) falls back to the tangent plane of its nearest
body vertex, ``n_0 . (p - v_0)``; outside the body both are positive (no energy), inside
this only happens deeper than about one vertex spacing, where it keeps pushing outward.

Neighbour lists (:class:`NeighborCache`) come from ``scipy.spatial.cKDTree`` and are
refreshed only for points that moved farther than their threshold delta since their
last refresh.  A list keeps only the candidates that can cover the point within that
threshold (``|p - v_i| < sqrt(h_i) + delta``, typically 15-20 of the 60), so f is *exact*
(identical to a fresh 60-neighbour query) as long as ``sqrt(max h) + delta <= r_60``
(distance to the 60th neighbour); we use ``delta = min(r_60 - sqrt(max h),
sqrt(median h) / 2)`` (about 0.8 vertex spacings; ``r_60 / 4`` if the first is negative).

Hessian: the exact one is ``2 k_c (grad f grad f^T + f hess f)``; the Newton solver
uses the Gauss-Newton part ``2 k_c grad f grad f^T`` (PSD; the dropped term is
proportional to the penetration depth, micrometres at equilibrium).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch
from scipy.spatial import cKDTree

N_NEIGHBORS = 60
N_SUPPORT = 6


@dataclass(frozen=True)
class ImplicitBody:
    """IMLS structure of one posed body.

    vertices : (nb, 3) m; normals : (nb, 3) unit; support : (nb,) h_i in m^2;
    faces : (fb, 3) or None (kept for reference, unused by IMLS); tree : cKDTree.
    """

    vertices: np.ndarray
    normals: np.ndarray
    support: np.ndarray
    tree: cKDTree
    faces: np.ndarray | None = None

    @staticmethod
    def from_mesh(vertices: np.ndarray, normals: np.ndarray, faces: np.ndarray | None = None) -> ImplicitBody:
        """vertices : (nb, 3) m; normals : (nb, 3) outward vertex normals (normalised here)."""
        v = np.ascontiguousarray(vertices, dtype=np.float64)
        n = np.asarray(normals, dtype=np.float64)
        if v.ndim != 2 or v.shape[1] != 3 or n.shape != v.shape:
            raise ValueError("body vertices and normals must both have shape (nb, 3)")
        nn = np.linalg.norm(n, axis=1, keepdims=True)
        if np.any(nn < 1e-12):
            raise ValueError("body normals must be non-zero")
        tree = cKDTree(v)
        k = min(N_SUPPORT + 1, len(v))
        d, _ = tree.query(v, k=k)
        h = 2.0 * np.mean(d[:, 1:] ** 2, axis=1)
        f = None if faces is None else np.asarray(faces, dtype=np.int64)
        return ImplicitBody(vertices=v, normals=n / nn, support=h, tree=tree, faces=f)


@dataclass(frozen=True)
class NeighborCache:
    """Per-point candidate lists.

    index : (P, K) int64 body vertex ids (padded with the nearest one);
    valid : (P, K) bool; nearest : (P,) int64; origin : (P, 3) positions at refresh;
    threshold : (P,) refresh distance (m); full_index, full_dist : (P, 60) raw query.
    """

    index: np.ndarray
    valid: np.ndarray
    nearest: np.ndarray
    origin: np.ndarray
    threshold: np.ndarray
    full_index: np.ndarray
    full_dist: np.ndarray


def _prune(body: ImplicitBody, origin, full_index, full_dist):
    k = full_index.shape[1]
    hmax = float(np.sqrt(body.support.max()))
    r_k = full_dist[:, -1]
    if k >= N_NEIGHBORS:
        thr = np.minimum(r_k - hmax, 0.5 * float(np.sqrt(np.median(body.support))))
        thr = np.where(thr > 0, thr, 0.25 * r_k)
    else:  # the list holds the whole body: always exact
        thr = np.full(len(r_k), np.inf)
    keep = full_dist < np.sqrt(body.support[full_index]) + thr[:, None]
    kmax = max(int(keep.sum(1).max()), 1)
    order = np.argsort(~keep, axis=1, kind="stable")[:, :kmax]
    index = np.take_along_axis(full_index, order, 1)
    valid = np.take_along_axis(keep, order, 1)
    index = np.where(valid, index, full_index[:, :1])
    return NeighborCache(index=index, valid=valid, nearest=full_index[:, 0].copy(), origin=origin,
                         threshold=thr, full_index=full_index, full_dist=full_dist)


def update_neighbors(body: ImplicitBody, points: np.ndarray, cache: NeighborCache | None = None) -> NeighborCache:
    """Return a cache valid at ``points`` (P, 3): ``cache`` itself when no point moved past
    its threshold, else a new one with the moved points re-queried."""
    p = np.asarray(points, dtype=np.float64)
    k = min(N_NEIGHBORS, len(body.vertices))
    if cache is None or cache.origin.shape != p.shape:
        d, i = body.tree.query(p, k=k)
        d, i = d.reshape(len(p), k), i.reshape(len(p), k)
        return _prune(body, p.copy(), i, d)
    moved = np.sum((p - cache.origin) ** 2, axis=1) > cache.threshold**2
    if not moved.any():
        return cache
    d, i = body.tree.query(p[moved], k=k)
    full_index, full_dist = cache.full_index.copy(), cache.full_dist.copy()
    full_index[moved] = i.reshape(-1, k)
    full_dist[moved] = d.reshape(-1, k)
    origin = cache.origin.copy()
    origin[moved] = p[moved]
    return _prune(body, origin, full_index, full_dist)


def imls(p: torch.Tensor, bv: torch.Tensor, bn: torch.Tensor, bh: torch.Tensor,
         index: torch.Tensor, valid: torch.Tensor, nearest: torch.Tensor, order: int = 0):
    """IMLS value and derivatives.

    p : (P, 3); bv, bn : (nb, 3); bh : (nb,); index, valid : (P, K); nearest : (P,).
    Returns ``f`` (P,), ``grad f`` (P, 3) or None, ``hess f`` (P, 3, 3) or None.
    """
    u = p[:, None, :] - bv[index]  # (P, K, 3)
    nrm = bn[index]
    hi = bh[index]
    q = torch.clamp(1.0 - (u * u).sum(-1) / hi, min=0.0) * valid
    w = q**4
    phi = (nrm * u).sum(-1)
    D = w.sum(1)
    covered = D > 0
    Ds = torch.where(covered, D, torch.ones_like(D))
    f_imls = (w * phi).sum(1) / Ds
    un = p - bv[nearest]
    nn = bn[nearest]
    f = torch.where(covered, f_imls, (nn * un).sum(-1))
    if order == 0:
        return f, None, None
    dw = (-8.0 * q**3 / hi)[..., None] * u  # (P, K, 3)
    gD = dw.sum(1)
    gN = (phi[..., None] * dw + w[..., None] * nrm).sum(1)
    gf = torch.where(covered[:, None], (gN - f[:, None] * gD) / Ds[:, None], nn)
    if order == 1:
        return f, gf, None
    eye = torch.eye(3, dtype=p.dtype, device=p.device)
    d2w = (-8.0 * q**3 / hi)[..., None, None] * eye + (48.0 * q**2 / hi**2)[..., None, None] * (
        u[..., :, None] * u[..., None, :])
    hD = d2w.sum(1)
    hN = (phi[..., None, None] * d2w + dw[..., :, None] * nrm[..., None, :]
          + nrm[..., :, None] * dw[..., None, :]).sum(1)
    hf = (hN - gf[:, :, None] * gD[:, None, :] - gD[:, :, None] * gf[:, None, :]
          - f[:, None, None] * hD) / Ds[:, None, None]
    hf = torch.where(covered[:, None, None], hf, torch.zeros_like(hf))
    return f, gf, hf


def contact(p: torch.Tensor, k: torch.Tensor, bv, bn, bh, index, valid, nearest,
            order: int = 0, exact_hessian: bool = False):
    """Penalty ``k min(f, 0)^2`` per point.

    p : (P, 3); k : (P,) N/m.  Returns energy (P,) J, gradient (P, 3) N or None and
    Hessian (P, 3, 3) N/m or None (Gauss-Newton unless ``exact_hessian``).
    Derivatives are evaluated only for penetrating points.
    """
    f, _, _ = imls(p, bv, bn, bh, index, valid, nearest, order=0)
    neg = torch.clamp(f, max=0.0)
    e = k * neg * neg
    if order == 0:
        return e, None, None
    act = torch.nonzero(f < 0).squeeze(1)
    grad = torch.zeros_like(p)
    hess = p.new_zeros((p.shape[0], 3, 3)) if order >= 2 else None
    if act.numel() == 0:
        return e, grad, hess
    need = 2 if (order >= 2 and exact_hessian) else 1
    fa, ga, ha = imls(p[act], bv, bn, bh, index[act], valid[act], nearest[act], order=need)
    ka = k[act]
    grad[act] = (2.0 * ka * fa)[:, None] * ga
    if order >= 2:
        h = (2.0 * ka)[:, None, None] * ga[:, :, None] * ga[:, None, :]
        if exact_hessian:
            h = h + (2.0 * ka * fa)[:, None, None] * ha
        hess[act] = h
    return e, grad, hess
