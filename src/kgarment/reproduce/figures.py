"""Figures of the reproduction report (matplotlib, Agg)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from kgarment.io import save_figure

KINDS = (("ours", "#1f3b73"), ("manual", "#d98c1f"), ("compliance", "#7a9e3a"), ("random", "#999999"))


def _plt():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def rho_bars(path: Path, doc: dict) -> str:
    """Grouped bars of rho ON per (experiment, motion) for our design and the baselines;
    returns the path relative to the report folder."""
    plt = _plt()
    labels, vals = [], {k: [] for k, _ in KINDS}
    err = []
    for e in doc["experiments"].values():
        ev = e["evaluations"]
        for m in e["motions"]:
            labels.append(f"{e['name']}\n{m}" if len(e["motions"]) > 1 else e["name"])
            for k, _ in KINDS[:3]:
                vals[k].append(ev[k]["rho"][m]["on"])
            rnd = [r["rho"][m]["on"] for r in ev["random"]]
            vals["random"].append(float(np.mean(rnd)) if rnd else np.nan)
            err.append(float(np.std(rnd)) if len(rnd) > 1 else 0.0)
    x = np.arange(len(labels))
    w = 0.2
    fig, ax = plt.subplots(figsize=(max(7.0, 0.55 * len(labels) + 2), 3.6), dpi=90)
    for i, (k, c) in enumerate(KINDS):
        ax.bar(x + (i - 1.5) * w, vals[k], w, color=c, label=k, yerr=err if k == "random" else None)
    ax.axhline(1.0, color="k", lw=0.8, ls=":")
    ax.set_xticks(x, labels, rotation=60, ha="right", fontsize=6)
    ax.set_ylabel("rho ON")
    ax.legend(fontsize=7, ncol=4)
    ax.grid(axis="y", alpha=0.3)
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path)
    plt.close(fig)
    return f"img/{path.name}"


def emergent_figure(path: Path, doc: dict, out: Path) -> str | None:
    """Our design beside the compliance and manual baselines (the paper's last figure) for
    the three-motion shirt, or the first multi-motion experiment there is."""
    exps = doc["experiments"]
    pick = exps.get("shirt_three_motions") or next((e for e in exps.values() if e["multi"]), None)
    pick = pick or next(iter(exps.values()), None)
    if pick is None:
        return None
    plt = _plt()
    kinds = [k for k in ("ours", "compliance", "manual") if k in pick["images"]]
    img0 = plt.imread(out / pick["images"][kinds[0]])
    aspect = img0.shape[0] / img0.shape[1]
    fig, axes = plt.subplots(len(kinds), 1, figsize=(9, (9 * aspect + 0.5) * len(kinds)), dpi=90)
    for ax, k in zip(np.atleast_1d(axes), kinds):
        ax.imshow(plt.imread(out / pick["images"][k]))
        r = pick["evaluations"][k]
        on = np.mean([r["rho"][m]["on"] for m in pick["motions"]])
        off = np.mean([r["rho"][m]["off"] for m in pick["motions"]])
        ax.set_title(f"{k}: {r['islands_with_clutches']} part(s), clutch ends {r['clutch_ends_supported']}/{r['clutch_ends']}, "
                     f"mean rho ON {on:.2f}, OFF {off:.2f}", fontsize=9)
        ax.axis("off")
    fig.suptitle(f"{pick['title']}: emergent properties", fontsize=9)
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)
    return f"img/{path.name}"


PATH_COLORS = {"ours": "#1f3b73", "manual": "#d98c1f", "full": "#555555"}


def force_curves(path_doc: dict, motion: str, state: str) -> tuple[list[float], list[float]]:
    """(t, force) of one design's path JSON (:meth:`kgarment.evaluate.path.PathReport.to_json`)
    in ``motion`` and ``state``: per frame the largest clutch tension (N), the rest pose
    first (its frame, or (0, 0) in a JSON made before paths had one)."""
    frames = sorted((f for f in path_doc["frames"] if f["motion"] == motion and f["state"] == state),
                    key=lambda f: f["t"])
    rest = [] if frames and frames[0]["t"] == 0.0 else [(0.0, 0.0)]
    pts = rest + [(f["t"], max(f["tension_N"].values(), default=0.0)) for f in frames]
    return [p[0] for p in pts], [p[1] for p in pts]


def force_stats(path_doc: dict, motion: str) -> dict:
    """Peak (over the frames) and mean (over the frames after rest) of the largest clutch
    tension ON and OFF (N), and the work against the garment over the motion ON and OFF (J:
    its energy at the target less at rest, :meth:`kgarment.evaluate.path.PathReport.summary`)."""
    from kgarment.evaluate.path import work_from_rest

    out = {}
    for s in ("on", "off"):
        t, f = force_curves(path_doc, motion, s)
        moving = [v for a, v in zip(t, f) if a > 0.0]
        energy = sorted((x["t"], x["energy_J"]) for x in path_doc["frames"] if x["motion"] == motion and x["state"] == s)
        out[s] = {"peak": max(f), "mean": sum(moving) / max(len(moving), 1), "work": work_from_rest(energy),
                  "energy": energy[-1][1] if energy else 0.0}
    return out


def force_figure(path: Path, paths: dict, title: str) -> Path:
    """Force against motion progress like the paper's force figure: per motion, the largest
    clutch tension of each design ({kind: path JSON}) ON (solid) and OFF (dashed), frames
    that did not converge crossed; a PNG."""
    plt = _plt()
    motions = list(dict.fromkeys(f["motion"] for doc in paths.values() for f in doc["frames"]))
    fig, axes = plt.subplots(1, len(motions), figsize=(max(3.4 * len(motions), 4.4), 3.0), dpi=90, squeeze=False)
    for ax, m in zip(axes[0], motions):
        for kind, doc in paths.items():
            c = PATH_COLORS.get(kind, "#999999")
            ax.plot(*force_curves(doc, m, "on"), color=c, lw=1.6, label=f"{kind} ON")
            ax.plot(*force_curves(doc, m, "off"), color=c, lw=1.0, ls="--", label=f"{kind} OFF")
            for state in ("on", "off"):  # frames that did not converge: crosses
                t, f = force_curves(doc, m, state)
                bad = {x["t"] for x in doc["frames"] if x["motion"] == m and x["state"] == state and not x["converged"]}
                pts = [(a, b) for a, b in zip(t, f) if a in bad]
                if pts:
                    ax.plot(*zip(*pts), "x", color=c, ms=6)
        ax.set_title(m, fontsize=9)
        ax.set_xlabel("motion progress")
        ax.grid(alpha=0.3)
    axes[0][0].set_ylabel("largest clutch tension (N)")
    axes[0][0].legend(fontsize=6)
    return save_figure(fig, path, title)
