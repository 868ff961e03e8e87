"""Problem files (TOML) to :class:`~kgarment.problem.spec.Problem` and back.

Every field is validated once, here, with a message naming the field and what is allowed
(ranges from :mod:`kgarment.constants`).  Relative paths are relative to the problem file.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import asdict
from pathlib import Path

from kgarment import constants as C
from kgarment.body import Motion, MotionLibrary, Phenotype, Rotation
from kgarment.body.motions import NAMED_AXES, builtin_motions
from kgarment.clutch import clutch_spec_from_record
from kgarment.clutch.layouts import LAYOUTS
from kgarment.errors import KgarmentError, unknown
from kgarment.garment import template_names
from kgarment.io import read_toml
from kgarment.problem.serialize import problem_to_dict  # noqa: F401 (re-exported)
from kgarment.problem.spec import (
    COMBINE_NAMES,
    DEFAULT_MOTIONS,
    FILTERS,
    METHODS,
    MOTION_WEIGHT_MAX,
    OBJECTIVE_NAMES,
    PRESET_NAMES,
    BesoParams,
    BodySpec,
    ClutchesSpec,
    ClutchHardware,
    DesignSpec,
    GarmentSpec,
    MaterialSpec,
    Problem,
    SolverSpec,
)

MATERIAL_RANGES = {"skin_friction": (0.0, C.FRICTION_MAX)}
SECTIONS = ("body", "motions", "garment", "clutches", "materials", "design", "solver")


def load_problem(path) -> Problem:
    """Read and validate a TOML problem file."""
    path = Path(path)
    if not path.is_file():
        raise KgarmentError(f"problem file {path} is a folder; give a .toml file" if path.is_dir()
                            else f"problem file not found: {path}")
    _, data = read_toml(path, "problem file")
    return parse_problem(data, path.parent, path)


def parse_problem(data: dict, base: Path = Path("."), source: Path | None = None) -> Problem:
    """Validate a parsed TOML dict into a :class:`Problem` (errors name the field)."""
    check_keys("problem", data, SECTIONS)
    for name in SECTIONS:  # each section a table (its fields are checked where it is read)
        if name in data and not isinstance(data[name], dict):
            raise KgarmentError(f"[{name}] must be a table of fields, not {data[name]!r}")
    body = _body(data.get("body", {}), base)
    user, names = _motions(data.get("motions", {}), body)
    garment = _garment(data.get("garment", {}), base)
    clutches = _clutches(data["clutches"], base) if "clutches" in data else None
    design = _design(data.get("design", {}))
    _check_levels(design.levels, garment.subdivision)
    for key, table in (("early", design.early), ("balance", design.balance), ("weights", design.weights)):
        bad = [m for m, _ in table if m not in names] if isinstance(table, tuple) else []
        if bad:
            raise KgarmentError(f"[design] {key}: {bad[0]!r} is not a motion of the problem; its motions: "
                                f"{', '.join(names)}")
    if design.early and (body.phenotypes or body.model != "anny"):
        raise KgarmentError("[design] early: the beginning of a motion is posed on one Anny body (leave early out "
                            "for a multi-body design or a mesh-sequence body)")
    if design.levels and body.phenotypes:
        raise KgarmentError("[design] levels: coarse-to-fine is for one body; a multi-body design ([body] "
                            "phenotypes) runs at its garment's subdivision (leave levels out)")
    solver = dict(data.get("solver", {}))
    mats = dict(data.get("materials", {}))
    check_keys("materials", mats, ("preset", "skin_friction"))
    if "preset" in solver:  # run folders written before [materials] existed
        mats.setdefault("preset", solver.pop("preset"))
    materials = section(MaterialSpec, "materials", mats, {"preset": PRESET_NAMES}, MATERIAL_RANGES)
    solver = section(SolverSpec, "solver", solver, {"method": METHODS}, C.SOLVER_RANGES)
    activation = _activation(data.get("motions", {}).get("activation", {}), names)
    return Problem(body, names, user, garment, clutches, design, solver, materials, source, activation)


def check_keys(section_name: str, d: dict, allowed) -> None:
    """Refuse a table with a field not in ``allowed``."""
    bad = set(d) - set(allowed)
    if bad:
        raise KgarmentError(f"[{section_name}]: unknown field {sorted(bad)[0]!r}; allowed: {', '.join(allowed)}")


def section(cls, name: str, d: dict, choices: dict, ranges: dict):
    """Validate a flat TOML table against a dataclass: known fields, types, choices, ranges."""
    fields = {f.name: f for f in dataclasses.fields(cls)}
    check_keys(name, d, list(fields))
    out = {}
    for k, v in d.items():
        default = fields[k].default
        if isinstance(default, bool):
            if not isinstance(v, bool):
                raise KgarmentError(f"[{name}] {k} = {v!r}; allowed: true, false")
        elif isinstance(default, (int, float)):
            if isinstance(v, bool) or not isinstance(v, (int, float)):
                raise KgarmentError(f"[{name}] {k} = {v!r} must be a number")
            if not math.isfinite(v):
                raise KgarmentError(f"[{name}] {k} = {v!r} must be a finite number")
            if isinstance(default, int) and not float(v).is_integer():
                raise KgarmentError(f"[{name}] {k} = {v!r} must be an integer")
            v = type(default)(v)
        elif isinstance(default, str) and not isinstance(v, str):
            raise KgarmentError(f"[{name}] {k} = {v!r} must be a string")
        if k in choices and v not in choices[k]:
            raise KgarmentError(f"[{name}] {k} = {v!r}; allowed: {', '.join(choices[k])}")
        if k in ranges and not ranges[k][0] <= v <= ranges[k][1]:
            raise KgarmentError(f"[{name}] {k} = {v!r} is outside [{ranges[k][0]:g}, {ranges[k][1]:g}]")
        out[k] = v
    return cls(**out)


def _path(base: Path, p, what: str) -> Path:
    if not isinstance(p, str):
        raise KgarmentError(f"{what} must be a file path string")
    q = Path(p)
    q = q if q.is_absolute() else base / q
    if not q.exists():
        raise KgarmentError(f"{what}: file not found: {q}")
    if q.is_dir():
        raise KgarmentError(f"{what}: {q} is a folder, not a file")
    return q


def _body(b: dict, base: Path) -> BodySpec:
    check_keys("body", b, ("model", "phenotype", "phenotypes", "rest", "rig", "motions"))
    model = b.get("model", "anny")
    if model not in ("anny", "meshes"):
        raise unknown("body model", model, ("anny", "meshes"))
    if "phenotypes" in b:
        if model != "anny" or "phenotype" in b:
            raise KgarmentError("[body] phenotypes: a multi-body design is on Anny bodies, given by phenotypes "
                                "alone (not with phenotype or model = 'meshes')")
        many = _phenotypes(b["phenotypes"])
        return BodySpec("anny", many[0][1], phenotypes=many)
    if model == "anny":
        return BodySpec("anny", Phenotype.from_dict(b.get("phenotype", {})))
    if "rest" not in b or "motions" not in b:
        raise KgarmentError("[body] model = 'meshes' needs rest = FILE and motions = {name = FILE}")
    if not isinstance(b["motions"], dict) or not all(isinstance(v, str) for v in b["motions"].values()):
        raise KgarmentError("[body] motions must be a table of mesh files, e.g. motions = { arms_raise = "
                            "\"raise.obj\" }")
    meshes = tuple((k, _path(base, v, f"body.motions.{k}")) for k, v in b["motions"].items())
    return BodySpec("meshes", Phenotype(), _path(base, b["rest"], "body.rest"),
                    _path(base, b["rig"], "body.rig") if "rig" in b else None, meshes)


RESERVED_BODY_NAMES = ("all",)  # kgarment sizes names its every-wearer run "all"


def _phenotypes(v) -> tuple[tuple[str, Phenotype], ...]:
    """[body] phenotypes = [{name = "S", weight = 0.3, ...}, ...]: two or more wearers, each a
    name (letters, digits, _ . -; default body1, body2, ...) and phenotype fields."""
    if not isinstance(v, list) or len(v) < 2 or not all(isinstance(d, dict) for d in v):
        raise KgarmentError("[body] phenotypes must list two or more tables, e.g. "
                            "[{name = \"S\", weight = 0.3}, {name = \"L\", weight = 0.8}]")
    out = []
    for i, d in enumerate(v):
        name = d.get("name", f"body{i + 1}")
        if not isinstance(name, str) or not C.BODY_NAME.fullmatch(name) or set(name) == {"."} \
                or name in RESERVED_BODY_NAMES:
            raise KgarmentError(f"[body] phenotypes[{i}]: name = {name!r}; allowed: letters, digits, _ . - "
                                f"(at most 32; not only dots, not {' or '.join(map(repr, RESERVED_BODY_NAMES))}: "
                                "kgarment sizes' own run folders)")
        try:
            out.append((name, Phenotype.from_dict({k: x for k, x in d.items() if k != "name"})))
        except KgarmentError as exc:
            raise KgarmentError(f"[body] phenotypes[{i}] ({name}): {exc}") from None
    names = [n for n, _ in out]
    dup = sorted({n for n in names if names.count(n) > 1})
    if dup:
        raise KgarmentError(f"[body] phenotypes: duplicate name {dup[0]!r}; give each wearer its own name")
    return tuple(out)


def _rotation(d, where: str) -> Rotation:
    if not isinstance(d, dict):
        raise KgarmentError(f"{where}: a rotation is a table {{bone, axis, degrees}}")
    check_keys(where, d, ("bone", "axis", "degrees"))
    if "bone" not in d or "degrees" not in d:
        raise KgarmentError(f"{where}: a rotation needs bone and degrees")
    axis = d.get("axis", "x")
    if isinstance(axis, list):
        if len(axis) != 3 or not all(_finite(a) for a in axis) or not any(axis):
            raise KgarmentError(f"{where}: axis = {axis!r}; give x, y, z or three finite numbers [ax, ay, az], not all 0")
        axis = tuple(float(a) for a in axis)
    elif not isinstance(axis, str) or axis not in NAMED_AXES:
        raise unknown(f"axis in {where}", axis, NAMED_AXES)
    if not isinstance(d["bone"], str):
        raise KgarmentError(f"{where}: bone = {d['bone']!r} must be a bone name (a string)")
    deg = d["degrees"]
    lo, hi = C.ROTATION_DEGREES
    if not _finite(deg) or not lo <= deg <= hi:
        raise KgarmentError(f"{where}: degrees = {deg!r}; allowed: a number in [{lo:g}, {hi:g}]")
    return Rotation(d["bone"], axis, float(deg))


def _finite(v) -> bool:
    """A finite int or float (not a boolean)."""
    return isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)


def _user_motion(name: str, d: dict) -> Motion:
    where = f"motions.define.{name}"
    if not C.NAME.fullmatch(name):
        raise KgarmentError(f"[motions.define]: motion name {name!r}; allowed: letters, digits, _ . + - (at most "
                            "64, not starting with . + -; file names are made of it)")
    if name in builtin_motions():
        raise KgarmentError(f"[{where}]: {name!r} is a built-in motion (kgarment motions lists them); give yours "
                            "another name")
    check_keys(where, d, ("rotations", "keyframes", "description"))
    if ("rotations" in d) == ("keyframes" in d):
        raise KgarmentError(f"[{where}]: give either rotations or keyframes")
    frames = [d["rotations"]] if "rotations" in d else d["keyframes"]
    if not isinstance(frames, list) or not all(isinstance(kf, list) and all(isinstance(r, dict) for r in kf)
                                               for kf in frames):
        raise KgarmentError(f"[{where}]: rotations must be a list of tables, keyframes a list of such lists, "
                            "e.g. rotations = [{bone = \"upperarm01.R\", axis = \"x\", degrees = 30}]")
    kfs = tuple(tuple(_rotation(r, where) for r in kf) for kf in frames)
    if not kfs or not all(kfs):
        raise KgarmentError(f"[{where}]: a motion needs at least one rotation")
    description = d.get("description", "user motion")
    if not isinstance(description, str):
        raise KgarmentError(f"[{where}] description = {description!r}: must be a string")
    return Motion(name, kfs, description)


def _motions(m: dict, body: BodySpec) -> tuple[tuple[Motion, ...], tuple[str, ...]]:
    check_keys("motions", m, ("use", "define", "activation"))
    define = m.get("define", {})
    if not isinstance(define, dict) or not all(isinstance(v, dict) for v in define.values()):
        raise KgarmentError("[motions] define must hold tables: [motions.define.NAME] rotations = [...]")
    user = tuple(_user_motion(k, v) for k, v in define.items())
    default = [k for k, _ in body.meshes] if body.model == "meshes" else DEFAULT_MOTIONS
    use = m.get("use", default)
    if not isinstance(use, (list, tuple)) or not all(isinstance(u, str) for u in use):
        raise KgarmentError(f"[motions] use = {use!r} must be a list of motion names, e.g. use = [\"arms_raise\"]")
    names = _check_motions(tuple(use), body, MotionLibrary({u.name: u for u in user}))
    return user, names


def _activation(a, motions: tuple[str, ...]) -> tuple[tuple[str, tuple[tuple[str, float], ...]], ...]:
    """[motions.activation]: per motion of ``use``, the clutches switched on: a list of names
    (each fully on) or a table {name = value in [0, 1]}.  Clutch names are checked when the
    clutches are built (:func:`kgarment.case.setup.activation_vectors`)."""
    if not isinstance(a, dict):
        raise KgarmentError("[motions.activation] must be a table: MOTION = [\"clutch\", ...] or "
                            "MOTION = {clutch = value}")
    out = []
    for motion, v in a.items():
        if motion not in motions:
            raise KgarmentError(f"[motions.activation] {motion!r} is not a motion of this problem; "
                                f"allowed: {', '.join(motions)}")
        where = f"[motions.activation] {motion}"
        if isinstance(v, (list, tuple)):
            if not all(isinstance(n, str) for n in v):
                raise KgarmentError(f"{where} = {v!r} must list clutch names")
            v = {n: 1.0 for n in v}
        if not isinstance(v, dict):
            raise KgarmentError(f"{where} = {v!r} must be a list of clutch names or a table {{name = value}}")
        pairs = []
        for n, x in v.items():
            if isinstance(x, bool) or not isinstance(x, (int, float)) or not (0.0 <= float(x) <= 1.0):
                raise KgarmentError(f"{where}: {n} = {x!r} is outside [0, 1]")
            pairs.append((str(n), float(x)))
        if not any(x > 0 for _, x in pairs):
            raise KgarmentError(f"{where} switches no clutch on (an empty set); name at least one clutch, "
                                f"or leave the motion out to switch all of them")
        out.append((motion, tuple(pairs)))
    return tuple(out)


def _check_motions(names: tuple[str, ...], body: BodySpec, library: MotionLibrary) -> tuple[str, ...]:
    """``names`` if each is a motion of the body (its mesh files, or the motion library)."""
    if body.model == "meshes":
        missing = [n for n in names if n not in dict(body.meshes)]
        if missing:
            raise unknown("motion", missing[0], dict(body.meshes))
    else:
        for n in names:
            library.get(n)
    if not names:
        raise KgarmentError("[motions] use = [] lists no motion")
    dup = sorted({n for n in names if names.count(n) > 1})
    if dup:
        raise KgarmentError(f"[motions] use lists {dup[0]!r} more than once")
    return names


def _garment(g: dict, base: Path) -> GarmentSpec:
    check_keys("garment", g, ("template", "mask", "attach", "subdivision"))
    sub = _subdivision(g.get("subdivision", 1))
    if "mask" in g:
        attach = g.get("attach", [])
        if not isinstance(attach, list) or not all(isinstance(a, str) for a in attach):
            raise KgarmentError(f"[garment] attach = {attach!r} must be a list of attachment loop names, e.g. "
                                "attach = [\"wrist.R\"]")
        return GarmentSpec(None, _path(base, g["mask"], "garment.mask"), tuple(attach), sub)
    t = g.get("template", "short_sleeve_shirt")
    if t not in template_names():
        raise unknown("garment", t, template_names())
    if "attach" in g:  # a template glues its own rings
        raise KgarmentError("[garment] attach is for a garment given by mask; a template's attachment rings are "
                            "its own (leave attach out, or give mask = FILE)")
    return GarmentSpec(t, None, (), sub)


def _subdivision(sub) -> int:
    if isinstance(sub, float) and sub.is_integer():
        sub = int(sub)
    if isinstance(sub, bool) or not isinstance(sub, int) or sub not in C.SUBDIVISIONS:
        raise KgarmentError(f"[garment] subdivision = {sub!r}; allowed: {', '.join(map(str, C.SUBDIVISIONS))}")
    return sub


def _design(d: dict) -> DesignSpec:
    """[design]: the objective, protection and the BESO fields (flat keys) -> DesignSpec."""
    beso_keys = {f.name for f in dataclasses.fields(BesoParams)}
    tables = ["balance", "levels", "early", "weights"]
    own = {f.name for f in dataclasses.fields(DesignSpec)} - {"beso", *tables}
    check_keys("design", d, sorted(own) + tables
               + [f.name for f in dataclasses.fields(BesoParams)])
    ranges = C.DESIGN_RANGES
    beso = section(BesoParams, "design", {k: v for k, v in d.items() if k in beso_keys}, {"filter": FILTERS}, ranges)
    rest = section(_DesignOwn, "design", {k: v for k, v in d.items() if k in own},
                   {"objective": OBJECTIVE_NAMES, "combine": COMBINE_NAMES}, ranges)
    return DesignSpec(beso=beso, **asdict(rest), levels=_levels(d.get("levels", [])),
                      early=_table("early", d.get("early", {}), "share", lambda t: 0.0 < t < 1.0, "a number in (0, 1)",
                                   '{ "arm_flexion.right" = 0.33 }'),
                      weights=_table("weights", d.get("weights", {}), "weight", lambda w: 0.0 < w <= MOTION_WEIGHT_MAX,
                                     f"a number in (0, {MOTION_WEIGHT_MAX:g}]", '{ "arm_extension.right" = 1.5 }'),
                      balance=_balance(d.get("balance", 0.0)))


def _balance(v) -> float | tuple[tuple[str, float], ...]:
    """[design] balance = w, or {MOTION = w, ...}: each w in the allowed range (the motions
    are checked against [motions] use in :func:`parse_problem`)."""
    lo, hi = C.DESIGN_RANGES["balance"]
    allowed = f"a number in [{lo:g}, {hi:g}]"
    if isinstance(v, dict):
        return _table("balance", v, "weight", lambda w: lo <= w <= hi, allowed, "")
    if isinstance(v, (int, float)) and not isinstance(v, bool) and lo <= v <= hi:
        return float(v)
    raise KgarmentError(f"[design] balance = {v!r} must be {allowed} (every motion) or a table "
                        'of motion = weight, e.g. { "arms_raise" = 2.0 }')


def _table(key: str, v, what: str, ok, allowed: str, example: str) -> tuple[tuple[str, float], ...]:
    """[design] KEY = {MOTION = value, ...}: each value (a ``what``) a number for which ``ok``
    holds (``allowed`` says which; the motions are checked against [motions] use in
    :func:`parse_problem`)."""
    if not isinstance(v, dict):
        raise KgarmentError(f"[design] {key} = {v!r} must be a table of motion = {what} ({allowed}), e.g. {example}")
    for m, t in v.items():
        if isinstance(t, bool) or not isinstance(t, (int, float)) or not ok(t):
            raise KgarmentError(f"[design] {key}: {m} = {t!r}; the {what} must be {allowed}")
    return tuple((str(m), float(t)) for m, t in v.items())


def _levels(v) -> tuple[int, ...]:
    """[design] levels: coarser subdivision levels, increasing (checked against the garment's
    level in :func:`_check_levels`)."""
    if not isinstance(v, list) or any(isinstance(x, bool) or not isinstance(x, int) for x in v):
        raise KgarmentError(f"[design] levels = {v!r} must be a list of subdivision levels, e.g. [0]")
    if any(x not in C.SUBDIVISIONS for x in v) or list(v) != sorted(set(v)):
        raise KgarmentError(f"[design] levels = {v!r} must be increasing levels out of "
                            f"{', '.join(map(str, C.SUBDIVISIONS))}")
    return tuple(v)


def _check_levels(levels: tuple[int, ...], subdivision: int) -> None:
    if levels and levels[-1] >= subdivision:
        raise KgarmentError(f"[design] levels = {list(levels)}: each must be below the garment's subdivision "
                            f"{subdivision} (the level the design finishes at)")


@dataclasses.dataclass(frozen=True)
class _DesignOwn:
    """The [design] fields that are not BESO parameters (for validation)."""

    objective: str = "active"
    protect_attachments: bool = False
    protect_clutch_margin: float = 0.0
    lockout: float = 0.0
    guard: float = 0.0
    combine: str = "sum"


HARDWARE = ("model", "holding_stress", "voltage", "dielectric_thickness", "permittivity", "friction",
            "holding_force", "buckle", "channel")


def _hardware(c: dict) -> ClutchHardware:
    """The clutch hardware keys of [clutches]: a holding force, stress or voltage implies
    ``model = "slip"``; with ``model = "locked"`` they are refused (they would do nothing)."""
    given = {k: c[k] for k in HARDWARE if k in c and k not in ("model", "holding_force")}
    holds = [k for k in ("holding_stress", "voltage", "holding_force") if k in c]
    model = c.get("model", "slip" if holds else "locked")
    hw = section(ClutchHardware, "clutches", {**given, "model": model}, {"model": C.CLUTCH_MODELS}, C.CLUTCH_RANGES)
    if model == "locked" and holds:
        raise KgarmentError(f"[clutches] {holds[0]} does nothing with model = \"locked\" (clutches that never "
                            "slip); use model = \"slip\" or leave it out")
    if "holding_stress" in c and "voltage" in c:
        raise KgarmentError("[clutches] holding_stress and voltage both set the holding stress; give one")
    if "voltage" in c and hw.voltage <= 0:
        raise KgarmentError(f"[clutches] voltage = {hw.voltage!r} must be > 0")
    force = c.get("holding_force")
    if force is None:
        return hw
    if not isinstance(force, dict):
        force = {"*": force}
    lo, hi = C.CLUTCH_RANGES["holding_force"]
    pairs = []
    for name, v in force.items():
        where = "[clutches] holding_force" + ("" if name == "*" else f".{name}")
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
            raise KgarmentError(f"{where} = {v!r} must be a number of newtons, or a table {{clutch = newtons}}")
        if not lo <= v <= hi:
            raise KgarmentError(f"{where} = {v!r} is outside [{lo:g}, {hi:g}] N")
        pairs.append((str(name), float(v)))
    return dataclasses.replace(hw, holding_force=tuple(pairs))


def _clutches(c: dict, base: Path) -> ClutchesSpec:
    check_keys("clutches", c, ("layout", "file", "clutch", "side") + HARDWARE)
    layout = c.get("layout")
    if layout is not None and layout not in LAYOUTS:
        raise unknown("clutch layout", layout, LAYOUTS)
    side = c.get("side", "R")
    if side not in ("L", "R"):
        raise KgarmentError(f"[clutches] side = {side!r}; allowed: L, R")
    f = _path(base, c["file"], "clutches.file") if "file" in c else None
    recs = c.get("clutch", [])
    if not isinstance(recs, list):
        raise KgarmentError("[clutches] clutch must be an array of tables ([[clutches.clutch]])")
    inline = tuple(clutch_spec_from_record(r, k, "[clutches]") for k, r in enumerate(recs))
    default = layout is None and f is None and "clutch" not in c
    return ClutchesSpec(layout, f, inline, side, _hardware(c), default)


def override(problem: Problem, *, motions=None, template: str | None = None, subdivision: int | None = None,
             preset: str | None = None, method: str | None = None, tol: float | None = None,
             max_iterations: int | None = None, clutch_model: str | None = None,
             holding_force: float | None = None, buckle: bool | None = None, refine: bool = False,
             friction: float | None = None, channel: bool | None = None) -> Problem:
    """``problem`` with command-line overrides (None: keep the file's), validated with the
    same rules and messages as the problem file's fields."""
    changes: dict = {}
    if motions:
        changes["motions"] = _check_motions(tuple(motions), problem.body, problem.library())
        changes["activation"] = tuple((m, v) for m, v in problem.activation if m in changes["motions"])
    g = problem.garment
    if template is not None:
        g = _garment({"template": template, "subdivision": g.subdivision}, Path("."))
    if subdivision is not None:
        g = dataclasses.replace(g, subdivision=_subdivision(subdivision))
    changes["garment"] = g
    if preset is not None or friction is not None:
        mats = {**asdict(problem.materials), **{k: v for k, v in (("preset", preset), ("skin_friction", friction))
                                                 if v is not None}}
        changes["materials"] = section(MaterialSpec, "materials", mats, {"preset": PRESET_NAMES}, MATERIAL_RANGES)
    solver = {k: v for k, v in (("method", method), ("tol", tol)) if v is not None}
    if solver:
        solver = {**asdict(problem.solver), **solver}
        changes["solver"] = section(SolverSpec, "solver", solver, {"method": METHODS}, C.SOLVER_RANGES)
    if max_iterations is not None:
        beso = {**asdict(problem.design.beso), "max_iterations": max_iterations}
        beso = section(BesoParams, "design", beso, {"filter": FILTERS}, C.DESIGN_RANGES)
        changes["design"] = dataclasses.replace(problem.design, beso=beso)
    if refine:  # coarse-to-fine from level 0 (kgarment.optimize.refine)
        if problem.body.phenotypes:
            raise KgarmentError("--refine: coarse-to-fine is for one body, not a multi-body design ([body] phenotypes)")
        d = changes.get("design", problem.design)
        changes["design"] = dataclasses.replace(d, levels=tuple(range(changes["garment"].subdivision)))
    if clutch_model is not None or holding_force is not None or buckle is not None or channel is not None:
        c = problem.clutch_spec()
        raw = c.hardware.to_dict()
        if clutch_model == "locked":  # the file's holding force or stress does nothing then
            raw = {k: v for k, v in raw.items() if k not in ("holding_stress", "voltage", "holding_force")}
        if clutch_model is not None:
            raw["model"] = clutch_model
        if holding_force is not None:
            raw["holding_force"] = holding_force
        raw.update({k: bool(v) for k, v in (("buckle", buckle), ("channel", channel)) if v is not None})
        changes["clutches"] = dataclasses.replace(c, hardware=_hardware(raw), default=False)
    return dataclasses.replace(problem, **changes)
