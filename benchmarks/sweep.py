"""Benchmark: ``kgarment sweep`` with 1 and with 2 Ray workers.

A 4-task sweep at subdivision 0 (the arm-flexion sleeve example, ``arm_flexion.toml``,
over two wearers' weight x the two material presets, each run stopped after
``--max-iterations`` BESO iterations, 80 by default: 40-90 s a run on one core), run from
the command line (``kgarment sweep FILE --out DIR --workers W`` in a child process: Python,
Ray's start, the tasks, the table) into a fresh temporary folder once with ``--workers 1``
and once with ``--workers 2``, ``--repeat`` times (3; the machine's speed drifts, so the
pairs alternate and the median counts).  The bodies are posed and cached before any timing.
Prints the wall times, the speed-ups, each task's own time, the load average, and whether
every sweep gave the same numbers (each task runs single-threaded, so they must); records
them in ``benchmarks/results.json`` under ``sweep`` (other entries kept).  Target on a
2-core machine: 2 workers at least 1.7x faster than 1 (the median).

    python benchmarks/sweep.py [--max-iterations N] [--repeat K] [--keep DIR] [--no-json]
"""

from __future__ import annotations

import argparse
import csv
import json
import os
import subprocess
import sys
import tempfile
import time
from datetime import date
from pathlib import Path

RESULTS = Path(__file__).resolve().parent / "results.json"
SWEEP = """# benchmarks/sweep.py: 4 tasks at subdivision 0
example = "arm_flexion"
[set]
"garment.subdivision" = 0
"design.max_iterations" = {iterations}
[grid]
"body.phenotype.weight" = [0.3, 0.7]
"materials.preset" = ["paper", "reference"]
"""


def run(sweep: Path, out: Path, workers: int) -> dict:
    load = os.getloadavg()
    t0 = time.time()
    r = subprocess.run([sys.executable, "-m", "kgarment.cli", "-q", "sweep", str(sweep), "--out", str(out),
                        "--workers", str(workers)], check=False, capture_output=True, text=True)
    wall = time.time() - t0
    if r.returncode != 0:
        raise SystemExit(f"the sweep with {workers} workers failed ({r.returncode}):\n{r.stdout[-2000:]}\n"
                         f"{r.stderr[-3000:]}")
    with open(out / "sweep.csv") as f:
        rows = list(csv.DictReader(f))
    return {"workers": workers, "wall_s": wall, "load_before": load[0], "load_after": os.getloadavg()[0],
            "task_wall_s": {r["task"]: float(r["wall_s"]) for r in rows},
            "iterations": {r["task"]: int(r["iterations"]) for r in rows},
            "rho": {r["task"]: {k: r[k] for k in r if k.startswith("rho_")} for r in rows}}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--max-iterations", type=int, default=80)
    ap.add_argument("--repeat", type=int, default=3, help="pairs of sweeps (1 worker, then 2), each into fresh folders")
    ap.add_argument("--keep", help="keep the sweep folders here (default: a temporary folder)")
    ap.add_argument("--no-json", action="store_true", help="do not record the figures in results.json")
    a = ap.parse_args()
    base = Path(a.keep) if a.keep else Path(tempfile.mkdtemp(prefix="kgarment-sweep-bench-"))
    base.mkdir(parents=True, exist_ok=True)
    sweep = base / "bench.toml"
    sweep.write_text(SWEEP.format(iterations=a.max_iterations))

    from kgarment.problem import build_body
    from kgarment.sweep import load_sweep

    t0 = time.time()
    for t in load_sweep(sweep).tasks:  # pose and cache every wearer first: neither timing includes it
        build_body(t.problem)
    print(f"bodies posed and cached in {time.time() - t0:.0f} s; load average {os.getloadavg()}")
    pairs = []
    for k in range(a.repeat):
        one = run(sweep, base / f"r{k}-w1", 1)
        two = run(sweep, base / f"r{k}-w2", 2)
        pairs.append((one, two))
        print(f"pair {k + 1}: 1 worker {one['wall_s']:.1f} s, 2 workers {two['wall_s']:.1f} s: "
              f"{one['wall_s'] / two['wall_s']:.2f}x (load average {one['load_before']:.2f} -> {one['load_after']:.2f}"
              f" -> {two['load_after']:.2f})")
        for name in one["task_wall_s"]:
            print(f"  {name:32s} {one['iterations'][name]:4d} iterations  {one['task_wall_s'][name]:6.1f} s alone, "
                  f"{two['task_wall_s'][name]:6.1f} s beside another")
    ratios = sorted(one["wall_s"] / two["wall_s"] for one, two in pairs)
    median = ratios[len(ratios) // 2]
    first = pairs[0][0]
    same = all(r["rho"] == first["rho"] and r["iterations"] == first["iterations"] for p in pairs for r in p)
    print(f"speed-up {', '.join(f'{r:.2f}x' for r in ratios)}: median {median:.2f}x (target >= 1.7x: "
          f"{'met' if median >= 1.7 else 'missed'}); the same numbers from every sweep: {'yes' if same else 'NO'}")
    print(f"sweep folders in {base}")
    if a.no_json:
        return
    doc = json.loads(RESULTS.read_text()) if RESULTS.is_file() else {}
    doc.setdefault("sweep", {})["4 tasks, subdivision 0"] = {
        "date": date.today().isoformat(), "problem": "arm_flexion, weight 0.3/0.7 x preset paper/reference",
        "max_iterations": a.max_iterations, "cores": os.cpu_count(), "speedup_median": median,
        "speedups": ratios, "same_results": same,
        "pairs": [{"wall_s_1_worker": one["wall_s"], "wall_s_2_workers": two["wall_s"],
                   "load_average": [one["load_before"], one["load_after"], two["load_after"]],
                   "task_wall_s_1_worker": one["task_wall_s"], "task_wall_s_2_workers": two["task_wall_s"]}
                  for one, two in pairs],
        "iterations": first["iterations"]}
    RESULTS.write_text(json.dumps(doc, indent=1) + "\n")
    print(f"recorded in {RESULTS} under sweep")


if __name__ == "__main__":
    main()
