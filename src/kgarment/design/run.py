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
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from kgarment.case.keys import (
    RHO,
    Kind,
    checkpoint_key,
    parse_checkpoint_key,
    state_column,
    state_columns,
    state_text,
)
from kgarment.case.values import design_values
from kgarment.constants import SIM_MODEL, X_MIN, target_reached
from kgarment.errors import KgarmentError
from kgarment.evaluate.metrics import Stored
from kgarment.io import atomic_save_npz, atomic_write_text, check_replaceable, load_npz
from kgarment.optimize.loop import LoopState


@dataclass(frozen=True)
class DesignSource:
    """Where a design comes from: a run folder (its final design: ``final/design.npz``'s
    iteration, the best at the target area; or iteration ``iteration``) or a design file (.npy, .npz with a ``design`` array, .txt)."""

    run: Path | None = None
    iteration: int | None = None
    file: Path | None = None

    def __str__(self) -> str:
        if self.run is None:
            return str(self.file)
        return f"{self.run}@{self.iteration}" if self.iteration is not None else str(self.run)


def parse_design_source(text: str, run_required: bool = False) -> DesignSource:
    """'RUN' (its final design), 'RUN@K' (iteration K) or a design file path.

    A folder must be a run folder (hold problem.toml); ``run_required`` refuses files.  A path
    that exists is taken whole ('v@2/run'); else ITERATION follows the last '@'."""
    text = str(text)
    run, at, it = text, "", ""
    if "@" in text and not Path(text).exists():
        run, at, it = text.rpartition("@")
    path = Path(run)
    if path.is_dir():
        if not (path / "problem.toml").is_file():
            raise KgarmentError(f"{path} is not a run folder (no problem.toml); give RUN or RUN@ITERATION")
        if at and not (it.isascii() and it.isdigit()):
            raise KgarmentError(f"iteration {it!r} in {text!r} must be a whole number from 0 "
                                f"(RUN@0 is the fully reinforced garment)")
        return DesignSource(run=path, iteration=int(it) if at else None)
    if run_required or at:
        raise KgarmentError(f"{text!r} is not a run folder; give RUN or RUN@ITERATION")
    if not path.is_file():
        raise KgarmentError(f"{text!r} is neither a run folder (RUN or RUN@ITERATION) nor a design file")
    return DesignSource(file=path)


def load_design(source: DesignSource | str | os.PathLike, n_faces: int) -> np.ndarray:
    """The design (n_faces,) in [x_min, 1] of a :class:`DesignSource` (or its text or path)."""
    src = source if isinstance(source, DesignSource) else parse_design_source(str(source))
    if src.run is not None:
        hist = load_design_history(src.run)
        k = iteration_of(src)
        if not 0 <= k < len(hist):
            raise KgarmentError(f"{src.run} has iterations 0..{len(hist) - 1}; asked for {k}")
        if hist.shape[1] != n_faces:
            raise KgarmentError(f"the design in {src.run} has {hist.shape[1]} faces, the garment {n_faces}")
        return design_values(hist[k])
    path = src.file
    if path.suffix == ".npz":
        z = load_npz(path, "design file (.npz with a 'design' array)")
        if not z:
            raise KgarmentError(f"design {path} holds no array; save the design (m,) as 'design'")
        d = z["design"] if "design" in z else next(iter(z.values()))
    else:
        try:
            if path.suffix != ".npy" and not path.read_text(errors="replace").strip():
                raise ValueError("the file is empty")
            d = np.load(path, allow_pickle=False) if path.suffix == ".npy" else np.loadtxt(path)
        except (OSError, ValueError, EOFError) as exc:
            raise KgarmentError(f"cannot read design {path} (.npy, .npz or text of {n_faces} numbers): {exc}") from None
    try:
        d = np.asarray(d, dtype=np.float64).reshape(-1)
    except (TypeError, ValueError):
        raise KgarmentError(f"design {path} does not hold numbers") from None
    if d.shape != (n_faces,):
        raise KgarmentError(f"design {path} has {d.size} values, the garment has {n_faces} faces")
    if not np.all((d >= 0) & (d <= 1)):
        raise KgarmentError(f"design {path}: values must lie in [0, 1] (1 reinforced; 0 or {X_MIN:g} plain cloth)")
    return np.maximum(d, X_MIN)  # plain cloth is X_MIN, not 0 (a 0/1 design is accepted as such)


