"""The paper's design experiments and the resolutions they run at: data only, so the
command line can list them without loading the simulator (see :mod:`.experiments`)."""

from __future__ import annotations

from dataclasses import dataclass

from kgarment.errors import KgarmentError

DATA = "data.json"  # in a reproduction folder: everything the report shows (results.json: its summary)


def objectives_at_target(rows, budget: float) -> list[float]:
    """A design run's objective at every iteration (metrics ``rows``) within 1% of the
    ``budget`` area whose states all converged: what the report says of the run once it
    reached its target."""
    return [r["objective"] for r in rows if abs(r["area"] - budget) < 0.01 and not r["unconverged_states"]]


@dataclass(frozen=True)
class Resolution:
    """subdivision : garment level (None: the example's); er : BESO's evolution ratio (None:
    the example's); max_iterations : cap (None: the example's); window : convergence
    window; seeds : random baseline designs;  path_frames : frames of the force over the
    motion (ours, manual, full; :mod:`kgarment.evaluate.path`);  ar_max : the share of faces
    added per iteration (None: ``er`` where it is given, else the example's)."""

    name: str
    subdivision: int | None
    er: float | None
    max_iterations: int | None
    window: int | None
    seeds: int
    path_frames: int = 10
    ar_max: float | None = None


RESOLUTIONS = {
    "tiny": Resolution("tiny", 0, 0.2, 3, 2, 2, 2),
    # preview: the target shrinks twice as fast as the paper's, faces are added at the paper's
    # 1.5% (measured on the single-motion arms-forward shirt with balance: 3% additions churned
    # 5-7% of the faces per iteration at the target area and the run never settled, rho ON
    # between 0.01 and 2.97; 1.5% stayed within 2.4-2.8)
    "preview": Resolution("preview", 0, 0.03, 120, None, 10, 5, ar_max=0.015),
    "default": Resolution("default", None, None, None, None, 10, 10),
}


@dataclass(frozen=True)
class Experiment:
    """name : also the example file's stem;  group : experiments sharing garment and
    clutch placement ("sleeve", "shirt", "long_sleeve");  multi : optimised for several
    motions;  paper : motion -> (rho ON, rho OFF or None) as published;  papers_model :
    made with the paper's clutch model (False: an experiment of ours, not the paper's, made
    with its example file's clutches; :func:`kgarment.reproduce.experiments.experiment_problem`)."""

    name: str
    group: str
    multi: bool
    paper: dict
    title: str
    papers_model: bool = True


EXPERIMENTS = (
    Experiment("arm_flexion", "sleeve", False, {"arm_flexion.right": (1.14, 0.34)}, "Arm flexion (sleeve, one clutch)"),
    Experiment("arm_extension", "sleeve", False, {"arm_extension.right": (1.74, 0.54)},
               "Arm extension (sleeve, one clutch)"),
    Experiment("arms_forward", "shirt", False, {"arms_forward": (2.13, 0.48)}, "Arms forward (shirt, three clutches)"),
    Experiment("arms_raise", "shirt", False, {"arms_raise": (1.51, 0.66)}, "Arms raise (shirt, three clutches)"),
    Experiment("bend_forward", "shirt", False, {"bend_forward": (2.47, 0.73)}, "Bend forward (shirt, three clutches)"),
    Experiment("sleeve_two_motions", "sleeve", True,
               {"arm_flexion.right": (0.88, None), "arm_extension.right": (1.27, None)},
               "Two-motion sleeve (flexion + extension)"),
    Experiment("sleeve_selective", "sleeve", True,
               {"arm_flexion.right": (0.88, None), "arm_extension.right": (1.27, None)},
               "Selective sleeve (flexion switches the outer clutch, extension the inner; paper: its two-motion sleeve)",
               papers_model=False),
    Experiment("shirt_three_motions", "shirt", True,
               {"arms_forward": (1.77, None), "arms_raise": (1.08, None), "bend_forward": (1.60, None)},
               "Three-motion shirt"),
    Experiment("long_sleeve_five_motions", "long_sleeve", True,
               {"arms_forward": (1.41, None), "arms_raise": (0.85, None), "bend_forward": (1.62, None),
                "arm_flexion.right": (0.64, None), "arm_extension.right": (1.16, None)},
               "Long-sleeve shirt, five clutches, five motions"),
)
BY_NAME = {e.name: e for e in EXPERIMENTS}
# the paper's Table 1 (three-motion shirt, rho ON): rows evaluated on, columns optimised for
PAPER_SHIRT_MATRIX = {
    "arms_forward": {"arms_forward": 2.13, "arms_raise": 0.46, "bend_forward": 0.34, "all": 1.77},
    "arms_raise": {"arms_forward": 0.62, "arms_raise": 1.51, "bend_forward": 0.14, "all": 1.08},
    "bend_forward": {"arms_forward": 0.35, "arms_raise": 0.81, "bend_forward": 2.47, "all": 1.60},
}
MULTI_OF_GROUP = {"sleeve": "sleeve_two_motions", "shirt": "shirt_three_motions"}


def select(names: str | None) -> list[Experiment]:
    """Experiments by comma-separated names (None: all), in the canonical order."""
    if names is None:
        return list(EXPERIMENTS)
    asked = [n.strip() for n in names.split(",") if n.strip()]
    if not asked:
        raise KgarmentError(f"--experiments {names!r} names no experiment; known: {', '.join(BY_NAME)} "
                            "(leave --experiments out for all)")
    unknown = [n for n in asked if n not in BY_NAME]
    if unknown:
        raise KgarmentError(f"unknown experiment {unknown[0]!r}; known: {', '.join(BY_NAME)}")
    return [e for e in EXPERIMENTS if e.name in asked]
