"""Clutch holding force: an ON clutch holds up to a force, then slides at that force.

An electrostatic clutch is two strips pressed together by the electric field; friction
between them holds a shear force up to ``F_h`` (N, set by the overlap area, the voltage and
the dielectric), and beyond it the strips slide.  The ``locked`` model (the paper's) makes
an ON clutch a stiff sheet that never slips.  The ``slip`` model splits an ON clutch
element into

* the clutch's OFF membrane (the textile guide the strips slide in, every direction), and
* an axial slider along the clutch: with ``a`` the element's rest direction along the
  clutch's centre line, ``lambda = |F a|`` its stretch and ``e = lambda - 1``, an energy
  per unit rest area ``psi(e)`` (J/m^2) whose force ``psi'(e)`` (N per metre of width) is

      k e                                   |e| <= e1 = (1 - SMOOTH) e_h
      a stiffness ramping from k to 0       e1 <= |e| <= e2 = (1 + SMOOTH) e_h
      q (1 + HARDENING (|e| - e2))          |e| >= e2           (sign of e; e_h = q / k)

  with ``k = (Y t)(g) - (Y t)_off`` (N/m) the stiffness the activation ``g`` adds and
  ``q = g^2 F_h / w`` (N/m) the holding force per unit width (``w`` the strip's rest width;
  the force goes with the voltage squared, so a partial activation ``g``, a fraction of
  the voltage, holds ``g^2 F_h``).  Friction holds both ways, so the law is symmetric.

A strip in uniform tension carries ``k w e`` (plus its guide) below ``(1 - SMOOTH) F_h``
and ``F_h`` from ``e2`` on, rising by ``HARDENING`` of it per unit of further strain
(``tests/test_sim_slip.py``).  Two departures from a plain Huber law, both for Newton:
the ramp (the force's slope falls to 0 over a band instead of at a kink) and the slight
hardening (5% over a further 10% slide; without it the elements of a sliding strip, in
series, have no stiffness to share the slide and Newton needed 3-10x the iterations, or did
not converge, on the main job's design).  ``psi`` is convex and ``lambda`` is convex in
the positions (the norm of a linear map), so the element Hessian::

    A [psi'' (c c^T) (x) (n n^T) + psi' / lambda (c c^T) (x) (I - n n^T)]

with ``c_b = g_b . a`` (the axial shape coefficients) and ``n = F a / lambda`` is positive
semi-definite wherever ``psi' >= 0`` (tension); in compression the second term is dropped
(``project``).  The energy is path-independent (a nonlinear-elastic stand-in for friction),
exact for the monotone loading of a motion from rest to its target pose.

Holding force of a clutch of width ``w`` and length ``L`` (overlap area ``w L``):
``F_h = tau w L`` with a shear strength ``tau`` (default 21 N/cm^2, measured for the
textile clutches the paper used, Hinchet & Shea 2020), or from the parallel-plate
electrostatic formula ``tau = mu eps0 eps_r V^2 / (2 d^2)`` (:func:`electrostatic_stress`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import torch

from kgarment.constants import SLIPPING

EPS0 = 8.8541878128e-12  # vacuum permittivity, F/m


def electrostatic_stress(voltage: float, thickness: float, permittivity: float, friction: float) -> float:
    """Shear holding stress ``mu eps0 eps_r V^2 / (2 d^2)`` in Pa of an electrostatic clutch:
    ``voltage`` V, dielectric ``thickness`` d (m), relative ``permittivity`` eps_r, friction
    coefficient mu between the strips."""
    return friction * EPS0 * permittivity * voltage**2 / (2.0 * thickness**2)


def slides(tension: float, holding: float) -> bool:
    """Whether a clutch carrying ``tension`` (N) slides at its ``holding`` force (N): at
    :data:`kgarment.constants.SLIPPING` of it or more; never when locked (inf) or off (0)."""
    return bool(0.0 < holding < math.inf and tension >= SLIPPING * holding)


def axial_coefficients(rest: np.ndarray, tri: np.ndarray, shape_grad: np.ndarray,
                       centerline: np.ndarray) -> np.ndarray:
    """(q, 3) axial shape coefficients ``c_b = g_b . a`` (1/m) of a strip's elements.

    rest : (nc, 3) the strip's rest vertices (m); tri : (q, 3) local vertex ids;
    shape_grad : (q, 3, 2) the elements' shape-function gradients in their rest frames;
    centerline : (r,) the centre-line vertices, start to end.  ``a`` is the direction of the
    centre-line segment nearest the element's centroid, in the element's plane; then
    ``F a = sum_b x_b c_b`` is the element's deformed axial vector, of length 1 at rest.
    """
    line = rest[np.asarray(centerline)]
    seg = line[1:] - line[:-1]  # (r-1, 3)
    cen = rest[tri].mean(axis=1)  # (q, 3)
    t = np.einsum("qsk,sk->qs", cen[:, None, :] - line[None, :-1], seg) / np.einsum("sk,sk->s", seg, seg)
    foot = line[None, :-1] + np.clip(t, 0.0, 1.0)[..., None] * seg[None]
    nearest = np.argmin(np.linalg.norm(cen[:, None, :] - foot, axis=2), axis=1)
    d = seg[nearest] / np.linalg.norm(seg[nearest], axis=1, keepdims=True)
    frame = np.einsum("qbk,qbj->qkj", rest[tri], shape_grad)  # (q, 3, 2): orthonormal columns
    a = np.einsum("qkj,qk->qj", frame, d)  # d in the element's 2D frame
    a /= np.linalg.norm(a, axis=1, keepdims=True)
    return np.einsum("qbj,qj->qb", shape_grad, a)


def path_length(points: np.ndarray) -> float:
    """Length (m) of a polyline (P, 3)."""
    return float(np.linalg.norm(np.diff(points, axis=0), axis=1).sum())


def rest_width(rest: np.ndarray, faces: np.ndarray, centerline: np.ndarray) -> float:
    """A strip's mean rest width (m): its rest area over its centre line's rest length."""
    p = rest[np.asarray(faces)]
    area = 0.5 * np.linalg.norm(np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]), axis=1).sum()
    return float(area) / path_length(rest[np.asarray(centerline)])


@dataclass(frozen=True)
class SliderSet:
    """The axial sliders of one state's slipping clutch elements (torch tensors).

    element : (q,) long element ids;  tri : (q, 3) long vertex ids;  coef : (q, 3) axial
    shape coefficients (1/m);  area : (q,) rest areas (m^2);  k : (q,) slider stiffness
    (N/m);  cap : (q,) holding force per unit width (N/m);  pull_only : the sliders carry
    no compression (a buckling strip, ``[clutches] buckle``).
    """

    element: torch.Tensor
    tri: torch.Tensor
    coef: torch.Tensor
    area: torch.Tensor
    k: torch.Tensor
    cap: torch.Tensor
    pull_only: bool = False


SMOOTH = 0.5      # the slider's stiffness ramps from k down over e_h (1 -+ SMOOTH)
HARDENING = 0.5   # beyond, the force rises by this share of the holding force per unit strain


def slider_law(e: torch.Tensor, k: torch.Tensor, cap: torch.Tensor, pull_only: bool = False):
    """``psi`` (J/m^2), ``psi'`` (N/m) and ``psi''`` (N/m) at axial strains e (q,).

    Symmetric (friction holds both ways): ``k e^2 / 2`` for ``|e| <= e1 = (1 - SMOOTH) e_h``,
    then a stiffness ramping linearly from k to 0 at ``|e| = e2 = (1 + SMOOTH) e_h``
    (``e_h = cap / k``), where the force ``|psi'|`` reaches ``cap`` exactly, and beyond
    ``cap (1 + HARDENING (|e| - e2))``.  C1, convex.  ``pull_only``: 0 for ``e < 0`` (a
    strip that buckles when shortened; still C1 and convex, its second derivative jumps at
    0 as the cloth's wrinkling relaxation's does)."""
    if pull_only:
        e = e.clamp(min=0.0)
    a = e.abs()
    e_h = cap / k
    e1, e2 = (1.0 - SMOOTH) * e_h, (1.0 + SMOOTH) * e_h
    w = e2 - e1
    ramp = torch.minimum((a - e1).clamp(min=0.0), w)  # strain into the ramp
    beyond = (a - e2).clamp(min=0.0)
    ec = torch.minimum(a, e1)  # strain in the quadratic part
    h = HARDENING * cap
    psi = (0.5 * k * ec * ec + k * e1 * ramp + k * (ramp * ramp / 2 - ramp**3 / (6 * w))
           + cap * beyond + 0.5 * h * beyond * beyond)
    dpsi = torch.sign(e) * (k * (ec + ramp - ramp * ramp / (2 * w)) + h * beyond)
    ddpsi = k * (1.0 - ramp / w) + h * (beyond > 0)
    if pull_only:
        ddpsi = ddpsi * (e > 0)
    return psi, dpsi, ddpsi


def slider_energy(x: torch.Tensor, s: SliderSet, order: int = 0, project: bool = True):
    """Energy of the sliders at positions x (N, 3): per slider energy (q,) J, gradient
    (q, 3, 3) [element vertex, coordinate] N (order >= 1) and Hessian (q, 9, 9) with row
    ``3 * vertex + coordinate`` N/m (order 2); Nones where not asked.  ``project`` drops
    the negative transverse term of a slider in compression (``psi' < 0``), which makes
    the Hessian PSD; without, it is exact."""
    v = torch.einsum("qbi,qb->qi", x[s.tri], s.coef)  # F a, (q, 3)
    lam = torch.linalg.vector_norm(v, dim=1)
    psi, dpsi, ddpsi = slider_law(lam - 1.0, s.k, s.cap, s.pull_only)
    energy = s.area * psi
    if order == 0:
        return energy, None, None
    n = v / lam[:, None]
    grad = (s.area * dpsi)[:, None, None] * s.coef[:, :, None] * n[:, None, :]
    if order == 1:
        return energy, grad, None
    cc = s.coef[:, :, None] * s.coef[:, None, :]  # (q, 3, 3)
    nn = n[:, :, None] * n[:, None, :]
    eye = torch.eye(3, dtype=x.dtype, device=x.device)
    side = (dpsi.clamp(min=0.0) if project else dpsi) / lam
    block = ddpsi[:, None, None] * nn + side[:, None, None] * (eye - nn)  # (q, 3, 3)
    hess = (s.area[:, None, None, None, None] * cc[:, :, None, :, None] * block[:, None, :, None, :])
    return energy, grad, hess.reshape(-1, 9, 9)