def best_iteration(rows, target: float, er: float) -> int:
    """The iteration a run reports as its design: the highest objective among the iterations
    at the target area whose states all converged; the last one if none.  BESO's objective
    is not monotone once the target is reached (where a state has several equilibria the
    design can flip between them), and the paper samples designs along a run likewise.  A
    step the guard took back (:mod:`kgarment.optimize.guard`) is never reported.  With ``[solver]
    path_start`` only the iterations whose ON states were also solved over the motion from
    rest count (``path_checked``): the others' objectives may be of an equilibrium the wearer
    never reaches."""
    ranked = ranked_iterations(rows, target, er)
    return ranked[0] if ranked else int(rows[-1]["iteration"])


def ranked_iterations(rows, target: float, er: float) -> list[int]:
    """The iterations :func:`best_iteration` chooses from, highest objective first (ties:
    the earlier iteration first); empty when none is at the target area with every state
    converged."""
    ok = [r for r in rows if target_reached(r["area"], target, er) and not r["unconverged_states"]
          and not r.get("rejected")]
    if any(r.get("path_checked") for r in ok):
        ok = [r for r in ok if r.get("path_checked")]
    return [int(r["iteration"]) for r in sorted(ok, key=lambda r: (-r["objective"], r["iteration"]))]


def final_iteration(run) -> int:
    """The iteration of a run's final design (``final/design.npz``), else its last one."""
    run = Path(run)
    path = run / "final" / "design.npz"
    if path.is_file():
        z = load_npz(path, "final design")
        if "iteration" in z:
            return int(z["iteration"])
    return len(load_design_history(run)) - 1


def iteration_of(source: DesignSource) -> int:
    """The iteration a run source names (its final design's when none is given)."""
    return final_iteration(source.run) if source.iteration is None else source.iteration


def run_status(run) -> str:
    """"new" (no checkpoint), "unfinished" or "finished" (final design written)."""
    run = Path(run)
    ck = run / "checkpoint.npz"
    if not ck.is_file():
        return "new"
    done = bool(load_npz(ck, "checkpoint", ("done",))["done"])
    return "finished" if done and (run / "final" / "design.npz").is_file() else "unfinished"


def check_run_folder(path, force: bool = False, resume: bool = False) -> Path:
    """Check a run folder before anything is built: for ``resume``, that it holds a
    checkpoint; otherwise that it is missing, empty or (with ``force``) a kgarment run folder
    (:func:`kgarment.io.check_replaceable`; the new run replaces it only once its problem is
    built, see :func:`kgarment.design.driver.open_run`)."""
    path = Path(path)
    if resume:
        if not (path / "checkpoint.npz").is_file():
            raise KgarmentError(f"{path} is not a resumable run (no checkpoint.npz)")
        return path
    hint = ("use --resume to continue it or --force to replace it" if (path / "checkpoint.npz").is_file() else
            "it stopped before its first checkpoint, so there is nothing to resume: use --force to start it again")
    return check_replaceable(path, force, hint=hint)


def save_checkpoint(run: Path, st: LoopState) -> None:
    names = sorted(st.warm)
    ref_keys = sorted(st.reference)
    text = metrics_json(st.metrics)
    arrays = dict(
        iteration=np.array(st.iteration), design=st.design, target=np.array(st.target),
        has_alpha=np.array(st.alpha_prev is not None),
        alpha_prev=st.alpha_prev if st.alpha_prev is not None else np.zeros(0),
        warm_names=np.array(names, dtype=str), objectives=np.array(st.objectives, dtype=np.float64),
        ref_keys=np.array([checkpoint_key(k) for k in ref_keys], dtype=str),
        ref_values=np.array([st.reference[k] for k in ref_keys], dtype=np.float64),
        ref_clutch=np.array([st.reference_stored[k].clutch_energy for k in ref_keys], dtype=np.float64),
        metrics=np.frombuffer(text.encode(), np.uint8), done=np.array(st.done),
        n_faces=np.array(len(st.design)), sim_model=np.array(SIM_MODEL),
        designs=packed_designs(st),
    )
    if st.guarded is not None:  # the step guard's, only when used (earlier checkpoints have none)
        arrays["guarded"] = st.guarded
    for i, (m, a) in enumerate(sorted((st.accepted_alpha or {}).items())):
        arrays[f"accepted_{i}"] = a
        arrays[f"accepted_name_{i}"] = np.array(m)
    for i, n in enumerate(names):
        arrays[f"warm_{i}"] = st.warm[n]
    for i, k in enumerate(ref_keys):
        arrays[f"ref_faces_{i}"] = st.reference_stored[k].face_energy
    atomic_save_npz(run / "checkpoint.npz", compressed=False, **arrays)  # rewritten every iteration
    write_history(run, st, arrays["designs"], text)


