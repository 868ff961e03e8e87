"""Plots of the force over the motion (:class:`kgarment.evaluate.path.PathReport`): clutch
tension against motion progress, like the paper's force figure."""

from __future__ import annotations

from pathlib import Path

from kgarment.evaluate.path import PathFrame, PathReport
from kgarment.io import save_figure


def draw_tensions(ax, report: PathReport, motion: str) -> tuple[list[PathFrame], list[PathFrame]]:
    """Draw on matplotlib axes ``ax`` each clutch's tension against motion progress in
    ``motion``, ON solid and OFF dashed, and a red line at each frame re-solved; returns
    the (ON, OFF) curves drawn (a report made before paths had a rest frame: from zero)."""
    on, off = report.curve(motion, "on"), report.curve(motion, "off")
    if not report.has_rest:  # an older report: nothing known at rest, drawn from zero
        on, off = ([PathFrame(motion, s, 0.0, 0.0, (0.0,) * len(report.clutches), True)] + c
                   for s, c in (("on", on), ("off", off)))
    t = [f.t for f in on]
    for k, c in enumerate(report.clutches):
        ax.plot(t, [f.tension_N[k] for f in on], color=f"C{k % 10}", lw=1.6, label=f"{c} ON")
        ax.plot(t, [f.tension_N[k] for f in off], color=f"C{k % 10}", lw=1.0, ls="--", label=f"{c} OFF")
    for f in report.resolved():
        if f.motion == motion:
            ax.axvline(f.t, color="#e76f51", lw=0.6, alpha=0.6)
    ax.grid(alpha=0.3)
    return on, off


def path_plot(report: PathReport, path, title: str = "") -> Path:
    """Force against motion progress like the paper's force figure: per motion, each
    clutch's tension ON (solid) and OFF (dashed), and the garment energy ON / OFF (right
    axis); a PNG at ``path``."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    motions = report.motions
    fig, axes = plt.subplots(1, len(motions), figsize=(max(3.6 * len(motions), 4.8), 3.4), dpi=100, squeeze=False)
    for ax, m in zip(axes[0], motions):
        on, off = draw_tensions(ax, report, m)
        t = [f.t for f in on]
        ax.set_xlabel("motion progress")
        ax.set_title(m, fontsize=9)
        e = ax.twinx()
        e.plot(t, [f.energy_J for f in on], color="k", lw=0.8, alpha=0.6)
        e.plot(t, [f.energy_J for f in off], color="k", lw=0.8, ls=":", alpha=0.6)
        e.set_ylabel("garment energy (J), ON solid / OFF dotted", fontsize=7)
        for mm, hold in report.holding_N:  # each clutch's holding force, where it is reached or near
            for k, h in enumerate(hold if mm == m else ()):
                if 0 < h < 2 * max((f.tension_N[k] for f in on), default=0.0):
                    ax.axhline(h, color=f"C{k % 10}", lw=0.8, ls=":", alpha=0.8)
    axes[0][0].set_ylabel("clutch tension (N)")
    axes[0][0].legend(fontsize=6, loc="upper left")
    return save_figure(fig, path, title)


