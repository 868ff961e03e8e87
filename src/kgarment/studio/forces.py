"""The force over the motion in the page: a picture and a table of a
:class:`kgarment.evaluate.path.PathReport` (what ``kgarment evaluate RUN --path K`` writes)."""

from __future__ import annotations

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from kgarment.evaluate.path import PathReport
from kgarment.evaluate.path_plot import draw_tensions


def force_image(report: PathReport, width_px: int = 420, row_px: int = 190) -> np.ndarray:
    """(H, W, 3) uint8: per motion (one row each) every clutch's tension against motion
    progress from rest, ON solid and OFF dashed (drawn on an Agg canvas of its own: no
    pyplot, safe in the page's threads)."""
    motions = report.motions
    dpi = 100
    fig = Figure(figsize=(width_px / dpi, row_px * max(len(motions), 1) / dpi), dpi=dpi)
    canvas = FigureCanvasAgg(fig)
    for i, m in enumerate(motions):
        ax = fig.add_subplot(len(motions), 1, i + 1)
        draw_tensions(ax, report, m)
        ax.set_title(m, fontsize=8)
        ax.set_ylabel("tension (N)", fontsize=7)
        ax.tick_params(labelsize=7)
        if i == 0:
            ax.legend(fontsize=6, loc="upper left")
    if fig.axes:
        fig.axes[-1].set_xlabel("motion progress (dashed: OFF)", fontsize=7)
    fig.tight_layout()
    canvas.draw()
    return np.asarray(canvas.buffer_rgba())[:, :, :3].copy()


def force_table(report: PathReport, label: str) -> str:
    """Markdown: per motion and clutch, peak and mean tension ON / OFF (N), and per motion
    the work over the motion ON / OFF (J, from rest) and the energy at the target."""
    head = (f"**Force over the motion, design {label}** (frames from rest; work: the garment's energy at the "
            "target less at rest)")
    lines = [head, "", "| motion | clutch | peak N ON / OFF | mean N ON / OFF | work J ON / OFF |", "|---|---|---|---|---|"]
    for r in report.summary():
        lines.append(f"| {r['motion']} | {r['clutch']} | {r['peak_on_N']:.0f} / {r['peak_off_N']:.0f} | "
                     f"{r['mean_on_N']:.0f} / {r['mean_off_N']:.0f} | {r['work_on_J']:.3g} / {r['work_off_J']:.3g} |")
    again = report.resolved()
    if again:
        lines += ["", (f"{len(again)} frame(s) re-solved (the first solve had ended in a higher-energy "
                       "equilibrium; red lines)")]
    return "\n".join(lines)
