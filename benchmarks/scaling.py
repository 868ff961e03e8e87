"""Benchmark: how one Newton iteration's cost and memory grow with the garment's subdivision.

For the three-motion shirt (three clutches, arms-forward ON state, half-reinforced design)
at subdivision 0, 1, 2: unknowns, non-zeros of the Hessian and of its Cholesky factor, the
time of one energy + gradient + Hessian evaluation, one numerical factorisation and one
solve with each sparse Cholesky of ``--factorizations`` (default: MKL PARDISO when
installed, CHOLMOD simplicial and supernodal), and the process's peak memory after each
size.  A whole design run repeats such
iterations (about 25-60 per state per BESO iteration, see benchmarks/README.md), so these
figures tell how a run at subdivision 2 would scale without running one.

    python benchmarks/scaling.py [--subdivisions 0 1 2] [--repeat 3] [--factorizations pardiso simplicial]
                                 [--json benchmarks/results.json]
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

    from kgarment.sim import SolverOptions, pardiso
    from kgarment.sim.assembly import SparseCholesky
    from kgarment.sim.solve import prepare_state

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--subdivisions", type=int, nargs="+", default=[0, 1, 2])
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--factorizations", nargs="+", choices=("pardiso", "simplicial", "supernodal"),
                    default=[f for f in ("pardiso", "simplicial", "supernodal") if f != "pardiso" or pardiso.available()])
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
        rhs = np.ones(model.pattern.n_dof)
        row = {"faces": g.n_faces, "unknowns": model.pattern.n_dof, "hessian_nnz": model.pattern.nnz,
               "setup_s": t_setup, "evaluate_ms": 1e3 * t_eval}
        parts = []
        for fac in args.factorizations:
            chol = SparseCholesky(model.pattern, mode=fac)
            t_fact = best_of(lambda c=chol, h=H: c.factorize(h), args.repeat)
            t_solve = best_of(lambda c=chol, b=rhs: c.solve(b), args.repeat)
            nnz_l = chol._pd.nnz_factor if chol.backend == "pardiso" else chol._factor.L().nnz
            row.update({f"factor_nnz {fac}": int(nnz_l), f"factorize_ms {fac}": 1e3 * t_fact,
                        f"solve_ms {fac}": 1e3 * t_solve,
                        f"newton_iteration_ms {fac}": 1e3 * (t_eval + t_fact + t_solve)})
            parts.append(f"{fac}: factor nnz {nnz_l:,}, factorise {1e3 * t_fact:.0f} ms, solve {1e3 * t_solve:.1f} ms "
                         f"(one Newton iteration ~{1e3 * (t_eval + t_fact + t_solve):.0f} ms)")
            del chol
        row["peak_rss_mb"] = rss = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
        figures[f"subdivision {sub}"] = row
        print(f"subdivision {sub}: {g.n_faces} faces, {row['unknowns']} unknowns; evaluate {row['evaluate_ms']:.0f} ms; "
              f"set-up {t_setup:.0f} s, peak RSS {rss:.0f} MB")
        for line in parts:
            print("    " + line)
    if args.json:
        save_json(args.json, "scaling", figures)


if __name__ == "__main__":
    main()
