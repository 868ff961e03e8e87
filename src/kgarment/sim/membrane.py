"""Constant-strain triangles with a compressible 2D neo-Hookean energy (+ wrinkling).

Per triangle with rest vertices ``X0, X1, X2`` we build an orthonormal 2D frame in the rest
plane, ``Dm = [X1-X0, X2-X0]`` in that frame (2x2) and the shape-function gradients
``g_a`` (rows of ``Dm^-1`` for a = 1, 2 and ``g_0 = -g_1 - g_2``).  The deformation gradient
is ``F = sum_a x_a g_a^T`` (3x2) and ``C = F^T F`` (2x2).  With ``c = (C11, C22, C12)``::

    W(C) = mu/2 (I_C - 2) - mu ln J + lambda/2 (ln J)^2,   I_C = C11 + C22,  J^2 = det C

and the element energy is ``W * A * t`` (rest area A, thickness t), joules.

Wrinkling relaxation (garment triangles only): with eigenvalues ``l_max >= l_min`` of C,

* ``l_max < 1``: slack, W = 0;
* ``l_max >= 1`` and ``l_min < l_max^-1/2``: uniaxial tension, W = w(l_max) with
  ``w(l) = mu/2 (l + l^-1/2 - 2) - mu/4 ln l + lambda/32 (ln l)^2`` (C evaluated at
  ``(l, l^-1/2)``);
* otherwise the normal energy, written with the smooth invariants ``I_C, det C``.

The relaxed branch depends on C only through ``l_max = I_C/2 + r``,
``r = sqrt(((C11-C22)/2)^2 + C12^2)``, whose Hessian ``~1/r`` is singular at repeated
eigenvalues; there ``w'(l_max) <= 2 w''(1) r`` (because ``l_max - 1 < 2 r`` in that
branch), so the product is bounded.  We drop the term when ``r < 1e-9`` (the triangle is
then within 1e-9 of its rest metric).  The energy is C1 at ``l_max = 1`` and only C0
across ``l_min = l_max^-1/2`` (the rule is the method's, not the exact tension-field
minimiser of the compressible law).

Derivatives: ``dW/dx_a = F S g_a`` with ``S = 2 dW/dC``; the Hessian is
``kron(G S G^T, I3) + J^T W_cc J`` with ``J = dc/dx`` (3x9).  PSD projection modes:

* ``"analytic"`` (default, no eigensolver): clamp the 2x2 stress ``S`` to PSD in closed
  form and make ``W_cc`` PSD analytically (relaxed branch: ``max(w'', 0)``; normal
  branch: drop the ``ln det C`` curvature term when its coefficient
  ``lambda ln(det C)/4 - mu/2`` is positive, i.e. area ratio > ~2.8).  Exact whenever
  the stress is tensile, which is the equilibrium of a stretched garment;
* ``"full"``: batched ``eigh`` of the 9x9 element Hessian, eigenvalues clamped at 0;
* ``"none"``: the exact Hessian (for tests).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch

from kgarment.sim import kernels

_R_EPS = 1e-9


@dataclass(frozen=True)
class TriangleElements:
    """Rest-state structure of a set of triangles.

    Attributes
    ----------
    tri : (m, 3) int64 — global vertex indices into the simulator's x (N, 3).
    shape_grad : (m, 3, 2) float64 — ``g_a`` per vertex, 1/m.
    area : (m,) float64 — rest area, m^2.
    """

    tri: np.ndarray
    shape_grad: np.ndarray
    area: np.ndarray

    @staticmethod
    def from_mesh(rest_vertices: np.ndarray, faces: np.ndarray, offset: int = 0) -> TriangleElements:
        """rest_vertices : (n, 3) m; faces : (m, 3) local indices; ``offset`` is added to them."""
        X = np.asarray(rest_vertices, dtype=np.float64)
        f = np.asarray(faces, dtype=np.int64)
        e1 = X[f[:, 1]] - X[f[:, 0]]
        e2 = X[f[:, 2]] - X[f[:, 0]]
        nrm = np.cross(e1, e2)
        dbl = np.linalg.norm(nrm, axis=1)
        if np.any(dbl <= 1e-14 * np.maximum(np.sum(e1 * e1, 1), 1e-300)):
            raise ValueError("degenerate (zero-area) rest triangle")
        t1 = e1 / np.linalg.norm(e1, axis=1, keepdims=True)
        t2 = np.cross(nrm / dbl[:, None], t1)
        dm = np.empty((len(f), 2, 2))
        dm[:, 0, 0] = np.sum(e1 * t1, 1)
        dm[:, 1, 0] = 0.0
        dm[:, 0, 1] = np.sum(e2 * t1, 1)
        dm[:, 1, 1] = np.sum(e2 * t2, 1)
        binv = np.linalg.inv(dm)  # rows: g_1, g_2
        g = np.empty((len(f), 3, 2))
        g[:, 1] = binv[:, 0]
        g[:, 2] = binv[:, 1]
        g[:, 0] = -binv[:, 0] - binv[:, 1]
        return TriangleElements(tri=f + offset, shape_grad=g, area=0.5 * dbl)

    @staticmethod
    def concat(parts: list[TriangleElements]) -> TriangleElements:
        return TriangleElements(
            tri=np.concatenate([p.tri for p in parts]),
            shape_grad=np.concatenate([p.shape_grad for p in parts]),
            area=np.concatenate([p.area for p in parts]),
        )


def _density(c11, c22, c12, mu, lam, relaxed, order: int, project: bool):
    """W (Pa), W_c (m, 3) and W_cc (m, 3, 3) on c = (C11, C22, C12)."""
    tr = c11 + c22
    a = 0.5 * (c11 - c22)
    r = torch.sqrt(a * a + c12 * c12)
    lmax = 0.5 * tr + r
    lmin = 0.5 * tr - r
    slack = relaxed & (lmax < 1.0)
    uni = relaxed & ~slack & (lmin * torch.sqrt(lmax) < 1.0)
    normal = ~slack & ~uni
    one = torch.ones_like(tr)

    det = c11 * c22 - c12 * c12
    det = torch.where(normal, det, one)
    L = torch.log(det)
    w_n = 0.5 * mu * (tr - 2.0) - 0.5 * mu * L + 0.125 * lam * L * L
    lu = torch.where(uni, lmax, one)
    lnl = torch.log(lu)
    w_u = 0.5 * mu * (lu + lu.rsqrt() - 2.0) - 0.25 * mu * lnl + lam / 32.0 * lnl * lnl
    zero = torch.zeros_like(tr)
    W = torch.where(normal, w_n, torch.where(uni, w_u, zero))
    if order == 0:
        return W, None, None

    # normal branch
    dL = torch.stack([c22, c11, -2.0 * c12], dim=1) / det[:, None]
    kappa = 0.25 * lam * L - 0.5 * mu
    wc_n = kappa[:, None] * dL
    wc_n[:, 0] += 0.5 * mu
    wc_n[:, 1] += 0.5 * mu
    # uniaxial branch
    dw = 0.5 * mu * (1.0 - 0.5 * lu ** -1.5) - 0.25 * mu / lu + lam / 16.0 * lnl / lu
    rs = torch.where(uni & (r > _R_EPS), r, one)
    ar = torch.where(uni & (r > _R_EPS), a / rs, zero)
    br = torch.where(uni & (r > _R_EPS), c12 / rs, zero)
    dl = torch.stack([0.5 + 0.5 * ar, 0.5 - 0.5 * ar, br], dim=1)
    wc_u = dw[:, None] * dl
    Wc = torch.where(normal[:, None], wc_n, torch.where(uni[:, None], wc_u, zero[:, None]))
    if order == 1:
        return W, Wc, None

    d2det = torch.zeros((3, 3), dtype=tr.dtype, device=tr.device)
    d2det[0, 1] = d2det[1, 0] = 1.0
    d2det[2, 2] = -2.0
    d2L = d2det / det[:, None, None] - dL[:, :, None] * dL[:, None, :]
    kap = torch.clamp(kappa, max=0.0) if project else kappa
    wcc_n = 0.25 * lam[:, None, None] * dL[:, :, None] * dL[:, None, :] + kap[:, None, None] * d2L
    ddw = 0.375 * mu * lu ** -2.5 + 0.25 * mu / (lu * lu) + lam / 16.0 * (1.0 - lnl) / (lu * lu)
    if project:
        ddw = torch.clamp(ddw, min=0.0)
    # Hessian of r in c: P^T (I - uu^T) P / r with u = (a, C12)/r, P = [[.5,-.5,0],[0,0,1]]
    perp = torch.stack([-br, ar], dim=1)  # unit vector orthogonal to u (zero where masked)
    pv = torch.stack([0.5 * perp[:, 0], -0.5 * perp[:, 0], perp[:, 1]], dim=1)
    d2l = pv[:, :, None] * pv[:, None, :] / rs[:, None, None]
    wcc_u = ddw[:, None, None] * dl[:, :, None] * dl[:, None, :] + dw[:, None, None] * d2l
    Wcc = torch.where(normal[:, None, None], wcc_n,
                      torch.where(uni[:, None, None], wcc_u, zero[:, None, None]))
    return W, Wc, Wcc


def branches(x: torch.Tensor, tri: torch.Tensor, shape_grad: torch.Tensor, relaxed: torch.Tensor) -> torch.Tensor:
    """(m,) int: 0 normal, 1 slack, 2 uniaxial tension (wrinkled) at positions x (N, 3)."""
    F = torch.einsum("mai,maj->mij", x[tri], shape_grad)
    f0, f1 = F[:, :, 0], F[:, :, 1]
    c11, c22, c12 = (f0 * f0).sum(1), (f1 * f1).sum(1), (f0 * f1).sum(1)
    r = torch.sqrt((0.5 * (c11 - c22)) ** 2 + c12 * c12)
    lmax, lmin = 0.5 * (c11 + c22) + r, 0.5 * (c11 + c22) - r
    slack = relaxed & (lmax < 1.0)
    uni = relaxed & ~slack & (lmin * torch.sqrt(lmax) < 1.0)
    out = torch.zeros_like(c11, dtype=torch.long)
    out[slack] = 1
    out[uni] = 2
    return out


def _abs2(s11, s22, s12):
    """Closed-form |S| (eigenvalues replaced by their absolute values) of symmetric 2x2."""
    m = 0.5 * (s11 + s22)
    r = torch.sqrt((0.5 * (s11 - s22)) ** 2 + s12 * s12)
    l1, l2 = m + r, m - r
    a1, a2 = l1.abs(), l2.abs()
    # S = l1 P1 + l2 P2 with P1 = (S - l2 I)/(l1 - l2), P2 = I - P1
    den = torch.where(r > 0, 2.0 * r, torch.ones_like(r))
    p11 = torch.where(r > 0, (s11 - l2) / den, torch.ones_like(r))
    p22 = torch.where(r > 0, (s22 - l2) / den, torch.zeros_like(r))
    p12 = torch.where(r > 0, s12 / den, torch.zeros_like(r))
    return a2 + (a1 - a2) * p11, a2 + (a1 - a2) * p22, (a1 - a2) * p12


def _psd2(s11, s22, s12):
    """Closed-form projection of symmetric 2x2 matrices onto the PSD cone."""
    m = 0.5 * (s11 + s22)
    r = torch.sqrt((0.5 * (s11 - s22)) ** 2 + s12 * s12)
    l1, l2 = m + r, m - r
    # where exactly one eigenvalue is positive: l1 * v v^T with v v^T = (S - l2 I) / (l1 - l2)
    den = torch.where(r > 0, 2.0 * r, torch.ones_like(r))
    f = torch.where(r > 0, l1 / den, torch.zeros_like(r))
    p11, p22, p12 = f * (s11 - l2), f * (s22 - l2), f * s12
    keep = l2 >= 0
    kill = l1 <= 0
    z = torch.zeros_like(s11)
    out11 = torch.where(keep, s11, torch.where(kill, z, p11))
    out22 = torch.where(keep, s22, torch.where(kill, z, p22))
    out12 = torch.where(keep, s12, torch.where(kill, z, p12))
    return out11, out22, out12


def membrane(
    x: torch.Tensor,
    tri: torch.Tensor,
    shape_grad: torch.Tensor,
    weight: torch.Tensor,
    mu: torch.Tensor,
    lam: torch.Tensor,
    relaxed: torch.Tensor,
    order: int = 0,
    projection: str = "analytic",
):
    """Membrane energy of all triangles at once.

    x : (N, 3) positions; tri : (m, 3) long; shape_grad : (m, 3, 2); weight : (m,) rest
    area * thickness (m^3); mu, lam : (m,) Pa; relaxed : (m,) bool (wrinkling relaxation).
    order : 0 energy, 1 + gradient, 2 + Hessian.  projection : "analytic" | "full" | "none".

    Returns ``(e, grad, hess)``: per-element energy (m,) J; per-element gradient (m, 3, 3)
    [element vertex, coordinate] N or None; per-element Hessian (m, 9, 9) with row index
    ``3 * vertex + coordinate`` in N/m, or None.
    """
    if order == 2 and projection in ("analytic", "none") and kernels.applies(x):
        e, grad, H = kernels.membrane_order2(*kernels.arrays(x, tri, shape_grad, weight, mu, lam, relaxed),
                                             projection == "analytic")
        return torch.from_numpy(e), torch.from_numpy(grad), torch.from_numpy(H)
    X = x[tri]  # (m, 3, 3)
    F = torch.einsum("mai,maj->mij", X, shape_grad)  # (m, 3, 2)
    f0, f1 = F[:, :, 0], F[:, :, 1]
    c11 = (f0 * f0).sum(1)
    c22 = (f1 * f1).sum(1)
    c12 = (f0 * f1).sum(1)
    project = projection in ("analytic", "abs")
    W, Wc, Wcc = _density(c11, c22, c12, mu, lam, relaxed, order, project)
    e = W * weight
    if order == 0:
        return e, None, None
    s11, s22, s12 = 2.0 * Wc[:, 0], 2.0 * Wc[:, 1], Wc[:, 2]
    S = torch.stack([torch.stack([s11, s12], 1), torch.stack([s12, s22], 1)], 1)
    grad = torch.einsum("mij,mjk,mak->mai", F, S, shape_grad) * weight[:, None, None]
    if order == 1:
        return e, grad, None
    if project:
        s11, s22, s12 = _abs2(s11, s22, s12) if projection == "abs" else _psd2(s11, s22, s12)
        S = torch.stack([torch.stack([s11, s12], 1), torch.stack([s12, s22], 1)], 1)
    G = shape_grad
    M = torch.einsum("maj,mjk,mbk->mab", G, S, G)  # (m, 3, 3)
    J = torch.stack([
        2.0 * G[:, :, 0, None] * f0[:, None, :],
        2.0 * G[:, :, 1, None] * f1[:, None, :],
        G[:, :, 0, None] * f1[:, None, :] + G[:, :, 1, None] * f0[:, None, :],
    ], dim=1).reshape(-1, 3, 9)  # (m, 3, 9)
    H = torch.einsum("mci,mcd,mdj->mij", J, Wcc, J)
    eye = torch.eye(3, dtype=x.dtype, device=x.device)
    H = H + (M[:, :, None, :, None] * eye[None, None, :, None, :]).reshape(-1, 9, 9)
    H = H * weight[:, None, None]
    if projection == "full":
        H = 0.5 * (H + H.transpose(1, 2))
        lam_, vec = torch.linalg.eigh(H)
        H = (vec * lam_.clamp(min=0.0)[:, None, :]) @ vec.transpose(1, 2)
    return e, grad, H
