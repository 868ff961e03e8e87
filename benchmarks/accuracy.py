"""Benchmark: how accurate is an equilibrium at a given solver tolerance, and how unique is it?

The three-motion shirt's 6 states (benchmarks/solver.py: a half-reinforced design, then
1.5% of its faces flipped), warm-started from equilibria of the first design:

* a reference solve of the changed design to ``--ref-tol`` (default 1e-7);
* warm solves to tolerances 1e-2 .. 1e-5: Newton iterations, seconds, and the error of
  the total energy and of the per-face energy densities (area-weighted L1, relative)
  against the reference;
* the *spread*: solves to 1e-5 with other solver settings (fewer contact passes, more
  shift increases, no extrapolation, the adaptive Hessian), every one converged, and the
  same distances to the reference. A garment without bending stiffness, sliding on a
  frictionless body, has many nearly equal equilibria (wrinkles and slack cloth can sit in
  slightly different places); which one a solve reaches depends on its path. Densities
  more accurate than this spread are not physically meaningful.

    python benchmarks/accuracy.py [--subdivision 0] [--states 0 1 2 3 4 5] [--json F]
"""

from __future__ import annotations

import argparse
import logging
import sys
import time
from pathlib import Path

import numpy as np
import torch

sys.path.insert(0, str(Path(__file__).parent))

TOLERANCES = (1e-2, 1e-3, 1e-4, 1e-5)
VARIANTS = {"1 contact pass": {"contact_passes": 1}, "6 shift increases": {"max_shifts": 6},
            "no extrapolation": {"extrapolate": False}, "adaptive Hessian": {"hessian": "adaptive"}}


def main() -> None:
    from solver import designs, save_json, setup

    from kgarment.sim import SolverOptions, solve_states
    from kgarment.sim.newton import newton_solve
    from kgarment.sim.solve import prepare_state

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--subdivision", type=int, default=0)
    ap.add_argument("--states", type=int, nargs="+", default=list(range(6)))
    ap.add_argument("--ref-tol", type=float, default=1e-7)
    ap.add_argument("--json", help="merge the figures into this JSON file (e.g. benchmarks/results.json)")
    args = ap.parse_args()
    logging.basicConfig(level=logging.WARNING)
    g, model, states = setup(args.subdivision, "paper")
    d0, d1 = designs(g, model.preset.x_min)
    m = model.n_faces
    area = model.elements.area[:m]
    start = solve_states(model, d0, states, options=SolverOptions(max_iter=3000))
    print(f"subdivision {args.subdivision}: {m} garment faces; warm starts from equilibria of the first design "
          f"({'all' if all(r.converged for r in start) else 'NOT all'} converged)")

    def solve(si, **kw):
        prob = prepare_state(model, d1, states[si])
        x, rec = newton_solve(prob, start[si].x, SolverOptions(**{"max_iter": 3000, **kw}))
        terms, e = prob.terms(torch.as_tensor(x))
        return rec, sum(terms.values()), e[:m] / area

    rows = {f"tol {t:g}": [] for t in TOLERANCES} | {k: [] for k in VARIANTS}
    for si in args.states:
        t0 = time.perf_counter()
        ref, e_ref, d_ref = solve(si, tol=args.ref_tol)
        print(f"  {states[si].name}: reference {ref.iterations} iterations to {ref.residual:.1e} "
              f"({time.perf_counter() - t0:.1f} s)")

        def dist(rec, e, d, e_ref=e_ref, d_ref=d_ref):
            return {"iterations": rec.iterations, "seconds": rec.wall_time, "converged": rec.converged,
                    "energy_error": abs(e - e_ref) / abs(e_ref),
                    "density_l1": float(np.abs(d - d_ref) @ area / (np.abs(d_ref) @ area))}

        for t in TOLERANCES:
            rows[f"tol {t:g}"].append(dist(*solve(si, tol=t)))
        for k, kw in VARIANTS.items():
            rows[k].append(dist(*solve(si, tol=1e-5, **kw)))
    print(f"{'solve':>20s} {'iterations':>10s} {'seconds':>8s} {'energy error':>13s} {'density L1 error':>17s}"
          "   (sums over states; errors: median / max over states)")
    figures = {}
    for k, rs in rows.items():
        it = sum(r["iterations"] for r in rs)
        sec = sum(r["seconds"] for r in rs)
        ee = [r["energy_error"] for r in rs]
        dd = [r["density_l1"] for r in rs]
        ok = "" if all(r["converged"] for r in rs) else "  (not all converged)"
        print(f"{k:>20s} {it:10d} {sec:8.1f} {np.median(ee):6.1e}/{max(ee):6.1e} {np.median(dd):8.1e}/{max(dd):7.1e}{ok}")
        figures[k] = {"iterations": it, "seconds": sec, "energy_error_median": float(np.median(ee)),
                      "energy_error_max": max(ee), "density_l1_median": float(np.median(dd)),
                      "density_l1_max": max(dd), "converged": not ok}
    if args.json:
        save_json(args.json, f"accuracy subdivision {args.subdivision}", figures)


if __name__ == "__main__":
    main()
