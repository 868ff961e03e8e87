"""Benchmark: how one Newton iteration's cost and memory grow with the garment's subdivision.

For the three-motion shirt (three clutches, arms-forward ON state, half-reinforced design)
at subdivision 0, 1, 2: unknowns, non-zeros of the Hessian and of its Cholesky factor, the
time of one energy + gradient + Hessian evaluation, one CHOLMOD factorisation and one
solve, and the process's peak memory after each size.  A whole design run repeats such
iterations (about 25-60 per state per BESO iteration, see benchmarks/README.md), so these
figures tell how a run at subdivision 2 would scale without running one.

    python benchmarks/scaling.py [--subdivisions 0 1 2] [--repeat 3] [--json benchmarks/results.json]
"""

from __future__ import annotations

import argparse
import logging
import resource
import time

import numpy as np


def best_of(fn, repeat: int) -> float:
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return min(times)


def main() -> None:
    import torch
    from solver import designs, save_json, setup

    from kgarment.sim import SolverOptions
    from kgarment.sim.assembly import SparseCholesky
    from kgarment.sim.solve import prepare_state

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--subdivisions", type=int, nargs="+", default=[0, 1, 2])
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--json", help="merge the figures into this JSON file (e.g. benchmarks/results.json)")
    args = ap.parse_args()
    logging.basicConfig(level=logging.WARNING)
    torch.set_num_threads(1)
    figures = {}
    for sub in args.subdivisions:
        t0 = time.perf_counter()
        g, model, states = setup(sub, "paper")
        t_setup = time.perf_counter() - t0
        d0, _ = designs(g, model.preset.x_min)
        prob = prepare_state(model, d0, states[0], SolverOptions())
        x = torch.as_tensor(prob.initial_positions())
        prob.evaluate(x, order=2, exact=True)  # compile / warm the caches
        t_eval = best_of(lambda p=prob, x=x: p.evaluate(x, order=2, exact=True), args.repeat)
        _, _, H = prob.evaluate(x, order=2)
        H = H.copy()
        H[model.pattern.diag_pos] += 1e-2 * prob.dof_stiffness + 1e-6 * model.preset.cloth_stiffness
        chol = SparseCholesky(model.pattern)
        t_fact = best_of(lambda c=chol, h=H: c.factorize(h), args.repeat)
        rhs = np.ones(model.pattern.n_dof)
        t_solve = best_of(lambda c=chol, b=rhs: c.solve(b), args.repeat)
        nnz_l = chol._factor.L().nnz if chol.backend == "cholmod" else float("nan")
        rss = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
        row = {"faces": g.n_faces, "unknowns": model.pattern.n_dof, "hessian_nnz": model.pattern.nnz,
               "factor_nnz": int(nnz_l), "setup_s": t_setup, "evaluate_ms": 1e3 * t_eval,
               "factorize_ms": 1e3 * t_fact, "solve_ms": 1e3 * t_solve,
               "newton_iteration_ms": 1e3 * (t_eval + t_fact + t_solve), "peak_rss_mb": rss}
        figures[f"subdivision {sub}"] = row
        print(f"subdivision {sub}: {g.n_faces} faces, {row['unknowns']} unknowns, factor nnz {row['factor_nnz']:,}; "
              f"evaluate {row['evaluate_ms']:.0f} ms, factorise {row['factorize_ms']:.0f} ms, "
              f"solve {row['solve_ms']:.1f} ms (one Newton iteration ~{row['newton_iteration_ms']:.0f} ms); "
              f"set-up {t_setup:.0f} s, peak RSS {rss:.0f} MB")
    if args.json:
        save_json(args.json, "scaling", figures)


if __name__ == "__main__":
    main()
