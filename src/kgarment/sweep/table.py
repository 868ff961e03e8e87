"""The sweep's table: one row per task, as CSV (every number) and Markdown (for reading).

Columns: the task, its axis values, status, the error of a failed task, iterations, the
best iteration (the final design's), wall time (s), the reinforced area share, parts
counting clutches as links, clutch ends on reinforcement and in all, then per motion rho
ON and OFF, and per motion and clutch the load share, needed and tension (N) with all
clutches ON (``kgarment evaluate``'s, from each run's ``final/evaluation.json``).  Tasks
with other motions or clutches leave the other cells empty.
"""

from __future__ import annotations

import csv
import io
import json
import math

NOTE = ("rho: the final design's (the best iteration at the target area), evaluated like `kgarment evaluate`; "
        "clutch loads with all clutches ON: share (only that clutch ON), needed (the share lost with only it OFF), "
        "tension in newtons. Run folders: `runs/TASK`.")


def motions_and_clutches(records: dict) -> tuple[list[str], list[tuple[str, str]]]:
    """Every motion (in order of first appearance) and every (motion, clutch) pair."""
    motions: dict = {}
    pairs: dict = {}
    for rec in records.values():
        for m in rec.get("rho", {}):
            motions[m] = None
        for c in rec.get("clutches", []):
            motions[c["motion"]] = None
            pairs[(c["motion"], c["clutch"])] = None
    return list(motions), list(pairs)


def _value(v) -> str:
    if isinstance(v, (list, dict)):
        return json.dumps(v)
    if isinstance(v, bool):
        return "true" if v else "false"
    return str(v)


def rows(folder) -> tuple[list[str], list[list]]:
    """(header, rows) of the CSV: plain values (numbers, strings; '' where none)."""
    recs = {n: folder.results.get(n, {"status": "new"}) for n in folder.tasks}
    motions, pairs = motions_and_clutches(recs)
    head = ["task", *folder.axes, "status", "error", "iterations", "best_iteration", "wall_s", "area", "parts",
            "ends_supported", "ends"]
    head += [f"rho_{s}[{m}]" for m in motions for s in ("on", "off")]
    head += [f"{k}[{m}:{c}]" for m, c in pairs for k in ("share", "needed", "tension_N")]
    out = []
    for name in folder.tasks:
        rec = recs[name]
        values = folder.values.get(name, {})
        row = [name, *(_value(values[a]) if a in values else "" for a in folder.axes), rec.get("status", ""),
               rec.get("error", "")]
        row += [rec.get(k, "") for k in ("iterations", "best_iteration", "wall_s", "area", "parts", "ends_supported",
                                         "ends")]
        rho = rec.get("rho", {})
        row += [rho.get(m, {}).get(s, "") for m in motions for s in ("on", "off")]
        loads = {(c["motion"], c["clutch"]): c for c in rec.get("clutches", [])}
        row += [loads.get(p, {}).get(k, "") for p in pairs for k in ("share", "needed", "tension_N")]
        out.append(["" if v is None else v for v in row])
    return head, out


def csv_text(folder) -> str:
    head, body = rows(folder)
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(head)
    w.writerows(body)
    return buf.getvalue()


def _num(v, fmt: str) -> str:
    if v is None or v == "" or (isinstance(v, float) and not math.isfinite(v)):
        return "-"
    return format(v, fmt)


def markdown_text(folder, title: str) -> str:
    """The table in Markdown: rho as ON / OFF per motion, each clutch's load per motion
    as share / needed / N; the errors of failed tasks below it."""
    recs = {n: folder.results.get(n, {"status": "new"}) for n in folder.tasks}
    motions, pairs = motions_and_clutches(recs)
    head = ["task", *folder.axes, "status", "iterations (best)", "wall (s)", "area %", "parts", "clutch ends"]
    head += [f"rho {m} ON / OFF" for m in motions]
    head += [f"{c} in {m}: share / needed / N" for m, c in pairs]
    lines = [f"# {title}", "", "| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    errors = []
    for name in folder.tasks:
        rec = recs[name]
        values = folder.values.get(name, {})
        cells = [name, *(_value(values[a]) if a in values else "" for a in folder.axes), rec.get("status", "")]
        it = rec.get("iterations")
        cells.append("-" if it is None else f"{it}" + (f" ({rec['best_iteration']})"
                                                         if rec.get("best_iteration") is not None else ""))
        cells.append(_num(rec.get("wall_s"), ".0f"))
        area = rec.get("area")
        cells.append(_num(None if area is None else 100 * area, ".1f"))
        cells.append(_num(rec.get("parts"), "d"))
        ends = rec.get("ends")
        cells.append("-" if ends is None else f"{rec.get('ends_supported')} of {ends}")
        rho = rec.get("rho", {})
        cells += [f"{_num(rho[m].get('on'), '.2f')} / {_num(rho[m].get('off'), '.3f')}" if m in rho else ""
                  for m in motions]
        loads = {(c["motion"], c["clutch"]): c for c in rec.get("clutches", [])}
        cells += [f"{_num(loads[p].get('share'), '.2f')} / {_num(loads[p].get('needed'), '.2f')} / "
                  f"{_num(loads[p].get('tension_N'), '.0f')}" if p in loads else "" for p in pairs]
        lines.append("| " + " | ".join(str(c).replace("|", "\\|") for c in cells) + " |")
        if rec.get("error"):
            errors.append(f"- `{name}`: {rec['error']}")
    if errors:
        lines += ["", "Failed tasks:", "", *errors]
    lines += ["", NOTE]
    return "\n".join(lines) + "\n"
