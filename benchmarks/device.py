"""Benchmark and check: the energies on a torch device (``--device cuda``) against the CPU.

For the three-motion shirt's arms-forward ON state (half-reinforced design, slightly moved
off the skin-tight start) at each subdivision: the order-2 evaluation (energy, gradient,
exact Hessian) on the CPU and on the device, best of 5, and the largest relative
difference of the three; then the arms-forward ON and OFF states solved on both devices
from the same start (subdivision 0): energies, Newton iterations, and how far apart the
two equilibria end.  Without a CUDA device only the CPU figures are printed.

    python benchmarks/device.py [--subdivisions 0 1 2] [--device cuda]

Measured on an H200 machine on 2026-11-26 (benchmarks/README.md, "On a GPU").
"""

from __future__ import annotations

import argparse
import time

import numpy as np


def main() -> None:
    import torch
    from scaling import best_of
    from solver import designs, setup

    from kgarment.sim import SolverOptions, solve_states
    from kgarment.sim.solve import prepare_state

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--subdivisions", type=int, nargs="+", default=[0, 1, 2])
    ap.add_argument("--device", default="cuda")
    args = ap.parse_args()
    devs = ["cpu"] + ([args.device] if args.device != "cpu" and torch.cuda.is_available() else [])
    print(f"torch {torch.__version__}; devices {devs}")
    for sub in args.subdivisions:
        g, model, states = setup(sub, "paper")
        d0, _ = designs(g, model.preset.x_min)
        out = {}
        for dev in devs:
            prob = prepare_state(model, d0, states[0], SolverOptions(device=dev))
            x = torch.as_tensor(prob.initial_positions(), device=dev)
            x = x + 1e-4 * torch.sin(torch.arange(x.numel(), device=dev, dtype=x.dtype).reshape(x.shape))
            prob.evaluate(x, order=2, exact=True)  # warm the caches
            t = best_of(lambda p=prob, x=x: p.evaluate(x, order=2, exact=True), 5)
            e, gr, h = prob.evaluate(x, order=2, exact=True)
            out[dev] = (float(e), gr.detach().cpu().numpy().ravel(), np.asarray(h).ravel())
            print(f"subdivision {sub} ({g.n_faces} faces) {dev}: evaluate (order 2) {1e3 * t:.1f} ms")
        if len(devs) == 2:
            (e0, g0, h0), (e1, g1, h1) = out["cpu"], out[devs[1]]
            print(f"    {devs[1]} against cpu: energy {abs(e1 - e0) / abs(e0):.1e}, gradient "
                  f"{np.abs(g1 - g0).max() / np.abs(g0).max():.1e}, Hessian {np.abs(h1 - h0).max() / np.abs(h0).max():.1e}")
    g, model, states = setup(0, "paper")
    d0, _ = designs(g, model.preset.x_min)
    res = {}
    for dev in devs:
        t0 = time.perf_counter()
        res[dev] = solve_states(model, d0, states[:2], options=SolverOptions(device=dev))
        print(f"subdivision 0, {len(res[dev])} states solved on {dev} in {time.perf_counter() - t0:.1f} s: " + ", ".join(
            f"{r.name} {r.total_energy:.6f} J in {r.convergence.iterations} iterations" for r in res[dev]))
    if len(devs) == 2:
        for a, b in zip(res["cpu"], res[devs[1]]):
            print(f"    {a.name}: energies {abs(a.total_energy - b.total_energy) / abs(a.total_energy):.1e} apart, "
                  f"positions up to {1e3 * np.abs(np.asarray(a.x) - np.asarray(b.x)).max():.1f} mm")


if __name__ == "__main__":
    main()
