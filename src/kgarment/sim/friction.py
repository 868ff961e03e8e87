"""Skin-garment friction: a lagged, smoothed Coulomb potential (``[materials] skin_friction``).

The paper's body is frictionless: the garment slides along the skin and lifts off freely.
A sleeve held at both ends then has a nearly free mode, turning about the arm, and on a
flexing elbow it takes it: the strip over the elbow's outside moves round to its axis,
where flexion does not stretch it, and the sleeve stores almost nothing (measured on the
two-motion sleeve, issue #19).  Cloth on skin has a friction coefficient of about 0.3 to
0.6 (Gerhardt et al. 2008; Derler & Gerhardt 2012), and a strip pulled tight over a bent
elbow presses hard on it, so a real sleeve does not turn there.

Model.  Each vertex v, the garment's and the clutches', is held to its *anchor* ``a_v``:
where it starts, skin-tight on the posed body (the garment that followed the skin without
slipping).  The clutches' vertices count because an ON clutch's pull reaches the skin
through them: a cable wrapped round the bent elbow presses on the body with its own
contact (``sim.cable``), not through the garment's vertices, and that pressure is what
holds it there.  Physically the strip presses on the cloth and the cloth on the skin, and
whichever of the two slides first has a coefficient of about the skin's (textile on
textile 0.3-0.6), so the strip's vertices take the skin's coefficient.  They slide freely
*along* their strip (``along``, :func:`strip_directions`, lagged with the normals): the
film slides in its guide, and a cable's inner nodes only sample its path; held along it
too, they bunched where the cable pressed hardest and Newton stalled (forces of 900 N left
at a node).  Across the strip they meet the full Coulomb force.

With the contact normal force ``lambda_v`` and the unit contact normal ``n_v`` *lagged*
(taken at a given configuration and held fixed during a solve, as in IPC: Li et al. 2020,
section 5), the tangential slip ``u_v = (I - n_v n_v^T - t_v t_v^T)(x_v - a_v)`` (``t_v``
the strip's direction, 0 on the garment) costs the dissipation potential

    D = sum_v  mu lambda_v f0(|u_v|),   f0(y) = y                        (y >= eps)
                                        f0(y) = -y^3/(3 eps^2) + y^2/eps + eps/3  (y < eps)

whose force is ``mu lambda_v`` along the slip once it exceeds ``eps`` (sliding, Coulomb)
and grows from zero below it (sticking; ``eps`` is the tangential give of the skin, a
millimetre or two).  ``f0`` is C2 in ``y`` apart from ``y = eps`` (C1), and its Hessian
is positive semi-definite everywhere (the tangential eigenvalues are ``mu lambda (2/eps -
2 y/eps^2)`` and ``mu lambda (2/eps - y/eps^2)`` below ``eps``, ``mu lambda / y`` and 0
above), so Newton needs no projection for it.

The lag (:func:`normal_forces`): the normal force is the part of the other forces on a
vertex (membrane and springs) that pushes it into the body, ``max(0, n . dE/dx)``, for
vertices on or inside the contact surface.  At an equilibrium that is exactly the contact
penalty's force; at the skin-tight start it is the pressure of the garment stretched with
the skin (the first estimate, before anything slipped).  :func:`kgarment.sim.serial.solve_serial`
re-solves with the normal forces of the equilibrium until they settle (``friction_lags``).
The potential is a dissipation, not stored energy: it is minimised with the rest but not
counted in a state's energy (``StateResult.energy``; its value is ``StateResult.friction``).
"""

from __future__ import annotations

import numpy as np
import torch


def tangential_slip(x: torch.Tensor, anchor: torch.Tensor, normal: torch.Tensor,
                    along: torch.Tensor | None = None) -> torch.Tensor:
    """The slip (P, 3) m that friction resists: ``x - anchor`` less its part along ``normal``
    and, where given, along ``along`` (the free slide along a strip); arguments as in
    :func:`friction`."""
    d = x - anchor
    u = d - (d * normal).sum(1, keepdim=True) * normal
    if along is not None:
        u = u - (d * along).sum(1, keepdim=True) * along
    return u


