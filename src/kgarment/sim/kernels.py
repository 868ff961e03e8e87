"""Compiled CPU kernels (numba) for the per-element derivatives of the hot energy terms.

The torch versions in :mod:`~kgarment.sim.membrane` and :mod:`~kgarment.sim.contact` are the
reference (any device, any precision); these loops compute the same quantities for float64
tensors on the CPU, where torch spends most of an order-2 evaluation in small batched
matrix products and broadcast temporaries (at subdivision 0 the membrane Hessian took
~12 ms and the exact IMLS Hessian ~20 ms in torch, against ~1 ms each here).  The
formulas are those of the torch code line by line; ``tests/test_sim_kernels.py`` checks
they agree to round-off.  Without numba (the ``solver`` extra), the torch code runs.

Kernels are compiled on first use and cached on disk (numba's ``cache=True``: next to
this file, or under ``NUMBA_CACHE_DIR`` where that is not writable).
"""

from __future__ import annotations

import logging
import math

import numpy as np

log = logging.getLogger(__name__)

try:  # pragma: no cover - exercised by whether the extra is installed
    import numba

    AVAILABLE = True
except ImportError:  # pragma: no cover
    numba = None
    AVAILABLE = False

ENABLED = True  # set False to force the torch code (tests, comparisons)
_R_EPS = 1e-9  # as membrane._R_EPS


def applies(x) -> bool:
    """Whether the kernels serve tensors like ``x`` (float64 on the CPU, numba present)."""
    import torch

    return AVAILABLE and ENABLED and x.device.type == "cpu" and x.dtype == torch.float64


def arrays(*tensors) -> list[np.ndarray]:
    """The tensors as contiguous numpy arrays (views where possible) for the kernels."""
    return [np.ascontiguousarray(t.detach().numpy()) for t in tensors]


def _njit(fn):
    # error_model="numpy": a degenerate element gives inf or nan (as in torch), which the
    # solver reports by state and term, instead of raising ZeroDivisionError
    return numba.njit(cache=True, nogil=True, error_model="numpy")(fn) if AVAILABLE else fn


@_njit
def _density2(c11, c22, c12, mu, lam, relaxed, project, wc, wcc):
    """W; fills wc (3,) and wcc (3, 3) on c = (C11, C22, C12) (membrane._density)."""
    tr = c11 + c22
    a = 0.5 * (c11 - c22)
    r = math.sqrt(a * a + c12 * c12)
    lmax = 0.5 * tr + r
    lmin = 0.5 * tr - r
    for i in range(3):
        wc[i] = 0.0
        for j in range(3):
            wcc[i, j] = 0.0
    slack = relaxed and lmax < 1.0
    if slack:
        return 0.0
    uni = relaxed and lmin * math.sqrt(lmax) < 1.0
    if not uni:
        det = c11 * c22 - c12 * c12
        L = math.log(det)
        W = 0.5 * mu * (tr - 2.0) - 0.5 * mu * L + 0.125 * lam * L * L
        d0, d1, d2 = c22 / det, c11 / det, -2.0 * c12 / det
        kappa = 0.25 * lam * L - 0.5 * mu
        wc[0] = kappa * d0 + 0.5 * mu
        wc[1] = kappa * d1 + 0.5 * mu
        wc[2] = kappa * d2
        kap = min(kappa, 0.0) if project else kappa
        dL = (d0, d1, d2)
        for i in range(3):
            for j in range(3):
                wcc[i, j] = (0.25 * lam - kap) * dL[i] * dL[j]
        wcc[0, 1] += kap / det
        wcc[1, 0] += kap / det
        wcc[2, 2] += -2.0 * kap / det
        return W
    lu = lmax
    lnl = math.log(lu)
    W = 0.5 * mu * (lu + 1.0 / math.sqrt(lu) - 2.0) - 0.25 * mu * lnl + lam / 32.0 * lnl * lnl
    dw = 0.5 * mu * (1.0 - 0.5 * lu ** -1.5) - 0.25 * mu / lu + lam / 16.0 * lnl / lu
    if r > _R_EPS:
        rs, ar, br = r, a / r, c12 / r
    else:
        rs, ar, br = 1.0, 0.0, 0.0
    dl = (0.5 + 0.5 * ar, 0.5 - 0.5 * ar, br)
    for i in range(3):
        wc[i] = dw * dl[i]
    ddw = 0.375 * mu * lu ** -2.5 + 0.25 * mu / (lu * lu) + lam / 16.0 * (1.0 - lnl) / (lu * lu)
    if project and ddw < 0.0:
        ddw = 0.0
    pv = (-0.5 * br, 0.5 * br, ar)
    for i in range(3):
        for j in range(3):
            wcc[i, j] = ddw * dl[i] * dl[j] + dw * pv[i] * pv[j] / rs
    return W