def packed_designs(st: LoopState) -> np.ndarray:
    """(iterations, ceil(m / 8)) uint8: every iteration's design, one bit per face."""
    return np.array([np.packbits(d) for d in st.designs]) if st.designs else np.zeros((0, 0), np.uint8)


def write_history(run: Path, st: LoopState, packed: np.ndarray | None = None, text: str | None = None) -> None:
    """designs.npz and the metrics files of ``st`` (what the checkpoint holds, written beside
    it for readers; a resumed run writes them again, so damaged copies are rebuilt)."""
    atomic_save_npz(run / "designs.npz", designs=packed_designs(st) if packed is None else packed,
                    n_faces=np.array(len(st.design)))
    write_metrics(run, st.metrics, text=metrics_json(st.metrics) if text is None else text)


CHECKPOINT_KEYS = ("iteration", "design", "target", "has_alpha", "alpha_prev", "warm_names", "objectives", "ref_keys",
                   "ref_values", "ref_clutch", "metrics", "done", "n_faces", "designs")


def load_checkpoint(run: Path) -> LoopState:
    """The loop state saved by :func:`save_checkpoint` (a damaged file -> one KgarmentError)."""
    path = Path(run) / "checkpoint.npz"
    z = load_npz(path, "checkpoint (delete the run folder and start again, or give another --out)", CHECKPOINT_KEYS)
    try:
        return _state_from(z)
    except (KeyError, ValueError, IndexError, TypeError) as exc:
        raise KgarmentError(f"{path} is damaged ({type(exc).__name__}: {exc}); start the run again") from None


def checkpoint_model(run: Path) -> int:
    """The simulation model a run was designed with (``kgarment.constants.SIM_MODEL``;
    checkpoints before version 2 carry none: 1)."""
    with np.load(Path(run) / "checkpoint.npz") as z:
        return int(z["sim_model"]) if "sim_model" in z.files else 1


def other_model(then: int) -> str:
    """How a run or report made with simulation model ``then`` differs from this kgarment's
    (the clause of the one-line errors that refuse to mix them)."""
    return (f"simulation model {then} and this kgarment simulates model {SIM_MODEL} "
            "(kgarment.constants.SIM_MODEL: what changed)")


def check_model(run: Path) -> None:
    """A run is resumed only under the simulation model it was designed with."""
    then = checkpoint_model(run)
    if then != SIM_MODEL:
        raise KgarmentError(f"{run} was designed with {other_model(then)}; its iterations would "
                            "mix the two: start it again with --force, or give another --out")


def _state_from(z: dict) -> LoopState:
    names = [str(n) for n in z["warm_names"]]
    keys = [parse_checkpoint_key(k) for k in z["ref_keys"]]
    m = int(z["n_faces"])
    designs = [np.unpackbits(row)[:m].astype(bool) for row in z["designs"]]
    return LoopState(
        iteration=int(z["iteration"]), design=z["design"].copy(), target=float(z["target"]),
        alpha_prev=z["alpha_prev"].copy() if bool(z["has_alpha"]) else None,
        warm={n: z[f"warm_{i}"].copy() for i, n in enumerate(names)},
        objectives=tuple(float(v) for v in z["objectives"]),
        reference={k: float(v) for k, v in zip(keys, z["ref_values"])},
        reference_stored={k: Stored(z[f"ref_faces_{i}"].copy(), float(c))
                          for i, (k, c) in enumerate(zip(keys, z["ref_clutch"]))},
        designs=tuple(designs), metrics=tuple(json.loads(_text(z["metrics"]))), done=bool(z["done"]),
        guarded=z["guarded"].astype(bool) if "guarded" in z else None,
        accepted_alpha={str(z[f"accepted_name_{i}"]): z[f"accepted_{i}"].copy()
                        for i in range(len(z)) if f"accepted_{i}" in z} or None,
    )


