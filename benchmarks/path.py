"""Benchmark: the force over the motion (``kgarment evaluate RUN --path K``) of a design.

Loads a finished run (default ``runs/demo``, the main job: ``kgarment demo`` makes it),
builds its evaluator, and times :func:`kgarment.evaluate.path.path_forces` with K frames
(default 10) on every motion of the run, ON and OFF: posing the body and the garment in
the frames, then the frame-by-frame solves and the clutch tensions.  As ``kgarment
evaluate RUN --path K`` does, the evaluator reads the run's equilibria (``RUN/equilibria``)
-- here a copy of them as the run's final evaluation left them (entries not newer than
``final/evaluation.json``: an earlier ``--path`` of the run does not make it faster), in a
temporary folder; ``--cold`` times it without them (the target's equilibria solved too).
Prints the timings, the peak tension per motion and clutch (ON and OFF) and the frames
re-solved, and records them in ``benchmarks/results.json`` under ``path`` (``path cold``).
Target on a 2-core machine: the main job's design (subdivision 0) at 10 frames in at most
60 s.

    python benchmarks/path.py [RUN] [--frames K] [--cold]
"""

from __future__ import annotations

import argparse
import json
import shutil
import tempfile
import time
from pathlib import Path

from kgarment.case.store import FOLDER, EquilibriumStore
from kgarment.design import load_design, parse_design_source
from kgarment.design.driver import run_inputs
from kgarment.design.run import iteration_of
from kgarment.evaluate import Evaluator
from kgarment.evaluate.path import frame_motions, path_forces
from kgarment.problem import load_problem

RESULTS = Path(__file__).resolve().parent / "results.json"


def run_copy(run: Path, folder: Path) -> tuple[EquilibriumStore, int]:
    """An EquilibriumStore in ``folder`` holding a copy of ``run``'s equilibria as its final
    evaluation left them (entries not newer than ``final/evaluation.json``; none for a run
    made with --no-evaluation), and how many."""
    final = run / "final" / "evaluation.json"
    end = final.stat().st_mtime if final.is_file() else float("-inf")
    kept = [f for f in sorted((run / FOLDER).glob("*.npz")) if f.stat().st_mtime <= end]
    for f in kept:
        shutil.copy2(f, folder / f.name)
    return EquilibriumStore(folder), len(kept)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("run", nargs="?", default="runs/demo")
    ap.add_argument("--frames", type=int, default=10)
    ap.add_argument("--cold", action="store_true", help="without the run's equilibria")
    a = ap.parse_args()
    src = parse_design_source(a.run, run_required=True)
    problem = load_problem(src.run / "problem.toml")
    problem, body, garment, strips = run_inputs(src.run, problem)
    with tempfile.TemporaryDirectory(prefix="kgarment-path-bench-") as tmp:
        store, kept = (None, 0) if a.cold else run_copy(src.run, Path(tmp))
        ev = Evaluator.from_problem(problem, body=body, garment=garment, strips=strips, store=store)
        design = load_design(src, ev.n_faces)
        t0 = time.time()
        frame_motions(problem, ev.motions, a.frames)  # posing (cached on disk after the first time)
        t_pose = time.time() - t0
        t0 = time.time()
        rep = path_forces(ev, design, problem, frames=a.frames)
        wall = time.time() - t0
    print(rep.table())
    out = {"run": str(src.run), "iteration": iteration_of(src), "frames": a.frames, "motions": ev.motions,
           "run_equilibria": kept, "read_back": 0 if store is None else store.hits,
           "faces": int(ev.n_faces), "posing_s": t_pose, "wall_s": wall,
           "resolved_frames": len(rep.resolved()),
           "peak_on_N": {f"{r['motion']}/{r['clutch']}": r["peak_on_N"] for r in rep.summary()},
           "peak_off_N": {f"{r['motion']}/{r['clutch']}": r["peak_off_N"] for r in rep.summary()}}
    print(f"\n{a.frames} frames x {len(ev.motions)} motions x ON/OFF on {ev.n_faces} faces: {wall:.1f} s "
          f"(posing alone, warm cache: {t_pose:.1f} s); target <= 60 s for the main job; "
          + ("cold: the target's equilibria solved too" if a.cold else
             f"{out['read_back']} solves read back from the run's {kept} equilibria, as kgarment evaluate RUN does"))
    doc = json.loads(RESULTS.read_text()) if RESULTS.is_file() else {}
    doc["path cold" if a.cold else "path"] = out
    RESULTS.write_text(json.dumps(doc, indent=1))
    print(f"recorded in {RESULTS}")


if __name__ == "__main__":
    main()
