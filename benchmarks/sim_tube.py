"""Simulator benchmark: a ~10k-face tube garment with 3 clutches on a cylinder body.

3 motions (stretch + twist) x 2 activation patterns (all ON, all OFF) = 6 states.
A cold solve with a banded design, then the timed part: warm-started re-solve after a
BESO-like 1.5% design change (faces on the band boundaries flipped), Newton vs L-BFGS.

    .venv/bin/python benchmarks/sim_tube.py [--preset paper|reference] [--lbfgs-states N]
"""

from __future__ import annotations

import argparse
import logging
import time

import numpy as np

from kgarment.sim import SimState, SolverOptions, build_model, solve_states
from kgarment.sim.synthetic import Tube


def banded_design(tube: Tube, x_min: float) -> np.ndarray:
    """Three helical reinforced bands (~30% of the area)."""
    c = tube.vertices[tube.faces].mean(1)
    th = np.arctan2(c[:, 1], c[:, 0])
    s = (c[:, 2] - tube.z0) / (tube.z1 - tube.z0)
    phase = np.mod(3 * (th + 2.0 * s) / (2 * np.pi), 1.0)
    return np.where(phase < 0.3, 1.0, x_min)


def beso_change(d: np.ndarray, density: np.ndarray, faces: np.ndarray, frac: float) -> np.ndarray:
    """A BESO-like step: among faces touching the other material, add the ``frac/2`` soft
    faces of highest energy density and remove the ``frac/2`` reinforced faces of lowest."""
    nv = faces.max() + 1
    has_hard, has_soft = np.zeros(nv, bool), np.zeros(nv, bool)
    hard = d == 1.0
    has_hard[faces[hard].ravel()] = True
    has_soft[faces[~hard].ravel()] = True
    n = round(frac * len(d) / 2)
    out = d.copy()
    cand_add = np.nonzero(~hard & has_hard[faces].any(1))[0]
    cand_rem = np.nonzero(hard & has_soft[faces].any(1))[0]
    out[cand_add[np.argsort(-density[cand_add])[:n]]] = 1.0
    out[cand_rem[np.argsort(density[cand_rem])[:n]]] = d.min()
    return out


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--preset", default="paper")
    ap.add_argument("--lbfgs-states", type=int, default=1)
    ap.add_argument("--lbfgs-iters", type=int, default=3000)
    ap.add_argument("--n-theta", type=int, default=90)
    ap.add_argument("--n-z", type=int, default=56)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("-v", action="store_true")
    a = ap.parse_args()
    logging.basicConfig(level=logging.INFO if a.v else logging.WARNING, format="%(message)s")

    tube = Tube(0.06, 0.0, 0.30, a.n_theta, a.n_z)
    clutches = [tube.clutch(f"c{k}", 2 * np.pi * k / 3 + 0.4, 0.075, 0.225, 0.01, 30, prestrain=0.98)
                for k in range(3)]
    t = time.perf_counter()
    model = build_model(tube.vertices, tube.faces, clutches, preset=a.preset)
    print(f"model: {model.n_faces} garment faces, {model.n_vertices} vertices, "
          f"{len(model.elements.area)} elements, mean edge {model.mean_edge * 1e3:.2f} mm, "
          f"build {time.perf_counter() - t:.2f} s")
    motions = [tube.motion("stretch", 0.12, 0.0, body_res=(64, 40)),
               tube.motion("twist", 0.05, 0.35, body_res=(64, 40)),
               tube.motion("twist_back", 0.08, -0.25, body_res=(64, 40))]
    states = [SimState.create(m, [g] * 3) for m in motions for g in (1.0, 0.0)]
    d0 = banded_design(tube, model.preset.x_min)
    print(f"design: {np.mean(d0 == 1):.1%} reinforced, preset {a.preset}")

    t = time.perf_counter()
    opts = SolverOptions(workers=a.workers)
    cold = solve_states(model, d0, states, options=opts)
    print(f"cold Newton solve: {time.perf_counter() - t:.2f} s  "
          + " ".join(f"{r.name}:{r.convergence.iterations}" for r in cold))

    dens = np.sum([r.garment_density for r in cold], axis=0)
    d1 = beso_change(d0, dens, tube.faces, 0.015)
    print(f"design change: {np.sum(d1 != d0)} faces ({np.mean(d1 != d0):.2%})")
    t = time.perf_counter()
    warm = solve_states(model, d1, states, warm_start=cold, options=opts)
    t_newton = time.perf_counter() - t
    print(f"WARM Newton, 6 states, {a.workers} worker(s): {t_newton:.2f} s wall  "
          + " ".join(f"{r.name}:{r.convergence.iterations}it/{r.convergence.wall_time:.2f}s" for r in warm))
    assert all(r.converged for r in warm)

    if a.lbfgs_states:
        sub = states[: a.lbfgs_states]
        t = time.perf_counter()
        lb = solve_states(model, d1, sub, warm_start=cold[: len(sub)],
                          options=SolverOptions(method="lbfgs", lbfgs_max_iter=a.lbfgs_iters))
        t_lb = time.perf_counter() - t
        t_nw = sum(r.convergence.wall_time for r in warm[: len(sub)])
        for r, w in zip(lb, warm):
            de = abs(r.total_energy - w.total_energy) / abs(w.total_energy)
            dx = np.abs(r.x - w.x).max()
            print(f"L-BFGS {r.name}: {r.convergence.iterations} it, {r.convergence.wall_time:.1f} s, "
                  f"converged {r.converged} (residual {r.convergence.residual:.2g}), "
                  f"rel energy diff {de:.2e}, max |dx| {dx * 1e3:.3g} mm")
        print(f"L-BFGS / Newton time on {len(sub)} state(s): {t_lb:.1f} s / {t_nw:.2f} s "
              f"= {t_lb / t_nw:.0f}x{'' if all(r.converged for r in lb) else ' (L-BFGS unconverged: lower bound)'}")


if __name__ == "__main__":
    main()
