"""Run folders: checkpoints after every iteration, metrics, designs, plots and renders.

Layout of a run folder::

    problem.toml        the problem file as given (when there was one)
    problem.txt         the resolved problem, in full
    checkpoint.npz      everything needed to resume bit-identically (atomic rewrite)
    designs.npz         every iteration's design, bit-packed: (iterations, ceil(m/8)) uint8
    metrics.csv/.json   one row per iteration (area, objective, rho per motion and state, ...)
    progress.png        rho ON/OFF per motion against iteration (like the paper's Fig. 6)
    final/              design.npz, design.ply (face colours), renders by energy density
"""

from __future__ import annotations

import csv
import io
import json
import os
import shutil
import tempfile
from pathlib import Path

import numpy as np

from kgarment.design.loop import LoopState
from kgarment.errors import KgarmentError
from kgarment.paths import atomic_save_npz


def atomic_write_text(path: Path, text: str) -> None:
    path = Path(path)
    fd, tmp = tempfile.mkstemp(dir=path.parent, suffix=".tmp")
    with os.fdopen(fd, "w") as f:
        f.write(text)
    os.replace(tmp, path)


def prepare_run_folder(path, force: bool = False, resume: bool = False) -> Path:
    """Create (or, for resume, check) a run folder; never clobber one without ``force``."""
    path = Path(path)
    if resume:
        if not (path / "checkpoint.npz").is_file():
            raise KgarmentError(f"{path} is not a resumable run (no checkpoint.npz)")
        return path
    if path.exists() and any(path.iterdir()):
        if not force:
            raise KgarmentError(f"run folder {path} exists; use --resume to continue it or --force to replace it")
        shutil.rmtree(path)
    path.mkdir(parents=True, exist_ok=True)
    return path


def save_checkpoint(run: Path, st: LoopState) -> None:
    names = sorted(st.warm)
    ref_keys = sorted(st.reference)
    arrays = dict(
        iteration=np.array(st.iteration), design=st.design, target=np.array(st.target),
        has_alpha=np.array(st.alpha_prev is not None),
        alpha_prev=st.alpha_prev if st.alpha_prev is not None else np.zeros(0),
        warm_names=np.array(names, dtype=str), objectives=np.array(st.objectives, dtype=np.float64),
        ref_keys=np.array(["|".join(k) for k in ref_keys], dtype=str),
        ref_values=np.array([st.reference[k] for k in ref_keys], dtype=np.float64),
        ref_clutch=np.array([st.reference_stored[k].clutch_energy for k in ref_keys], dtype=np.float64),
        metrics=np.array(json.dumps(st.metrics)), done=np.array(st.done),
        n_faces=np.array(len(st.design)),
        designs=np.array([np.packbits(d) for d in st.designs]) if st.designs else np.zeros((0, 0), np.uint8),
    )
    for i, n in enumerate(names):
        arrays[f"warm_{i}"] = st.warm[n]
    for i, k in enumerate(ref_keys):
        arrays[f"ref_faces_{i}"] = st.reference_stored[k].face_energy
    atomic_save_npz(run / "checkpoint.npz", **arrays)
    atomic_save_npz(run / "designs.npz", designs=arrays["designs"], n_faces=arrays["n_faces"])
    write_metrics(run, st.metrics)


def load_checkpoint(run: Path) -> LoopState:
    from kgarment.design.metrics import Stored

    with np.load(run / "checkpoint.npz") as z:
        names = [str(n) for n in z["warm_names"]]
        keys = [tuple(str(k).split("|")) for k in z["ref_keys"]]
        m = int(z["n_faces"])
        designs = [np.unpackbits(row)[:m].astype(bool) for row in z["designs"]]
        return LoopState(
            iteration=int(z["iteration"]), design=z["design"].copy(), target=float(z["target"]),
            alpha_prev=z["alpha_prev"].copy() if bool(z["has_alpha"]) else None,
            warm={n: z[f"warm_{i}"].copy() for i, n in enumerate(names)},
            objectives=[float(v) for v in z["objectives"]],
            reference={k: float(v) for k, v in zip(keys, z["ref_values"])},
            reference_stored={k: Stored(z[f"ref_faces_{i}"].copy(), float(c))
                              for i, (k, c) in enumerate(zip(keys, z["ref_clutch"]))},
            designs=designs, metrics=json.loads(str(z["metrics"])), done=bool(z["done"]),
        )


def load_design_history(run) -> np.ndarray:
    """(iterations, m) bool: the design evaluated at every iteration of a run."""
    path = Path(run) / "designs.npz"
    if not path.is_file():
        raise KgarmentError(f"{run} has no designs.npz; is it a run folder?")
    with np.load(path) as z:
        m = int(z["n_faces"])
        return np.array([np.unpackbits(r)[:m].astype(bool) for r in z["designs"]])


def write_metrics(run: Path, rows: list[dict]) -> None:
    if not rows:
        return
    cols = list(dict.fromkeys(k for r in rows for k in r))
    buf = io.StringIO()
    w = csv.DictWriter(buf, fieldnames=cols)
    w.writeheader()
    w.writerows(rows)
    atomic_write_text(run / "metrics.csv", buf.getvalue())
    atomic_write_text(run / "metrics.json", json.dumps(rows, indent=1))


def progress_plot(run: Path, rows: list[dict]) -> Path:
    """rho per motion and state against iteration, with the reinforced area share."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    it = [r["iteration"] for r in rows]
    fig, ax = plt.subplots(figsize=(7, 4), dpi=100)
    keys = [k for k in rows[0] if k.startswith("rho[")]
    for k in keys:
        style = "--" if k.endswith(":off]") else "-"
        ax.plot(it, [r.get(k, np.nan) for r in rows], style, label=k[4:-1])
    ax.set_xlabel("iteration")
    ax.set_ylabel("relative energy density rho")
    ax2 = ax.twinx()
    ax2.plot(it, [100 * r["area"] for r in rows], ":", color="grey", label="area")
    ax2.set_ylabel("reinforced area (%)", color="grey")
    ax.legend(fontsize=7, loc="upper left")
    ax.grid(alpha=0.3)
    fig.tight_layout()
    path = run / "progress.png"
    fig.savefig(path)
    plt.close(fig)
    return path
