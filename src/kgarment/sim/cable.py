"""The cable clutch: an ON clutch carries one force between its ends, pulled only.

An electrostatic clutch is two strips that slide over each other; switched on, friction
between them holds the force between the clutch's two ends, whatever the strips do in
between.  The ``locked`` and ``slip`` models (the paper's and :mod:`kgarment.sim.slip`) make
every element of an ON strip stiff: a band bonded to the cloth, whose halves can be
stretched by the cloth under them while the strip as a whole is shortened, so that it
stores energy (a "lock") where a real clutch, shortened end to end, is slack.

The ``cable`` model (``[clutches] model = "cable"``) keeps an ON strip's OFF membrane (the
textile guide the strips slide in) and adds one pull-only cable per clutch along the
strip's centre line: from the centroid of its three start anchors through its inner
centre-line vertices to the centroid of its three end anchors (points ``p = W x``,
:func:`strip_path`).  With ``L(x) = sum_j |p_{j+1} - p_j|``, ``L0`` its rest length and
``A = w L0`` the strip's rest area (w its mean width)::

    e = L / L0 - 1,        E = A psi(e)          (J)

``psi`` is :func:`kgarment.sim.slip.slider_law`, pull only, with ``k = (Y t)(g) - (Y t)_off``
(N/m) and ``cap = g^2 F_h / w`` (N/m): the cable carries ``T = w psi'(e)`` newtons
(:meth:`Cable.tension`), ``k w e`` below the holding force ``F_h``, about ``F_h`` beyond it
(it slides), and nothing when the strip is shortened on the whole, however its parts are
stretched.  It pulls the two anchor groups towards each other along the strip and presses
the inner centre line onto the body where it wraps it (a string's force, normal to the
path); the anchors carry it into the garment, so :func:`kgarment.sim.clutch_tensions`
measures it as in the other models.

A string's inner nodes have no stiffness along it, so they may slide along the path
freely (physically right: the film slides in its guide; the nodes only sample its path),
and under a taut cable they bunched (a zero-length segment has curvature ``1/|s|``: Newton
stalled).  A *spacing* term keeps them spread: ``k_s / 2 sum_j (l_{j+1} - l_j)^2`` over
consecutive segment lengths, unchanged when the path stretches or shortens evenly (so it
resists no change of the cable's length), with ``k_s = SPACING w min(cap, k) / l0``
(l0 the mean rest segment): a 1 mm unevenness between two segments stores ~1e-4 J.

Variants that stalled Newton are in docs/notes/solver.md, "The cable clutch".

Derivatives, with ``u_j`` the unit segment directions and ``J = dL/dx = W^T (u_{j-1} - u_j)``::

    grad = w psi'(e) J
    hess = (w / L0) psi''(e) J J^T + w psi'(e) W^T [sum_j (I - u_j u_j^T) / |s_j|] W

both positive semi-definite (``psi' >= 0``), dense over the cable's vertices (its anchors
and centre line, ~30 at subdivision 1): a block per clutch in the Hessian's pattern
(:func:`kgarment.sim.assembly.build_pattern`, ``dense``).  The energy is shared among the
strip's elements by area for the per-element energies (renders, ``terms``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch

from kgarment.sim.slip import slider_law

LOCKED_CAP = 1e30  # N/m: the cap of a cable that never slips (an infinite holding force)
SPACING = 0.1      # the spacing term's stiffness: this share of the cable's holding force (or of
                   # its force at 100% strain, if lower) per rest segment length


def strip_path(anchors: np.ndarray, centerline: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """A cable through the strip's own vertices: their local ids (v,) (sorted: the anchors
    and the centre line) and W (P, v) to the path's points: the start anchors' centroid,
    the inner centre-line vertices, the end anchors' centroid."""
    anchors, centerline = np.asarray(anchors), np.asarray(centerline)
    ids = np.unique(np.concatenate([anchors, centerline]))
    inner = centerline[1:-1]
    W = np.zeros((len(inner) + 2, len(ids)))
    W[0, np.searchsorted(ids, anchors[:3])] = 1.0 / 3.0
    W[np.arange(1, len(inner) + 1), np.searchsorted(ids, inner)] = 1.0
    W[-1, np.searchsorted(ids, anchors[3:])] = 1.0 / 3.0
    return ids, W


