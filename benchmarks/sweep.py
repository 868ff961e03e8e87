"""Benchmark: ``kgarment sweep`` with 1 and with 2 Ray workers.

A 4-task sweep at subdivision 0 (the arm-flexion sleeve example, ``arm_flexion.toml``,
over two wearers' weight x the two material presets, each run stopped after
``--max-iterations`` BESO iterations, 80 by default: 40-90 s a run on one core), run from
the command line (``kgarment sweep FILE --out DIR --workers W`` in a child process: Python,
Ray's start, the tasks, the table) into a fresh temporary folder once with ``--workers 1``
and once with ``--workers 2``, ``--repeat`` times (3; the machine's speed drifts, so the
pairs alternate and the median counts; a pair during which other processes took more than
5% of the machine's CPU is reported and not counted).  The bodies are posed and cached before any timing.
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
import statistics
import subprocess
import sys
import tempfile
import threading
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


TICK = os.sysconf("SC_CLK_TCK")


def _procs() -> dict:
    """{pid: (ppid, CPU seconds, start in seconds since boot)} of every process (Linux /proc)."""
    out = {}
    for pid in filter(str.isdigit, os.listdir("/proc")):
        try:
            with open(f"/proc/{pid}/stat") as f:
                fields = f.read().rsplit(")", 1)[1].split()
        except OSError:
            continue
        out[int(pid)] = (int(fields[1]), (int(fields[11]) + int(fields[12])) / TICK, int(fields[19]) / TICK)
    return out


class OtherCPU:
    """CPU seconds spent by processes other than this one and its descendants while the
    block runs (sampled every second): another job on the machine shows here."""

    def __enter__(self):
        self.total, self.stop = 0.0, threading.Event()
        self.thread = threading.Thread(target=self._sample, daemon=True)
        self.thread.start()
        return self

    def _sample(self) -> None:
        with open("/proc/uptime") as f:
            last_t = float(f.read().split()[0])
        prev = _procs()
        while not self.stop.wait(1.0):
            now = _procs()
            with open("/proc/uptime") as f:
                t = float(f.read().split()[0])
            ours = {os.getpid()}
            for _ in range(8):  # descendants (Ray's processes are grandchildren and deeper)
                ours |= {p for p, (pp, _, _) in now.items() if pp in ours}
            for p, (_, cpu, start) in now.items():
                if p in ours:
                    continue
                before = prev[p][1] if p in prev else (0.0 if start >= last_t else cpu)
                self.total += max(0.0, cpu - before)
            prev, last_t = now, t

    def __exit__(self, *exc):
        self.stop.set()
        self.thread.join()


def run(sweep: Path, out: Path, workers: int) -> dict:
    load = os.getloadavg()
    t0 = time.time()
    with OtherCPU() as other:
        r = subprocess.run([sys.executable, "-m", "kgarment.cli", "-q", "sweep", str(sweep), "--out", str(out),
                            "--workers", str(workers)], check=False, capture_output=True, text=True)
    wall = time.time() - t0
    if r.returncode != 0:
        raise SystemExit(f"the sweep with {workers} workers failed ({r.returncode}):\n{r.stdout[-2000:]}\n"
                         f"{r.stderr[-3000:]}")
    with open(out / "sweep.csv") as f:
        rows = list(csv.DictReader(f))
    return {"workers": workers, "wall_s": wall, "load_before": load[0], "load_after": os.getloadavg()[0],
            "other_cpu_s": other.total,
            "task_wall_s": {r["task"]: float(r["wall_s"]) for r in rows},
            "iterations": {r["task"]: int(r["iterations"]) for r in rows},
            "rho": {r["task"]: {k: r[k] for k in r if k.startswith("rho_")} for r in rows}}


def disturbed(one: dict, two: dict) -> bool:
    """Whether other processes took more than 5% of the machine's CPU during either sweep."""
    cores = os.cpu_count() or 1
    return any(r["other_cpu_s"] > 0.05 * cores * r["wall_s"] for r in (one, two))


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
              f" -> {two['load_after']:.2f}; other processes' CPU {one['other_cpu_s']:.0f} s and "
              f"{two['other_cpu_s']:.0f} s" + (": DISTURBED, not counted)" if disturbed(one, two) else ")"))
        for name in one["task_wall_s"]:
            print(f"  {name:32s} {one['iterations'][name]:4d} iterations  {one['task_wall_s'][name]:6.1f} s alone, "
                  f"{two['task_wall_s'][name]:6.1f} s beside another")
    ratios = sorted(one["wall_s"] / two["wall_s"] for one, two in pairs if not disturbed(one, two))
    median = statistics.median(ratios) if ratios else float("nan")
    first = pairs[0][0]
    same = all(r["rho"] == first["rho"] and r["iterations"] == first["iterations"] for p in pairs for r in p)
    print(f"speed-up of the undisturbed pairs {', '.join(f'{r:.2f}x' for r in ratios) or 'none'}: median "
          f"{median:.2f}x (target >= 1.7x: {'met' if median >= 1.7 else 'missed'}); the same numbers from every "
          f"sweep: {'yes' if same else 'NO'}")
    print(f"sweep folders in {base}")
    if a.no_json:
        return
    doc = json.loads(RESULTS.read_text()) if RESULTS.is_file() else {}
    doc.setdefault("sweep", {})["4 tasks, subdivision 0"] = {
        "date": date.today().isoformat(), "problem": "arm_flexion, weight 0.3/0.7 x preset paper/reference",
        "max_iterations": a.max_iterations, "cores": os.cpu_count(), "speedup_median": median,
        "speedups": ratios, "same_results": same,
        "pairs": [{"wall_s_1_worker": one["wall_s"], "wall_s_2_workers": two["wall_s"],
                   "other_cpu_s": [one["other_cpu_s"], two["other_cpu_s"]], "disturbed": disturbed(one, two),
                   "load_average": [one["load_before"], one["load_after"], two["load_after"]],
                   "task_wall_s_1_worker": one["task_wall_s"], "task_wall_s_2_workers": two["task_wall_s"]}
                  for one, two in pairs],
        "iterations": first["iterations"]}
    RESULTS.write_text(json.dumps(doc, indent=1) + "\n")
    print(f"recorded in {RESULTS} under sweep")


if __name__ == "__main__":
    main()