def _text(a: np.ndarray) -> str:
    """A checkpoint's metrics: UTF-8 bytes (uint8), or a string (checkpoints before 2026-11-27)."""
    return a.tobytes().decode() if a.dtype == np.uint8 else str(a)


def metrics_json(rows) -> str:
    """The metrics rows as JSON, one row per line (``metrics.json``; the checkpoint keeps
    the same text)."""
    return "[\n" + ",\n".join(json.dumps(r) for r in rows) + "\n]\n"


def load_design_history(run) -> np.ndarray:
    """(iterations, m) bool: the design evaluated at every iteration of a run."""
    path = Path(run) / "designs.npz"
    if not path.is_file():
        raise KgarmentError(f"{run} has no designs.npz; is it a run folder?")
    z = load_npz(path, "design history", ("designs", "n_faces"))
    m = int(z["n_faces"])
    hist = np.array([np.unpackbits(r)[:m].astype(bool) for r in z["designs"]]).reshape(-1, m)
    if len(hist) == 0:
        raise KgarmentError(f"{path} holds no iteration yet; resume the run first")
    return hist


def write_metrics(run: Path, rows, text: str | None = None) -> None:
    """``metrics.csv`` and ``metrics.json`` of ``rows`` (``text``: their
    :func:`metrics_json`, where already made)."""
    if not rows:
        return
    cols = list(dict.fromkeys(k for r in rows for k in r))
    buf = io.StringIO()
    w = csv.DictWriter(buf, fieldnames=cols)
    w.writeheader()
    w.writerows(list(rows))
    atomic_write_text(run / "metrics.csv", buf.getvalue())
    atomic_write_text(run / "metrics.json", metrics_json(rows) if text is None else text)


def progress_plot(run: Path, rows: list[dict]) -> Path:
    """rho per motion and state against iteration, with the reinforced area share."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.ticker import MaxNLocator

    it = [r["iteration"] for r in rows]
    fig, ax = plt.subplots(figsize=(7, 4), dpi=100)
    keys = list(state_columns(rows[0], RHO))
    taken_back = [r for r in rows if r.get("rejected")]  # steps the guard took back: markers, off the lines
    kept = [r for r in rows if not r.get("rejected")]
    for key in keys:
        k = state_column(RHO, key)
        style = "--" if key.kind is Kind.OFF else "-"
        (line,) = ax.plot([r["iteration"] for r in kept], [r.get(k, np.nan) for r in kept], style, label=state_text(key))
        if taken_back:
            ax.plot([r["iteration"] for r in taken_back], [r.get(k, np.nan) for r in taken_back], "x",
                    color=line.get_color(), alpha=0.6)
    if taken_back:
        ax.plot([], [], "x", color="grey", label="step taken back (guard)")
    ax.set_xlabel("iteration")
    ax.set_ylabel("relative energy density rho")
    ax2 = ax.twinx()
    ax2.plot(it, [100 * r["area"] for r in rows], ":", color="grey", label="area")
    ax2.set_ylabel("reinforced area (%)", color="grey")
    ax.xaxis.set_major_locator(MaxNLocator(integer=True))
    ax.grid(alpha=0.3)
    # the legend beside the plot, past the area axis (inside, it hid the first iterations' curves)
    fig.set_size_inches(10, 4)
    fig.tight_layout(rect=(0, 0, 0.68, 1))
    fig.legend(*ax.get_legend_handles_labels(), fontsize=7, loc="upper left", bbox_to_anchor=(0.69, 0.95),
               frameon=False)
    path = run / "progress.png"
    fig.savefig(path)
    plt.close(fig)
    return path