def friction(x: torch.Tensor, anchor: torch.Tensor, normal: torch.Tensor, bound: torch.Tensor, eps: float,
             order: int = 0, along: torch.Tensor | None = None):
    """The smoothed Coulomb potential per vertex (module doc).

    x, anchor, normal : (P, 3) positions (m), anchors (m) and unit normals;  bound : (P,)
    the largest friction force ``mu lambda`` (N);  eps : the slip (m) at which it is reached;
    along : (P, 3) unit tangents orthogonal to ``normal`` along which a vertex slides freely
    (a strip's vertices: its length), zero rows for none; None: none anywhere.
    Returns energy (P,) J, gradient (P, 3) N or None and Hessian (P, 3, 3) N/m or None.
    """
    u = tangential_slip(x, anchor, normal, along)
    y = torch.linalg.vector_norm(u, dim=1)
    stick = y < eps
    e = bound * torch.where(stick, -y**3 / (3.0 * eps**2) + y**2 / eps + eps / 3.0, y)
    if order == 0:
        return e, None, None
    ysafe = torch.where(y > 0, y, torch.ones_like(y))
    ratio = torch.where(stick, 2.0 / eps - y / eps**2, 1.0 / ysafe)  # f0'(y) / y
    grad = (bound * ratio)[:, None] * u
    if order == 1:
        return e, grad, None
    eye = torch.eye(3, dtype=x.dtype, device=x.device)
    proj = eye - normal[:, :, None] * normal[:, None, :]
    if along is not None:
        proj = proj - along[:, :, None] * along[:, None, :]
    # d(ratio)/dy / y: -1/(eps^2 y) when sticking, -1/y^3 when sliding
    dr = torch.where(stick, -1.0 / (eps**2 * ysafe), -1.0 / ysafe**3)
    dr = torch.where(y > 0, dr, torch.zeros_like(dr))
    hess = bound[:, None, None] * (ratio[:, None, None] * proj + dr[:, None, None] * u[:, :, None] * u[:, None, :])
    return e, grad, hess


def slid_anchor(x: np.ndarray, anchor: np.ndarray, normal: np.ndarray, along: np.ndarray, eps: float) -> np.ndarray:
    """Where friction holds each vertex after the equilibrium ``x`` (P, 3) reached held at
    ``anchor`` (P, 3) (m): the return map of Coulomb friction with the skin's elastic give
    ``eps`` (m).  A vertex whose tangential offset ``u`` (across its strip; ``normal`` and
    ``along`` (P, 3) unit vectors as in :func:`friction`, ``along`` zero rows off strips)
    exceeds ``eps`` slid: it is held ``eps`` behind where it stands, in the direction it
    slid (the skin's give stays loaded, the slip beyond it is permanent); one within ``eps``
    stuck and keeps its offset.  So a frame that repeats the pose finds the garment where it
    was, under any force below the Coulomb bound (anchoring at ``x`` itself would let it
    creep by the give at every frame).  Returns (P, 3) m."""
    u = tangential_slip(*(torch.as_tensor(np.asarray(a, dtype=np.float64)) for a in (x, anchor, normal, along))).numpy()
    y = np.linalg.norm(u, axis=1)
    keep = np.minimum(1.0, eps / np.maximum(y, 1e-300))
    return x - u * keep[:, None]


def normal_forces(elastic_grad: np.ndarray, normal: np.ndarray, f: np.ndarray, near: float) -> np.ndarray:
    """The lagged normal force (P,) N of each vertex (module doc): ``max(0, n . g)`` with
    ``g`` (P, 3) the gradient of every energy but contact and friction (N), ``normal``
    (P, 3) the unit contact normals and ``f`` (P,) the contact function (m); 0 where ``f``
    exceeds ``near`` (m: off the body)."""
    push = np.maximum((elastic_grad * normal).sum(1), 0.0)
    return np.where(f <= near, push, 0.0)


def strip_neighbours(model) -> np.ndarray:
    """For every vertex of ``model`` (a SimModel) the two vertices (N, 2) global ids whose
    difference gives its strip's direction: for a clutch vertex the centre-line vertices
    before and after the one nearest it at rest; -1 for the garment's vertices."""
    out = np.full((model.n_vertices, 2), -1, dtype=np.int64)
    for k, c in enumerate(model.clutches):
        off = int(model.vertex_offsets[k + 1])
        cl = np.asarray(c.centerline)
        near = np.argmin(np.linalg.norm(c.vertices[:, None, :] - c.vertices[cl][None], axis=2), axis=1)
        out[off: off + len(c.vertices), 0] = off + cl[np.maximum(near - 1, 0)]
        out[off: off + len(c.vertices), 1] = off + cl[np.minimum(near + 1, len(cl) - 1)]
    return out


def strip_directions(x: np.ndarray, neighbours: np.ndarray, normal: np.ndarray) -> np.ndarray:
    """Unit directions (N, 3) along each vertex's strip at x (N, 3), orthogonal to its unit
    ``normal`` (N, 3): zero rows for vertices on no strip (``neighbours`` (N, 2) -1)."""
    on = neighbours[:, 0] >= 0
    t = np.zeros_like(x)
    t[on] = x[neighbours[on, 1]] - x[neighbours[on, 0]]
    t -= (t * normal).sum(1, keepdims=True) * normal
    length = np.linalg.norm(t, axis=1)
    return np.where(length[:, None] > 0, t / np.maximum(length, 1e-300)[:, None], 0.0)
