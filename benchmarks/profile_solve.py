"""Benchmark: where the time of a warm design-loop solve goes, at subdivision 0, 1 or 2.

The three-motion shirt's 6 states (3 motions x ON/OFF) for a half-reinforced design are
solved cold, then 1.5% of the faces flip (a BESO step) and the 6 states are solved again
warm, in one process, at ``--tol`` (default 1e-3, the design loop's tolerance at the target
area).  The warm solves are timed by part: the Newton direction's factorisations (those
that succeed, and the shifts that fail), the contact-anticipation updates (Woodbury or a
refactorisation), the triangular solves, the energy evaluations (with derivatives, and
the line search's values) and inside them the contact neighbour lists; the rest is
Newton's own bookkeeping.  Issue #24 item 2 asks for this profile before attacking the
largest share.

    python benchmarks/profile_solve.py [--subdivision 2] [--tol 1e-3] [--json benchmarks/results.json]
"""

from __future__ import annotations

import argparse
import functools
import logging
import time
from collections import defaultdict

PARTS = ("factorise", "factorise (failed shift)", "anticipation update", "solve", "evaluate (with derivatives)",
         "evaluate (line search)", "of which neighbour lists")


def instrument(timers: dict, counts: dict) -> None:
    """Wrap the solver's parts with timers (this process only)."""
    from kgarment.sim import energy
    from kgarment.sim.assembly import NotPositiveDefinite, SparseCholesky

    def timed(owner, name, part_of):
        fn = getattr(owner, name)

        @functools.wraps(fn)
        def wrapper(*a, **k):
            t0 = time.perf_counter()
            failed = False
            try:
                return fn(*a, **k)
            except NotPositiveDefinite:
                failed = True
                raise
            finally:
                part = part_of(a, k, failed)
                if part:
                    timers[part] += time.perf_counter() - t0
                    counts[part] += 1
        setattr(owner, name, wrapper)

    state = {"in_outer": False}

    def outer(owner, name):
        fn = getattr(owner, name)

        @functools.wraps(fn)
        def wrapper(*a, **k):
            t0 = time.perf_counter()
            state["in_outer"] = True
            try:
                return fn(*a, **k)
            finally:
                state["in_outer"] = False
                timers["anticipation update"] += time.perf_counter() - t0
                counts["anticipation update"] += 1
        setattr(owner, name, wrapper)

    timed(SparseCholesky, "factorize", lambda a, k, failed: "factorise (failed shift)" if failed else "factorise")
    outer(SparseCholesky, "add_outer")
    timed(SparseCholesky, "solve", lambda a, k, failed: None if state["in_outer"] else "solve")
    timed(energy.StateProblem, "evaluate",
          lambda a, k, failed: "evaluate (with derivatives)" if k.get("order", a[2] if len(a) > 2 else 0) > 0
          else "evaluate (line search)")
    timed(energy.StateProblem, "_contact_args", lambda a, k, failed: "of which neighbour lists")


def main() -> None:
    import torch
    from solver import designs, save_json, setup

    from kgarment.sim import SolverOptions, solve_states

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--subdivision", type=int, default=2)
    ap.add_argument("--tol", type=float, default=1e-3)
    ap.add_argument("--lag-contact", action=argparse.BooleanOptionalAction, default=None,
                    help="the last step's anticipated contact set in the next factorisation (SolverOptions.lag_contact)")
    ap.add_argument("--json", help="merge the figures into this JSON file (e.g. benchmarks/results.json)")
    args = ap.parse_args()
    logging.basicConfig(level=logging.WARNING)
    torch.set_num_threads(1)
    g, model, states = setup(args.subdivision, "paper")
    d0, d1 = designs(g, model.preset.x_min)
    opts = SolverOptions(tol=args.tol, workers=1, threads=1, lag_contact=args.lag_contact)
    t0 = time.perf_counter()
    cold = solve_states(model, d0, states, options=opts)
    t_cold = time.perf_counter() - t0
    timers, counts = defaultdict(float), defaultdict(int)
    instrument(timers, counts)
    t0 = time.perf_counter()
    warm = solve_states(model, d1, states, warm_start=cold, options=opts)
    total = time.perf_counter() - t0
    newton = sum(r.convergence.iterations for r in warm)
    rest = total - sum(timers[p] for p in PARTS if p != "of which neighbour lists")
    print(f"subdivision {args.subdivision}: {g.n_faces} faces, {model.pattern.n_dof} unknowns; 6 states cold "
          f"{t_cold:.1f} s; warm after a 1.5% design change at tol {args.tol:g}: {total:.1f} s, {newton} Newton "
          f"iterations ({1e3 * total / max(newton, 1):.0f} ms each), {sum(r.converged for r in warm)}/6 converged; "
          f"lag_contact {args.lag_contact}; cold Newton iterations {sum(r.convergence.iterations for r in cold)}; "
          f"energies {' '.join(f'{r.total_energy:.6g}' for r in warm)}")
    row = {"faces": int(g.n_faces), "tol": args.tol, "warm_s": total, "newton_iterations": newton,
           "ms_per_newton_iteration": 1e3 * total / max(newton, 1)}
    for p in PARTS + ("rest",):
        sec, n = (rest, 0) if p == "rest" else (timers[p], counts[p])
        per = f", {n} calls, {1e3 * sec / n:.1f} ms each" if n else ""
        print(f"    {p:30s} {sec:7.2f} s  {100 * sec / total:5.1f}%{per}")
        row[f"{p} s"] = sec
        row[f"{p} calls"] = n
    if args.json:
        save_json(args.json, "profile", {f"subdivision {args.subdivision}": row})


if __name__ == "__main__":
    main()