@_njit
def membrane_order2(x, tri, G, weight, mu, lam, relaxed, project):
    """Energy (m,), gradient (m, 3, 3) and Hessian (m, 9, 9) of every triangle.

    x : (N, 3); tri : (m, 3) int64; G : (m, 3, 2); weight, mu, lam : (m,); relaxed : (m,)
    bool; project : analytic PSD projection (membrane's ``"analytic"``) or exact.
    """
    m = tri.shape[0]
    e = np.empty(m)
    grad = np.empty((m, 3, 3))
    H = np.empty((m, 9, 9))
    F = np.empty((3, 2))
    wc = np.empty(3)
    wcc = np.empty((3, 3))
    J = np.empty((3, 9))
    JW = np.empty((3, 9))
    S = np.empty((2, 2))
    M = np.empty((3, 3))
    for t in range(m):
        for i in range(3):
            for j in range(2):
                s = 0.0
                for a in range(3):
                    s += x[tri[t, a], i] * G[t, a, j]
                F[i, j] = s
        c11 = F[0, 0] * F[0, 0] + F[1, 0] * F[1, 0] + F[2, 0] * F[2, 0]
        c22 = F[0, 1] * F[0, 1] + F[1, 1] * F[1, 1] + F[2, 1] * F[2, 1]
        c12 = F[0, 0] * F[0, 1] + F[1, 0] * F[1, 1] + F[2, 0] * F[2, 1]
        w = weight[t]
        e[t] = _density2(c11, c22, c12, mu[t], lam[t], relaxed[t], project, wc, wcc) * w
        s11, s22, s12 = 2.0 * wc[0], 2.0 * wc[1], wc[2]
        S[0, 0], S[1, 1], S[0, 1], S[1, 0] = s11, s22, s12, s12
        for a in range(3):
            for i in range(3):
                s = 0.0
                for j in range(2):
                    for k in range(2):
                        s += F[i, j] * S[j, k] * G[t, a, k]
                grad[t, a, i] = s * w
        if project:  # membrane._psd2
            mm = 0.5 * (s11 + s22)
            rr = math.sqrt((0.5 * (s11 - s22)) ** 2 + s12 * s12)
            l1, l2 = mm + rr, mm - rr
            if l2 < 0.0:
                if l1 <= 0.0:
                    s11 = s22 = s12 = 0.0
                else:
                    f = l1 / (2.0 * rr) if rr > 0.0 else 0.0
                    s11, s22, s12 = f * (s11 - l2), f * (s22 - l2), f * s12
            S[0, 0], S[1, 1], S[0, 1], S[1, 0] = s11, s22, s12, s12
        for a in range(3):
            for b in range(3):
                s = 0.0
                for j in range(2):
                    for k in range(2):
                        s += G[t, a, j] * S[j, k] * G[t, b, k]
                M[a, b] = s
        for a in range(3):
            g0, g1 = G[t, a, 0], G[t, a, 1]
            for i in range(3):
                J[0, 3 * a + i] = 2.0 * g0 * F[i, 0]
                J[1, 3 * a + i] = 2.0 * g1 * F[i, 1]
                J[2, 3 * a + i] = g0 * F[i, 1] + g1 * F[i, 0]
        for d in range(3):
            for q in range(9):
                JW[d, q] = wcc[d, 0] * J[0, q] + wcc[d, 1] * J[1, q] + wcc[d, 2] * J[2, q]
        for p in range(9):
            for q in range(p, 9):
                s = J[0, p] * JW[0, q] + J[1, p] * JW[1, q] + J[2, p] * JW[2, q]
                if p % 3 == q % 3:
                    s += M[p // 3, q // 3]
                H[t, p, q] = s * w
                H[t, q, p] = s * w
    return e, grad, H


@_njit
def imls_order2(p, bv, bn, bh, index, valid, nearest, order):
    """IMLS value f (P,), gradient (P, 3), (order 2) Hessian (P, 3, 3) and whether some
    support covers each point (P,) bool (contact.imls)."""
    P, K = index.shape
    f = np.empty(P)
    cov = np.zeros(P, np.bool_)
    gf = np.zeros((P, 3))
    hf = np.zeros((P, 3, 3))
    u = np.empty(3)
    gD = np.empty(3)
    gN = np.empty(3)
    hD = np.empty((3, 3))
    hN = np.empty((3, 3))
    for i in range(P):
        D = 0.0
        Nsum = 0.0
        for c in range(3):
            gD[c] = 0.0
            gN[c] = 0.0
            for d in range(3):
                hD[c, d] = 0.0
                hN[c, d] = 0.0
        for k in range(K):
            if not valid[i, k]:
                continue
            v = index[i, k]
            h = bh[v]
            d2 = 0.0
            phi = 0.0
            for c in range(3):
                u[c] = p[i, c] - bv[v, c]
                d2 += u[c] * u[c]
                phi += bn[v, c] * u[c]
            q = 1.0 - d2 / h
            if q <= 0.0:
                continue
            q2 = q * q
            w = q2 * q2
            D += w
            Nsum += w * phi
            if order == 0:
                continue
            a = -8.0 * q2 * q / h
            for c in range(3):
                dw = a * u[c]
                gD[c] += dw
                gN[c] += phi * dw + w * bn[v, c]
            if order == 1:
                continue
            b = 48.0 * q2 / (h * h)
            for c in range(3):
                for d in range(3):
                    d2w = b * u[c] * u[d] + (a if c == d else 0.0)
                    hD[c, d] += d2w
                    hN[c, d] += phi * d2w + a * u[c] * bn[v, d] + bn[v, c] * a * u[d]
        if D > 0.0:
            cov[i] = True
            fi = Nsum / D
            f[i] = fi
            if order >= 1:
                for c in range(3):
                    gf[i, c] = (gN[c] - fi * gD[c]) / D
            if order >= 2:
                for c in range(3):
                    for d in range(3):
                        hf[i, c, d] = (hN[c, d] - gf[i, c] * gD[d] - gD[c] * gf[i, d] - fi * hD[c, d]) / D
        else:
            v = nearest[i]
            s = 0.0
            for c in range(3):
                s += bn[v, c] * (p[i, c] - bv[v, c])
                gf[i, c] = bn[v, c]
            f[i] = s
    return f, gf, hf, cov


@_njit
def imls_value(p, V, N, hinv, vv, nv, valid, v0, n0):
    """IMLS value f (P,) from contact.gather's per-candidate arrays, and whether some
    support covers each point (P,) bool (contact.imls_value)."""
    P, K = hinv.shape
    f = np.empty(P)
    cov = np.zeros(P, np.bool_)
    for i in range(P):
        pp = p[i, 0] * p[i, 0] + p[i, 1] * p[i, 1] + p[i, 2] * p[i, 2]
        D = 0.0
        Nsum = 0.0
        for k in range(K):
            if valid[i, k] == 0:
                continue
            d2 = pp - 2.0 * (V[i, k, 0] * p[i, 0] + V[i, k, 1] * p[i, 1] + V[i, k, 2] * p[i, 2]) + vv[i, k]
            q = 1.0 - d2 * hinv[i, k]
            if q <= 0.0:
                continue
            q2 = q * q
            w = q2 * q2 * valid[i, k]
            D += w
            Nsum += w * (N[i, k, 0] * p[i, 0] + N[i, k, 1] * p[i, 1] + N[i, k, 2] * p[i, 2] - nv[i, k])
        if D > 0.0:
            cov[i] = True
            f[i] = Nsum / D
        else:
            f[i] = (n0[i, 0] * (p[i, 0] - v0[i, 0]) + n0[i, 1] * (p[i, 1] - v0[i, 1])
                    + n0[i, 2] * (p[i, 2] - v0[i, 2]))
    return f, cov
