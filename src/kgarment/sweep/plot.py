"""The sweep's plots (``sweep.png``): per motion, rho ON (and OFF) and every clutch's
tension (N, all clutches ON) against the first numeric axis, one line per combination of
the other axes' values (robustness across bodies, presets, ...).  Without a numeric axis
the tasks are the x axis, one point each."""

from __future__ import annotations

import io
import numbers
from pathlib import Path

from kgarment.io import atomic_write_bytes
from kgarment.sweep.table import motions_and_clutches

STYLES = ("-", "--", ":", "-.")
MARKERS = ("o", "s", "^", "D", "v", "P")


def _numeric(v) -> bool:
    return isinstance(v, numbers.Real) and not isinstance(v, bool)


def x_axis(folder, names: list[str]) -> str | None:
    """The first axis whose value is a number in every task of ``names`` (None: none is)."""
    for a in folder.axes:
        if all(_numeric(folder.values.get(n, {}).get(a)) for n in names):
            return a
    return None


def sweep_plot(folder, path, title: str) -> Path | None:
    """Draw ``path`` from the finished tasks' records; None when no task has rho yet."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    names = [n for n in folder.tasks if folder.results.get(n, {}).get("rho")]
    if not names:
        return None
    recs = {n: folder.results[n] for n in names}
    motions, pairs = motions_and_clutches(recs)
    xa = x_axis(folder, names)
    others = [a for a in folder.axes if a != xa]

    def group_of(n: str) -> str:
        v = folder.values.get(n, {})
        return ", ".join(f"{a.rsplit('.', 1)[-1]}={v[a]}" for a in others if a in v) if xa else ""

    groups = list(dict.fromkeys(group_of(n) for n in names))
    xs = {n: (folder.values[n][xa] if xa else k) for k, n in enumerate(names)}
    cols = max(1, len(motions))
    fig, axes = plt.subplots(2, cols, figsize=(4.6 * cols, 7.5), squeeze=False)
    colours = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    for j, m in enumerate(motions):
        top, bottom = axes[0][j], axes[1][j]
        for g, group in enumerate(groups):
            members = sorted((n for n in names if group_of(n) == group and m in recs[n]["rho"]), key=lambda n: xs[n])
            x = [xs[n] for n in members]
            colour = colours[g % len(colours)]
            top.plot(x, [recs[n]["rho"][m].get("on", float("nan")) for n in members], "-o", color=colour,
                     label=group or "ON")
            top.plot(x, [recs[n]["rho"][m].get("off", float("nan")) for n in members], ":", marker=".", color=colour,
                     alpha=0.7, label=None if group else "OFF")
            for c, (mm, clutch) in enumerate(p for p in pairs if p[0] == m):
                loads = {n: next((r for r in recs[n].get("clutches", []) if (r["motion"], r["clutch"]) == (mm, clutch)),
                                 None) for n in members}
                pts = [(xs[n], r["tension_N"]) for n, r in loads.items() if r is not None]
                if pts:
                    bottom.plot(*zip(*pts), STYLES[g % len(STYLES)], marker=MARKERS[c % len(MARKERS)],
                                color=colours[c % len(colours)],
                                label=clutch if g == 0 else None)
        top.set_title(m)
        top.set_ylabel("rho ON (solid) / OFF (dotted)")
        bottom.set_ylabel("clutch tension, all ON (N)")
        for ax in (top, bottom):
            ax.set_ylim(bottom=0)
            ax.grid(alpha=0.3)
            if xa:
                ax.set_xlabel(xa)
            else:
                ax.set_xticks(range(len(names)), names, rotation=30, ha="right", fontsize=7)
        top.legend(fontsize=7, title=", ".join(a.rsplit(".", 1)[-1] for a in others) if xa and others else None,
                   title_fontsize=7)
        if bottom.lines:
            bottom.legend(fontsize=7, title="clutch" + (" (line style: as above)" if len(groups) > 1 else ""),
                          title_fontsize=7)
    fig.suptitle(title)
    fig.tight_layout()
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=110)
    plt.close(fig)
    return atomic_write_bytes(path, buf.getvalue())
