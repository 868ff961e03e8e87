"""Write docs/reference/problem-file.md: every field of a problem file, its default and range.

Defaults come from the frozen dataclasses of :mod:`kgarment.problem.spec` (and the clutch and
body specs), ranges and choices from :mod:`kgarment.constants` and the names the parser
checks against (:mod:`kgarment.problem.parse`); only the one-line meanings are written here.
A dataclass field without a meaning below makes :func:`render` fail, so a new field cannot
reach the file format undocumented.  ``tests/test_docs.py`` asserts that the committed page
is what this script writes; run it after changing the problem file's fields::

    .venv/bin/python docs/scripts/problem_reference.py
"""

from __future__ import annotations

import dataclasses
import sys
from pathlib import Path

from kgarment import constants as C
from kgarment.body.anny_backend import Phenotype
from kgarment.body.motions import NAMED_AXES
from kgarment.clutch.layouts import LAYOUTS
from kgarment.clutch.spec import MAX_ASPECT, MAX_LENGTH, ClutchSpec
from kgarment.garment import template_names
from kgarment.problem import parse as P
from kgarment.problem import spec as S

PAGE = Path(__file__).resolve().parents[1] / "reference" / "problem-file.md"

# The meaning of every field, by section.  Keys are the names written in a problem file.
MEANING = {
    "design": {
        "objective": "what the design maximises: `active` is the paper's E_ON - E_OFF, `passive` the "
                     "energy without clutches (the predecessor paper), `compliance` E_ON alone",
        "target_area": "A*, the reinforced share of the garment's area at the end (0.20 in the sleeve examples)",
        "er": "evolution ratio: the target area shrinks by this share per iteration, from 100% down to A*",
        "ar_max": "at most this share of the faces may be added per iteration",
        "filter": "sensitivity filter: `one_ring` (area-weighted vertex average, the paper's) or `radius`",
        "radius": "metres, the reach of the `radius` filter",
        "history": "average each iteration's filtered sensitivities with the previous iteration's",
        "tol": "converged when A* is reached and the objective changes by less than this (relative) "
               "over `window` iterations",
        "window": "iterations over which convergence is judged",
        "max_iterations": "hard stop of the design loop",
        "connected": "repair every BESO update so that each clutch end sits on reinforcement joined to "
                     "what the body holds, no islands (false: the paper's plain BESO)",
        "settle": "at A*, halve the faces that may be added every `settle` iterations (0: off)",
        "protect_attachments": "keep the attachment rings reinforced",
        "protect_clutch_margin": "metres around each clutch anchor kept reinforced (0: off)",
        "lockout": "with clutch sets per motion: weight of the energy other motions' sets store in a "
                   "motion, subtracted from its objective term",
        "balance": "weight of each clutch's own gain (that clutch alone ON) added to its motion's term, "
                   "or a table `{ MOTION = w }` for the motions named only",
        "levels": "coarser subdivision levels to design at first (coarse-to-fine), each below the "
                  "garment's, increasing",
        "guard": "take back a step after which a motion's objective term falls by more than this share "
                 "(0: off)",
        "combine": "`sum` of the motions' terms (the paper's) or `product` (no motion given up for the others)",
        "early": "`{ MOTION = t }`: also design for the body posed the share t in (0, 1) of the way "
                 "(design runs only)",
        "weights": "`{ MOTION = w }`: a motion's weight in the objective, w in (0, 10] (others 1)",
    },
    "solver": {
        "method": "`newton` (sparse Cholesky, the default) or `lbfgs` (the paper's solver, for comparison)",
        "tol": "largest vertex force over (local stiffness Y t x mean edge length): iteration 0's "
               "tolerance; evaluations solve to min(tol, 1e-4)",
        "evolution_tol": "the tolerance of every design iteration after iteration 0 "
                         "(= tol to solve every iteration alike)",
        "max_iter": "Newton iterations per state",
        "skin_start": "also solve every design iteration from the evaluator's two starts and keep the "
                      "lowest-energy equilibrium (3x the solves)",
        "path_start": "every N-th design iteration also solves each ON state over its motion from rest "
                      "as the evaluator does (0: never)",
        "path_frames": "frames of that motion from rest, for the check and the run's final evaluation",
        "workers": "processes solving states in parallel (0: one per core, at most 8; results do not "
                   "depend on it)",
    },
    "materials": {
        "preset": "`paper` (0.5 MPa / 0.5 GPa / 3 GPa) or `reference` (0.5 / 5.7 / 25.7 MPa): plain "
                  "cloth / reinforced cloth / clutch ON",
        "skin_friction": "skin-garment friction coefficient (0: the paper's frictionless body; cloth on "
                         "skin is about 0.3 to 0.6)",
    },
    "clutches": {
        "layout": "a default layout by name (without `layout`, `file` or `clutch`: the garment's own)",
        "file": "a clutch file (TOML, as `kgarment clutches show` writes), relative to the problem file",
        "clutch": "`[[clutches.clutch]]`: clutches of your own (fields in the next table)",
        "side": "the body side of a layout's one-sided clutches",
        "model": "`locked`: an ON clutch never slips (the paper's); `slip`: it holds up to its holding "
                 "force and slides beyond; `cable`: one pull-only force between its ends, up to it",
        "holding_stress": "Pa of strip (width x length) a clutch holds: 21 N/cm^2, measured for the "
                          "paper's textile clutches",
        "voltage": "V; > 0: the holding stress from the parallel-plate formula mu eps0 eps_r V^2 / (2 d^2)",
        "dielectric_thickness": "d of that formula, metres",
        "permittivity": "eps_r of that formula (relative)",
        "friction": "mu of that formula, between the strips",
        "holding_force": "newtons every clutch holds, or `{ CLUTCH = N }` per clutch (overrides the stress)",
        "buckle": "ON strips take no compression (they buckle); false is the paper's model",
        "channel": "each clutch sewn along its length into a channel of reinforced fabric (false: "
                   "snapped on at its two ends, the paper's build)",
    },
    "clutch": {
        "name": "the clutch's name: letters, digits, `_ . + -`, at most 64",
        "start": "a landmark name, or `[x, y, z]` in rest coordinates (snapped onto the garment, at most 2 cm away)",
        "towards": "a landmark or `[x, y, z]` the clutch heads for (give this or `direction`)",
        "direction": "`[x, y, z]`, projected onto the start face (give this or `towards`)",
        "length": f"metres along the surface, up to {MAX_LENGTH:g}",
        "width": f"metres, at most {MAX_ASPECT:g} x the length",
        "prestrain": "rest-shape scale in (0, 1]: below 1 the clutch starts taut",
        "clip": "stop the clutch at the garment's boundary instead of failing",
    },
    "garment": {
        "template": "a garment template (`kgarment garments`)",
        "mask": "instead of a template: a face mask file (`.npy`, the body faces of the garment)",
        "attach": "with `mask`: the boundary loops glued to the body",
        "subdivision": "edge-midpoint subdivision levels of the garment (resolution; 1 is about the "
                       "paper's resolution on Anny, 2 its face count)",
    },
    "body": {
        "model": "`anny` (a parametric body) or `meshes` (your own posed meshes of one topology)",
        "phenotype": "Anny's shape: a table of the fields below, each in [0, 1]",
        "phenotypes": "instead of `phenotype`: two or more wearers `[{name = \"S\", weight = 0.2}, ...]`, "
                      "one design for all (the first is the body the garment is cut from)",
        "rest": "with `meshes`: the rest pose's mesh file",
        "rig": "with `meshes`, optional: an `.npz` with bone_names, bone_parents, skin_indices, "
               "skin_weights, rest_joints",
        "motions": "with `meshes`: `{ MOTION = FILE }`, one posed mesh per motion",
    },
    "phenotype": {
        "gender": "0 male, 1 female", "age": "", "muscle": "", "weight": "", "height": "", "proportions": "",
    },
    "motions": {
        "use": "the motions of the problem, by name (`kgarment motions` lists the library)",
        "define": "`[motions.define.NAME]`: a motion of your own (fields in the next table)",
        "activation": "`[motions.activation]`: per motion, the clutches its controller switches on: a "
                      "list of names, or `{ CLUTCH = g }` with g in [0, 1] (default: all)",
    },
    "define": {
        "rotations": "`[{ bone = \"upperarm01.L\", axis = \"-y\", degrees = 60 }, ...]`: the target pose",
        "keyframes": "instead: a list of such lists, an animated sequence whose last frame is the target",
        "description": "free text shown by `kgarment motions`",
    },
}

