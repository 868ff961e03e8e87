"""Design runs in the studio: open a run folder, check it fits, scrub its iterations.

A run folder (see :mod:`kgarment.design.run`) holds every iteration's design in
``designs.npz`` and one metrics row per iteration. The studio shows a run only on the
garment it was made for: same body, same garment template or mask, same subdivision, same
face count; otherwise it says which of these differ and changes nothing.
"""

from __future__ import annotations

import json
import zipfile
from collections.abc import Sequence
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from matplotlib.ticker import MaxNLocator

from kgarment.case.keys import RHO, state_column, state_columns, state_text
from kgarment.design import load_design_history
from kgarment.errors import KgarmentError
from kgarment.optimize import LoopState
from kgarment.problem import BodySpec, GarmentSpec, Problem, load_problem


@dataclass(frozen=True)
class RunHistory:
    """A run folder read for scrubbing (or followed while it runs).

    folder : Path; problem : Problem (the run's problem.toml); designs : (K, m) bool, the
    design of every iteration (K may be 0 while a run starts); metrics : K dict rows.
    """

    folder: Path
    problem: Problem
    designs: np.ndarray = field(repr=False)
    metrics: tuple[dict, ...]

    @classmethod
    def empty(cls, folder: Path, problem: Problem, n_faces: int) -> RunHistory:
        """A run that has not finished an iteration yet."""
        return cls(Path(folder), problem, np.zeros((0, n_faces), bool), ())

    def following(self, st: LoopState) -> RunHistory:
        """This run with the iterations of a running design loop's state ``st``."""
        designs = np.array(st.designs, dtype=bool).reshape(len(st.designs), -1)
        return RunHistory(self.folder, self.problem, designs, tuple(st.metrics))

    @property
    def n_iterations(self) -> int:
        return len(self.designs)

    def design(self, k: int) -> np.ndarray:
        """(m,) bool design of iteration ``k`` (negative counts from the end)."""
        n = self.n_iterations
        if n == 0:
            raise KgarmentError(f"run {self.folder} has no iteration yet")
        if not -n <= k < n:
            raise KgarmentError(f"run {self.folder} has iterations 0..{n - 1}; asked for {k}")
        return self.designs[k]

    def summary(self, k: int) -> str:
        """One line on iteration ``k``: area, objective and rho per motion and state."""
        if not 0 <= k < len(self.metrics):
            return f"iteration {k}"
        row = self.metrics[k]
        rho = ", ".join(f"{state_text(key)} {v:.2f}" for key, v in state_columns(row, RHO).items())
        return (f"iteration {k}: area {100 * row.get('area', float('nan')):.1f}%, "
                f"objective {row.get('objective', float('nan')):.4f}; rho {rho}")


def read_run(folder) -> RunHistory:
    """Read a run folder (raises KgarmentError naming what is missing or damaged)."""
    folder = Path(folder)
    if not folder.is_dir():
        raise KgarmentError(f"run folder not found: {folder}")
    if not (folder / "problem.toml").is_file():
        raise KgarmentError(f"{folder} is not a run folder (no problem.toml)")
    problem = load_problem(folder / "problem.toml")
    try:
        designs = load_design_history(folder) if (folder / "designs.npz").is_file() else np.zeros((0, 0), bool)
    except KgarmentError:
        raise
    except (OSError, ValueError, KeyError, zipfile.BadZipFile) as exc:
        raise KgarmentError(f"cannot read the designs of run {folder}: {exc}") from None
    metrics = []
    if (folder / "metrics.json").is_file():
        try:
            metrics = json.loads((folder / "metrics.json").read_text())
        except ValueError:
            metrics = []
    return RunHistory(folder, problem, designs, tuple(metrics))


def _garment_text(g: GarmentSpec, n_faces: int | None) -> str:
    what = g.template or f"mask {g.mask}"
    return f"{what} at subdivision {g.subdivision}" + (f" ({n_faces} faces)" if n_faces is not None else "")


def check_compatible(run: RunHistory, problem: Problem, n_faces: int) -> None:
    """Raise KgarmentError unless ``run`` was made on ``problem``'s body and garment and its
    designs have ``n_faces`` faces."""
    mine, theirs = problem, run.problem
    if asdict(mine.body) != asdict(theirs.body):
        raise KgarmentError(f"run {run.folder} was made on a different body ({_body_text(theirs.body)}); "
                            f"the studio has {_body_text(mine.body)}")
    gm, gt = mine.garment, theirs.garment
    same = (gm.template, gm.mask, tuple(gm.attach), gm.subdivision) == (gt.template, gt.mask, tuple(gt.attach),
                                                                       gt.subdivision)
    m_run = run.designs.shape[1] if run.designs.ndim == 2 and run.n_iterations else None
    if not same or (m_run is not None and m_run != n_faces):
        raise KgarmentError(f"run {run.folder} was made for garment {_garment_text(gt, m_run)}; "
                            f"the studio has {_garment_text(gm, n_faces)}")


def _body_text(b: BodySpec) -> str:
    if b.model == "anny":
        return "Anny, phenotype " + ", ".join(f"{k} {v:g}" for k, v in asdict(b.phenotype).items())
    return f"meshes from {b.rest}"


def metric_series(rows: Sequence[dict]) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    """(iterations (K,), {label: (K,) values}) of the rho curves and the area share (%)."""
    it = np.array([r.get("iteration", k) for k, r in enumerate(rows)], dtype=np.float64)
    keys = list(dict.fromkeys(k for r in rows for k in state_columns(r, RHO)))
    out = {state_text(k): np.array([r.get(state_column(RHO, k), np.nan) for r in rows], dtype=np.float64) for k in keys}
    out["area %"] = np.array([100 * r.get("area", np.nan) for r in rows], dtype=np.float64)
    return it, out


def progress_image(rows: Sequence[dict], width_px: int = 420, height_px: int = 360) -> np.ndarray:
    """(H, W, 3) uint8 picture of rho per motion and state against iteration (dashed: OFF)
    with the reinforced area share, like the run folder's progress.png (drawn on an Agg
    canvas of its own: no pyplot, safe in the page's threads)."""
    dpi = 100
    fig = Figure(figsize=(width_px / dpi, height_px / dpi), dpi=dpi)
    canvas = FigureCanvasAgg(fig)
    ax = fig.add_subplot(111)
    if rows:
        it, series = metric_series(rows)
        for label, y in series.items():
            if label == "area %":
                continue
            ax.plot(it, y, "--" if label.endswith(":off") else "-", label=label, marker="." if len(it) < 30 else None)
        ax2 = ax.twinx()
        ax2.plot(it, series["area %"], ":", color="grey")
        ax2.set_ylabel("reinforced area (%)", color="grey", fontsize=8)
        ax2.tick_params(labelsize=8)
        ax2.xaxis.set_major_locator(MaxNLocator(integer=True))
        # below the axes, in two columns: readable at the panel's width, never over the curves
        ax.legend(fontsize=8, loc="upper center", bbox_to_anchor=(0.5, -0.2), ncol=2, frameon=False)
    else:
        ax.text(0.5, 0.5, "no iteration yet", ha="center", va="center", transform=ax.transAxes)
    ax.set_xlabel("iteration", fontsize=8)
    ax.set_ylabel("rho", fontsize=8)
    ax.tick_params(labelsize=8)
    ax.xaxis.set_major_locator(MaxNLocator(integer=True))  # iterations are whole numbers
    ax.grid(alpha=0.3)
    fig.tight_layout()
    canvas.draw()
    return np.asarray(canvas.buffer_rgba())[..., :3].copy()
