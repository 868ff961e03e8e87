"""The report's counterpart of the paper's physical validation (its section "Physical
Validation" and force figure): the paper replaced one clutch of its fabricated multi-motion
shirt by a force sensor -- in the upper back for arms forward, at the bottom left clutch for
arms raise and bend forward -- and measured the largest force over the motion, for its
automatic design and for its best participant's manual design: the automatic ones gave
"on average two times and up to four times" the force, the largest difference in arms raise.
Here the same clutch's tension over the motion (``kgarment evaluate --path``) of our design
against the manual baseline, ON."""

from __future__ import annotations

from kgarment.reproduce.text import md_table

NEGLIGIBLE_N = 5.0  # a baseline clutch below this peak tension, or below NEGLIGIBLE_SHARE of
NEGLIGIBLE_SHARE = 0.02  # ours, carries (almost) nothing: no ratio is printed

# per experiment and motion, the clutch the paper's sensor replaced (None: not named, the
# largest clutch tension is used); the bottom left clutch of the shirt seen from behind is the
# wearer's left one
SENSOR = {"shirt_three_motions": {"arms_forward": "upper_back", "arms_raise": "lower_back.L",
                                  "bend_forward": "lower_back.L"},
          "sleeve_two_motions": {}}


def peak_tension(path_doc: dict, motion: str, clutch: str | None) -> float:
    """The largest tension (N) over the motion, ON, of ``clutch`` (None: of any clutch), from
    the path's per-clutch summary (:meth:`kgarment.evaluate.path.PathReport.summary`)."""
    return max((r["peak_on_N"] for r in path_doc["summary"] if r["motion"] == motion and clutch in (None, r["clutch"])),
               default=0.0)


def sensor_rows(doc: dict) -> list[dict]:
    """Per experiment of :data:`SENSOR` with the force over the motion of ours and the manual
    baseline, per motion: {experiment, motion, clutch, ours_N, manual_N, ratio (None where the
    manual design's clutch carries (almost) nothing: below NEGLIGIBLE_N or NEGLIGIBLE_SHARE of ours)}."""
    rows = []
    for name, sensors in SENSOR.items():
        e = doc.get("experiments", {}).get(name)
        paths = (e or {}).get("path") or {}
        if "ours" not in paths or "manual" not in paths:
            continue
        for m in e["motions"]:
            clutch = sensors.get(m)
            ours, manual = peak_tension(paths["ours"], m, clutch), peak_tension(paths["manual"], m, clutch)
            rows.append({"experiment": name, "motion": m, "clutch": clutch, "ours_N": ours, "manual_N": manual,
                         "ratio": ours / manual if manual >= max(NEGLIGIBLE_N, NEGLIGIBLE_SHARE * ours) else None})
    return rows


def validation_lines(doc: dict) -> list[str]:
    """The report's section body (Markdown lines); empty without the forces it needs."""
    rows = sensor_rows(doc)
    if not rows:
        return []
    table = [[r["experiment"], r["motion"], r["clutch"] or "the most loaded clutch", f"{r['ours_N']:.0f}",
              f"{r['manual_N']:.0f}",
              f"{r['ratio']:.2f}x" if r["ratio"] is not None else "none: the manual design's clutch carries (almost) nothing"]
             for r in rows]
    ratios = [r["ratio"] for r in rows if r["ratio"] is not None]
    words = (f"Ours against the manual baseline: {sum(ratios) / len(ratios):.2f}x on average, up to "
             f"{max(ratios):.2f}x ({len(ratios)} of {len(rows)} motions with a ratio)." if ratios else
             "The manual baseline's clutches carry (almost) nothing here: no ratio.")
    return [("The paper's physical validation replaced one clutch of the fabricated shirt by a force sensor (upper "
            "back for arms forward, the bottom left clutch for arms raise and bend forward; for the sleeve it names "
            "none) and found its automatic designs' largest force over the motion on average 2x and up to 4x that "
            "of its best participant's manual design, the largest difference in arms raise. Here: the largest "
            "tension over the motion of the same clutch, ON, in our design and the manual baseline (simulated; "
            "the paper measured with plastic strips in place of the clutches)."), ""] + \
        md_table(["experiment", "motion", "clutch (the paper's sensor)", "ours (N)", "manual (N)", "ours / manual"],
                 table) + [words, ""]
