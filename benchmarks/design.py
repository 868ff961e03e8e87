"""Benchmark: the whole three-motion shirt design at subdivision 0, 1 (and 2).

Runs `kgarment design examples/shirt_three_motions.toml --subdivision S` in a child process
per resolution and prints wall time (the final design's evaluation included), iterations,
peak memory (RSS, the largest of the main and worker processes), the last iteration's rho
per motion and state, and the final design's parts, clutch ends on reinforcement and
clutch loads; the wall time split into the design loop (until the last iteration's
metrics) and the final evaluation with the renders. Targets on a 2-core machine:
subdivision 0 in at most 5 minutes, subdivision 1 in at most 30 minutes, subdivision 2
(coarse-to-fine, ``--refine``) in at most 30 minutes. ``--refine`` designs coarse-to-fine (the evolution at
subdivision 0, ``kgarment design --refine``; figures under ``subdivision S refined``; the
final evaluation's rho ON / OFF per motion is printed for both, to compare them).

    python benchmarks/design.py [--subdivisions 0 1] [--refine] [--max-iterations N] [--keep DIR]
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from kgarment.problem import example_path

ROOT = Path(__file__).resolve().parents[1]
CHILD = """
import resource, sys
from kgarment.cli import main
rc = main(sys.argv[1:])
from kgarment.sim import parallel
for pool in parallel._POOLS.values():  # wait for the workers so that their peak counts
    pool.shutdown(wait=True)
print("PEAK_RSS_KB", max(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss,
                         resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss))
sys.exit(rc)
"""


def run(sub: int, out: Path, max_iterations: int | None, refine: bool = False) -> dict:
    args = [sys.executable, "-c", CHILD, "-q", "design", str(example_path("shirt_three_motions")),
            "--subdivision", str(sub), "--out", str(out), "--force"] + (["--refine"] if refine else [])
    if max_iterations:
        args += ["--max-iterations", str(max_iterations)]
    t0 = time.time()
    r = subprocess.run(args, capture_output=True, text=True)
    wall = time.time() - t0
    if r.returncode != 0:
        raise SystemExit(f"subdivision {sub} failed:\n{r.stderr[-3000:]}")
    peak = int(next(line.split()[1] for line in r.stdout.splitlines() if line.startswith("PEAK_RSS_KB")))
    loop = (out / "metrics.json").stat().st_mtime - t0  # written after the last iteration
    rows = json.loads((out / "metrics.json").read_text())
    last = rows[-1]
    coarse = [json.loads((f / "metrics.json").read_text()) for f in sorted(out.glob("level*"))]
    return {"subdivision": sub, "wall_s": wall, "loop_s": loop, "evaluation_s": wall - loop,
            "iterations": len(rows), "peak_rss_mb": peak / 1024,
            "coarse_iterations": [len(c) for c in coarse],
            "area": last["area"], "islands": last["islands"],
            "newton_iterations": sum(r["newton_iterations"] for r in rows + [x for c in coarse for x in c]),
            "unconverged_iterations": sum(1 for r in rows if r["unconverged_states"]),
            "rho": {k[4:-1]: v for k, v in last.items() if k.startswith("rho[")},
            "solver_s": sum(r["seconds"] for r in rows), **final_evaluation(out)}


def final_evaluation(out: Path) -> dict:
    """The final design's evaluation (final/evaluation.json): parts counting clutch links,
    clutch ends on reinforcement, clutches loaded in at least one motion, and the clutch
    loads (share / tension per motion)."""
    path = out / "final" / "evaluation.json"
    if not path.is_file():
        return {}
    ev = json.loads(path.read_text())
    names = list(dict.fromkeys(c["clutch"] for c in ev.get("clutches", [])))
    loaded = [n for n in names if any(c["loaded"] for c in ev["clutches"] if c["clutch"] == n)]
    rho = {f"{m}:{s}": v for m, states in ev["rho"].items() for s, v in states.items()} \
        if isinstance(ev.get("rho"), dict) else {}
    return {"final_rho": rho, "parts": ev["islands_with_clutches"], "clutch_ends_supported": ev["clutch_ends_supported"],
            "clutch_ends": ev["clutch_ends"], "clutches_loaded": len(loaded), "clutches": len(names),
            "loads": {f"{c['motion']}:{c['clutch']}": f"{c['share']:.2f} / {c['tension_N']:.0f} N"
                      for c in ev.get("clutches", [])}}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--subdivisions", type=int, nargs="+", default=[0, 1])
    ap.add_argument("--max-iterations", type=int)
    ap.add_argument("--keep", help="keep the run folders here")
    ap.add_argument("--refine", action="store_true", help="coarse-to-fine: evolve at subdivision 0")
    ap.add_argument("--json", help="merge the figures into this JSON file (e.g. benchmarks/results.json)")
    args = ap.parse_args()
    figures = {}
    base = Path(args.keep) if args.keep else Path(tempfile.mkdtemp(prefix="kgarment-bench-"))
    targets = {0: 300.0, 1: 1800.0, 2: 1800.0}
    for sub in args.subdivisions:
        name = f"subdivision {sub}" + (" refined" if args.refine else "")
        res = run(sub, base / f"sub{sub}{'-refined' if args.refine else ''}", args.max_iterations, args.refine)
        t = targets.get(sub)
        ratio = f" ({res['wall_s'] / t:.2f} x the {t / 60:.0f}-minute target)" if t else ""
        print(f"{name}: {res['wall_s']:.0f} s{ratio} (design loop {res['loop_s']:.0f} s, final evaluation and "
              f"renders {res['evaluation_s']:.0f} s), {res['iterations']} iterations "
              f"(+ {res['coarse_iterations']} coarse), "
              f"peak RSS {res['peak_rss_mb']:.0f} MB, final area {100 * res['area']:.1f}%, islands {res['islands']}, "
              f"{res['newton_iterations']} Newton iterations ({res['unconverged_iterations']} iterations with an "
              f"unconverged state)")
        for k, v in res["rho"].items():
            print(f"    rho {k:22s} {v:.3f}" + (f"  (final evaluation {res['final_rho'][k]:.3f})"
                                                 if k in res.get("final_rho", {}) else ""))
        if "parts" in res:
            print(f"    final design: {res['parts']} part(s) counting clutch links, clutch ends on reinforcement "
                  f"{res['clutch_ends_supported']}/{res['clutch_ends']}, clutches loaded {res['clutches_loaded']}/"
                  f"{res['clutches']}")
            for k, v in res["loads"].items():
                print(f"    load {k:34s} {v}")
        figures[name] = {**{k: v for k, v in res.items() if k != "rho"}, "last_rho": res["rho"],
                         "date": time.strftime("%Y-%m-%d")}
    print(f"run folders in {base}")
    if args.json:
        sys.path.insert(0, str(Path(__file__).parent))
        from solver import save_json

        save_json(args.json, "design", figures)


if __name__ == "__main__":
    main()