@dataclass(frozen=True)
class Cable:
    """One ON clutch's cable (torch tensors where arrays).

    clutch : the clutch's index;  vertices : (v,) long global vertex ids;  W : (P, v) the
    map to the path's points (:func:`strip_path`);  rest : rest length L0 (m);  width : the
    strip's mean rest width w (m);  k : stiffness the activation adds (N/m);  cap : holding
    force per unit width (N/m);  elements : (q,) long the strip's element ids;  share : (q,)
    their rest-area shares (sum 1);  spacing : stiffness (N/m) of the spacing term (module doc).
    """

    clutch: int
    vertices: torch.Tensor
    W: torch.Tensor
    rest: float
    width: float
    k: torch.Tensor
    cap: torch.Tensor
    elements: torch.Tensor
    share: torch.Tensor
    spacing: float = 0.0

    def tension(self, x: torch.Tensor) -> float:
        """The force (N) the cable carries at positions x (N, 3): ``w psi'(e)``."""
        _, dpsi, _ = slider_law(self.strain(x), self.k, self.cap, pull_only=True)
        return float(self.width * dpsi)

    def strain(self, x: torch.Tensor) -> torch.Tensor:
        """The cable's strain ``L / L0 - 1`` at positions x (N, 3) (0-d tensor)."""
        p = self.W @ x[self.vertices]
        return torch.linalg.vector_norm(p[1:] - p[:-1], dim=1).sum() / self.rest - 1.0


def cable_energy(x: torch.Tensor, c: Cable, order: int = 0, project: bool = True):
    """One cable's energy at positions x (N, 3): ``(energy, grad, hess)`` -- the energy (0-d,
    J), its gradient over the cable's vertices (v, 3) N (order >= 1) and its Hessian there
    (3v, 3v) N/m, DOF ``3 * vertex + coordinate`` (order 2); Nones where not asked.

    The energy is the cable's ``A psi(e)`` plus the spacing term (module doc), a function
    of the segment lengths ``l`` (P-1,): ``E(l)``; with ``B = dl/dx``, ``g = dE/dl``::

        grad = B^T g,   hess = B^T (d2E/dl2) B + sum_i g_i W^T (I - u_i u_i^T) / l_i W

    ``d2E/dl2`` is PSD; ``project`` keeps only ``g_i > 0`` in the second term (PSD; the
    cable's own ``g_i = w psi' >= 0`` always, the spacing term's may be negative)."""
    p = c.W @ x[c.vertices]  # (P, 3)
    seg = p[1:] - p[:-1]
    length = torch.linalg.vector_norm(seg, dim=1)
    e = length.sum() / c.rest - 1.0
    psi, dpsi, ddpsi = slider_law(e, c.k, c.cap, pull_only=True)
    area = c.width * c.rest
    diff = length[1:] - length[:-1]
    energy = area * psi + 0.5 * c.spacing * (diff * diff).sum()
    if order == 0:
        return energy, None, None
    g = c.width * dpsi + c.spacing * _dt(diff, len(length))  # dE/dl, (P-1,)
    u = seg / length[:, None]
    B = torch.zeros(len(length), len(p), 3, dtype=x.dtype, device=x.device)  # dl/dp
    j = torch.arange(len(length), device=x.device)
    B[j, j + 1] = u
    B[j, j] = -u
    Bx = torch.einsum("lpi,pv->lvi", B, c.W).reshape(len(length), -1)  # dl/dx, (P-1, 3v)
    grad = (g @ Bx).reshape(-1, 3)
    if order == 1:
        return energy, grad, None
    n = len(c.vertices)
    D = torch.zeros(len(length) - 1, len(length), dtype=x.dtype, device=x.device)
    D[j[:-1], j[:-1] + 1], D[j[:-1], j[:-1]] = 1.0, -1.0
    d2 = c.width * ddpsi / c.rest + c.spacing * (D.T @ D)  # d2E/dl2 (the cable's part is rank one)
    eye = torch.eye(3, dtype=x.dtype, device=x.device)
    gg = g.clamp(min=0.0) if project else g
    blocks = gg[:, None, None] * (eye - u[:, :, None] * u[:, None, :]) / length[:, None, None]  # (P-1, 3, 3)
    Hp = torch.zeros(len(p), 3, len(p), 3, dtype=x.dtype, device=x.device)
    Hp[j, :, j, :] += blocks
    Hp[j + 1, :, j + 1, :] += blocks
    Hp[j, :, j + 1, :] -= blocks
    Hp[j + 1, :, j, :] -= blocks
    geo = torch.einsum("pv,piqj,qw->viwj", c.W, Hp, c.W).reshape(3 * n, 3 * n)
    hess = Bx.T @ d2 @ Bx + geo
    return energy, grad, hess


def _dt(diff: torch.Tensor, n: int) -> torch.Tensor:
    """``D^T diff`` (n,) for the differences ``diff = D l`` (n-1,) of consecutive lengths."""
    out = torch.zeros(n, dtype=diff.dtype, device=diff.device)
    out[1:] += diff
    out[:-1] -= diff
    return out