# Problem-file keys that are dataclass fields under another name, and fields that are not keys.
RENAMED = {("clutches", "inline"): "clutch", ("body", "meshes"): "motions"}
TABLES = ("early", "weights", "holding_force")  # empty tuples that a problem file writes as tables
INTERNAL = {("design", "beso"), ("clutches", "hardware"), ("clutches", "default")}


class Raw(str):
    """A default written as it is (not a TOML value)."""


def fmt(v) -> str:
    """A default as it would be written in TOML."""
    if isinstance(v, Raw):
        return str(v)
    if isinstance(v, bool):
        return "`true`" if v else "`false`"
    if v is None:
        return "(none)"
    if isinstance(v, float):
        return f"`{v:g}`"
    if isinstance(v, tuple):
        return "`[]`" if not v or not isinstance(v[0], tuple) else "`{}`"
    return f"`{v!r}`".replace("'", '"')


def allowed(section: str, key: str, default) -> str:
    """The range or choices the parser accepts for a field."""
    choices = {("design", "objective"): S.OBJECTIVE_NAMES, ("design", "combine"): S.COMBINE_NAMES,
               ("design", "filter"): S.FILTERS, ("solver", "method"): S.METHODS,
               ("materials", "preset"): S.PRESET_NAMES, ("clutches", "model"): C.CLUTCH_MODELS,
               ("clutches", "layout"): LAYOUTS, ("clutches", "side"): ("L", "R"),
               ("garment", "template"): tuple(template_names()), ("garment", "subdivision"): C.SUBDIVISIONS,
               ("body", "model"): ("anny", "meshes")}
    if (section, key) in choices:
        return " \\| ".join(f"`{c}`" for c in choices[(section, key)])
    ranges = {"design": C.DESIGN_RANGES, "solver": C.SOLVER_RANGES, "materials": P.MATERIAL_RANGES,
              "clutches": C.CLUTCH_RANGES}.get(section, {})
    if key in ranges:
        lo, hi = ranges[key]
        return f"[{lo:g}, {hi:g}]"
    if isinstance(default, bool):
        return "`true` \\| `false`"
    if section == "phenotype":
        return "[0, 1]"
    return {("design", "early"): "each t in (0, 1)",
            ("design", "weights"): f"each w in (0, {S.MOTION_WEIGHT_MAX:g}]",
            ("design", "levels"): "increasing, below `subdivision`"}.get((section, key), "")


