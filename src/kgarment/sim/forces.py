"""Forces an equilibrium transmits: the tension each clutch carries.

A clutch strip is held on the garment by its 6 anchor springs (3 at each end; its other
centre-line vertices are tied only weakly, ``sim.model``).  The force the garment exerts
on the strip through the anchors of one end is what a load cell put in place of the
clutch measures (the paper's physical test, docs/method/index.md, "Judging a design as a garment").  With ``F_A``, ``F_B``
(N) those forces at the start and the end, and ``u_A``, ``u_B`` the strip's directions at
its ends (unit, pointing from the start towards the end along the deformed centre
line), a strip in tension is pulled outwards at both ends, so its tension is::

    T = (-F_A . u_A + F_B . u_B) / 2      (N; negative: compression)

The two halves differ only by the weak ties and contact along the strip.  A cable clutch
(``sim.cable``) pulls on the same anchors, so its tension is measured the same way.
"""

from __future__ import annotations

import numpy as np
import torch

from kgarment.sim.model import SimModel, SimState
from kgarment.sim.options import SolverOptions
from kgarment.sim.serial import prepare_state
from kgarment.sim.springs import springs


def clutch_tensions(model: SimModel, design: np.ndarray, state: SimState, x: np.ndarray,
                    options: SolverOptions | None = None) -> np.ndarray:
    """(K,) tension in newtons carried along each clutch at positions ``x`` (N, 3) m
    (an equilibrium of ``state`` for ``design`` (m,)); see the module docstring."""
    if model.n_clutches == 0:
        return np.zeros(0)
    prob = prepare_state(model, design, state, options)
    xt = torch.as_tensor(np.asarray(x, dtype=np.float64), device=prob.device)
    _, grad = springs(xt, prob.s_index, prob.s_coef, prob.s_target, prob.s_k, order=1)
    force = -grad.cpu().numpy()  # on each vertex, from the springs
    out = np.empty(model.n_clutches)
    for k, c in enumerate(model.clutches):
        off = model.vertex_offsets[k + 1]
        xc = np.asarray(x)[off: model.vertex_offsets[k + 2]]
        line = xc[np.asarray(c.centerline)]
        u_a = _unit(line[1] - line[0])
        u_b = _unit(line[-1] - line[-2])
        a = np.asarray(c.anchors)
        f_a = force[off + a[:3]].sum(axis=0)
        f_b = force[off + a[3:]].sum(axis=0)
        out[k] = 0.5 * (-(f_a @ u_a) + f_b @ u_b)
    return out


def _unit(v: np.ndarray) -> np.ndarray:
    return v / max(float(np.linalg.norm(v)), 1e-300)