def rows(section: str, fields) -> list[str]:
    """Table rows for (key, default) pairs of one section; every key needs a meaning."""
    out = ["| field | default | allowed | meaning |", "|---|---|---|---|"]
    for key, default in fields:
        meaning = MEANING[section].get(key)
        if meaning is None:
            raise KeyError(f"docs/scripts/problem_reference.py: no meaning for [{section}] {key}")
        if default == () and key in TABLES:
            default = Raw("`{}`")
        out.append(f"| `{key}` | {fmt(default)} | {allowed(section, key, default)} | {meaning} |")
    return out


def spec_fields(section: str, *classes) -> list[tuple[str, object]]:
    """(key, default) of every field of the dataclasses, as named in a problem file."""
    out = []
    for cls in classes:
        obj = cls()
        for f in dataclasses.fields(cls):
            if (section, f.name) in INTERNAL:
                continue
            out.append((RENAMED.get((section, f.name), f.name), getattr(obj, f.name)))
    return out


def render() -> str:
    none = Raw("(none)")
    body = [(k, none if k == "motions" else v) for k, v in spec_fields("body", S.BodySpec) if k != "phenotype"]
    body.insert(1, ("phenotype", Raw("all 0.5")))
    clutch_defaults = {f.name: f.default for f in dataclasses.fields(ClutchSpec)}
    clutch = [("name", None), ("start", None), ("towards", None), ("direction", None),
              ("length", None)] + [(k, clutch_defaults[k]) for k in ("width", "prestrain", "clip")]
    ph = Phenotype()
    lines = [
        "# Problem file reference",
        "",
        "<!-- Written by docs/scripts/problem_reference.py from kgarment.problem.spec, kgarment.constants",
        "     and the parser's choices; tests/test_docs.py checks that it is up to date. Do not edit. -->",
        "",
        "A problem is a TOML file with the sections below, each optional; a field left out takes its",
        "default. Every field is checked once, when the file is read: an unknown field, a value out of",
        "range or a name that does not exist is one line naming the field and what is allowed, exit",
        "status 2. Relative paths are relative to the problem file. Units are SI (metres, pascals,",
        "newtons, joules). Command-line flags (`--motion`, `--garment`, `--subdivision`,",
        "`--max-iterations`, `--clutch-model`, `--holding-force`, `--buckle`, `--channel`,",
        "`--skin-friction`, and for `simulate` `--preset`, `--solver`, `--tol`) override the file and",
        "are checked the same way. Without a file, commands use the built-in default: Anny at",
        "phenotype 0.5, the motions " + ", ".join(f"`{m}`" for m in S.DEFAULT_MOTIONS) + ", the short-sleeve",
        "shirt at subdivision 1 with its three back clutches.",
        "",
        "Names of motions and clutches: letters, digits, `_ . + -`, at most 64, not starting with",
        "`. + -` (file names are made of them). Examples of whole files: `kgarment examples`.",
        "",
        "## [body]", "",
        *rows("body", body), "",
        "Phenotype fields (`[body] phenotype = { weight = 0.7 }`, and each wearer of `phenotypes`):", "",
        *rows("phenotype", [(f.name, getattr(ph, f.name)) for f in dataclasses.fields(Phenotype)]), "",
        "## [motions]", "",
        *rows("motions", [("use", list(S.DEFAULT_MOTIONS)), ("define", none), ("activation", Raw("all clutches"))]), "",
        "`[motions.define.NAME]` (not a built-in motion's name):", "",
        *rows("define", [("rotations", None), ("keyframes", None), ("description", "user motion")]), "",
        "A rotation's `axis`: " + ", ".join(f"`{a}`" for a in NAMED_AXES) + " (world axes fixed in the",
        "rest pose; `hinge` is perpendicular to a bent joint, positive = flexion; `twist` the bone's",
        "long axis) or a 3-vector; `degrees` in "
        f"[{C.ROTATION_DEGREES[0]:g}, {C.ROTATION_DEGREES[1]:g}].",
        "",
        "## [garment]", "",
        *rows("garment", spec_fields("garment", S.GarmentSpec)), "",
        "## [clutches]", "",
        "Without the section, the garment's default layout (" + ", ".join(
            f"`{t}`: `{v}`" for t, v in S.DEFAULT_LAYOUT.items()) + ") with the default hardware.", "",
        *rows("clutches", spec_fields("clutches", S.ClutchesSpec, S.ClutchHardware)), "",
        "A holding force, stress or voltage implies `model = \"slip\"`; with `model = \"locked\"` they",
        "are refused. `holding_stress` and `voltage` exclude each other.", "",
        "`[[clutches.clutch]]` (and each clutch of a clutch file):", "",
        *rows("clutch", clutch), "",
        "## [design]", "",
        *rows("design", spec_fields("design", S.DesignSpec, S.BesoParams)), "",
        "The material interpolation is fixed: p = " + f"{C.PENALTY:g}, x_min = {C.X_MIN:g}"
        " (see [the method](../method/index.md)).", "",
        "## [materials]", "",
        *rows("materials", spec_fields("materials", S.MaterialSpec)), "",
        "## [solver]", "",
        *rows("solver", spec_fields("solver", S.SolverSpec)), "",
        f"Evaluations (`evaluate`, `simulate`, `fabricate`, the studio, `reproduce`) solve to "
        f"min(`tol`, {C.EVALUATION_TOL:g}).",
        "",
    ]
    return "\n".join(lines)


if __name__ == "__main__":
    text = render()
    if "--check" in sys.argv:
        sys.exit(0 if PAGE.read_text() == text else 1)
    PAGE.write_text(text)
    print(f"wrote {PAGE}")
