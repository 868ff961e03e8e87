"""Problem files (TOML): body, motions and garment, parsed once into frozen dataclasses.

Example::

    [body]
    model = "anny"                      # or "meshes"
    phenotype = { height = 0.6 }        # each in [0, 1]
    # model = "meshes": rest = "rest.obj", rig = "rig.npz" (optional),
    #                   motions = { arm_flexion = "flexion.obj" }

    [motions]
    use = ["arms_forward", "arms_raise", "bend_forward"]

    [motions.define.wave]               # a user motion (bone -> rotation about a named axis)
    rotations = [{ bone = "upperarm01.L", axis = "-y", degrees = 60 }]
    # or keyframes = [[{...}, ...], [{...}, ...]] for an animated sequence

    [garment]
    template = "short_sleeve_shirt"     # or mask = "faces.npy" with attach = ["opening0"]
    subdivision = 1

    [clutches]
    layout = "shirt"                    # a default layout (see kgarment.clutch.layouts)
    # file = "clutches.toml"            # a portable clutch file
    [[clutches.clutch]]                 # and/or inline clutches
    name = "extra"
    start = "upper_back"                # a landmark, or [x, y, z] in rest coordinates
    towards = "shoulder_top.L"          # or direction = [x, y, z]
    length = 0.08                       # metres; width = 0.01, prestrain = 1.0

Relative paths are relative to the problem file.
"""

from __future__ import annotations

import tomllib
from dataclasses import asdict, dataclass, field
from pathlib import Path

from kgarment.body import Body, Motion, MotionLibrary, Phenotype, Rotation, load_anny_body, load_mesh_sequence
from kgarment.body.motions import NAMED_AXES, PAPER_MOTIONS
from kgarment.errors import KgarmentError, unknown
from kgarment.garment import Garment, garment_from_mask, load_face_mask, make_garment, template_names

DEFAULT_MOTIONS = ("arms_forward", "arms_raise", "bend_forward")
DEFAULT_LAYOUT = {"short_sleeve_shirt": "shirt", "long_sleeve_shirt": "long_sleeve", "arm_sleeve": "sleeve"}


@dataclass(frozen=True)
class BodySpec:
    model: str = "anny"
    phenotype: Phenotype = field(default_factory=Phenotype)
    rest: Path | None = None
    rig: Path | None = None
    meshes: tuple[tuple[str, Path], ...] = ()


@dataclass(frozen=True)
class GarmentSpec:
    template: str | None = "short_sleeve_shirt"
    mask: Path | None = None
    attach: tuple[str, ...] = ()
    subdivision: int = 1


@dataclass(frozen=True)
class ClutchesSpec:
    """Clutches: a default layout by name, a clutch file, and/or inline clutches."""

    layout: str | None = None
    file: Path | None = None
    inline: tuple = ()
    side: str = "R"

    @property
    def empty(self) -> bool:
        return self.layout is None and self.file is None and not self.inline


@dataclass(frozen=True)
class DesignSpec:
    """[design]: the objective and BESO parameters (see kgarment.design.beso.BesoParams)."""

    objective: str = "active"
    target_area: float = 0.15
    er: float = 0.015
    ar_max: float = 0.015
    filter: str = "one_ring"
    radius: float = 0.02
    history: bool = True
    tol: float = 1e-3
    window: int = 5
    max_iterations: int = 200
    protect_attachments: bool = False
    protect_clutch_margin: float = 0.0  # metres around clutch anchors kept reinforced (0: off)


@dataclass(frozen=True)
class SolverSpec:
    """[solver] and [materials]: simulator settings.

    tol : the scaled force residual of :class:`kgarment.sim.SolverOptions` (its module doc).
    1e-3 for design iterations: the equilibria are only defined to about that accuracy.
    ``benchmarks/accuracy.py`` (three-motion shirt, subdivision 0, 6 states after a BESO-like
    design change): per-face energy densities at 1e-3 are within 0.3% (median over states;
    1.9% at most) of a 1e-7 solve, while solves that all *converge* to 1e-5 with other
    solver settings land up to 0.35-2.4% apart: a membrane without bending stiffness on a
    frictionless body has many nearly equal equilibria (slack cloth, wrinkles, sliding).
    The main job at 1e-3 and at 1e-4 ends with designs 4 faces (of 3,229) apart, rho ON
    within 1% when both are evaluated at 1e-5, in 2.5x less time.  Evaluations
    (``kgarment evaluate``, ``kgarment reproduce``, the studio) solve to
    ``min(tol, EVALUATION_TOL)`` (1e-4).
    evolution_tol : the tolerance while the BESO target area is still changing (iterations
    1 until A* is reached; iteration 0, the reference of rho, and every iteration at A*,
    whose objectives decide convergence, solve to ``tol``).  The ranking that moves the
    design towards A* needs sensitivities, not digits (Amir & Sigmund 2011, "On reducing
    computational effort in topology optimization: how accurate should the analysis
    be?"); ``benchmarks/design.py`` measures what it costs and buys.  Set it equal to
    ``tol`` to solve every iteration alike.
    workers : processes solving states in parallel; 0 = one per core, at most 8 (results do
    not depend on it).
    """

    preset: str = "paper"
    method: str = "newton"
    tol: float = 1e-3
    evolution_tol: float = 1e-2
    max_iter: int = 200
    workers: int = 0


@dataclass(frozen=True)
class Problem:
    body: BodySpec = field(default_factory=BodySpec)
    motions: tuple[str, ...] = DEFAULT_MOTIONS
    user_motions: tuple[Motion, ...] = ()
    garment: GarmentSpec = field(default_factory=GarmentSpec)
    clutches: ClutchesSpec | None = None  # None: the garment's default layout
    design: DesignSpec = field(default_factory=DesignSpec)
    solver: SolverSpec = field(default_factory=SolverSpec)
    source: Path | None = None

    def library(self) -> MotionLibrary:
        return MotionLibrary({m.name: m for m in self.user_motions})

    def motion_list(self) -> list[Motion]:
        lib = self.library()
        return [lib.get(n) for n in self.motions]

    def clutch_spec(self) -> ClutchesSpec:
        """The clutches section, or the garment template's default layout when absent."""
        if self.clutches is not None:
            return self.clutches
        t = (self.garment.template or "").split(".")[0]
        side = "L" if (self.garment.template or "").endswith(".left") else "R"
        return ClutchesSpec(layout=DEFAULT_LAYOUT.get(t), side=side)

    def describe(self) -> str:
        """The resolved problem, in full, for the start of a run."""
        lines = [f"problem: {self.source or '(built-in default)'}", f"body: {self.body.model}"]
        if self.body.model == "anny":
            lines.append(f"  phenotype: {asdict(self.body.phenotype)}")
        else:
            lines.append(f"  rest: {self.body.rest}; rig: {self.body.rig}")
        lines.append(f"motions: {', '.join(self.motions)}")
        g = self.garment
        lines.append(f"garment: {g.template or g.mask}; subdivision {g.subdivision}" + (f"; attach {list(g.attach)}" if g.attach else ""))
        c = self.clutch_spec()
        parts = ([f"layout {c.layout} ({c.side})"] if c.layout else []) + ([f"file {c.file}"] if c.file else []) \
            + ([f"{len(c.inline)} inline"] if c.inline else [])
        lines.append(f"clutches: {'; '.join(parts) or 'none'}")
        lines.append("design: " + ", ".join(f"{k} {v}" for k, v in asdict(self.design).items()))
        lines.append("solver: " + ", ".join(f"{k} {v}" for k, v in asdict(self.solver).items()))
        return "\n".join(lines)


def _check_keys(section: str, d: dict, allowed) -> None:
    bad = set(d) - set(allowed)
    if bad:
        raise KgarmentError(f"[{section}]: unknown field {sorted(bad)[0]!r}; allowed: {', '.join(allowed)}")


def _path(base: Path, p, what: str) -> Path:
    if not isinstance(p, str):
        raise KgarmentError(f"{what} must be a file path string")
    q = Path(p)
    q = q if q.is_absolute() else base / q
    if not q.exists():
        raise KgarmentError(f"{what}: file not found: {q}")
    return q


def _rotation(d, where: str) -> Rotation:
    if not isinstance(d, dict):
        raise KgarmentError(f"{where}: a rotation is a table {{bone, axis, degrees}}")
    _check_keys(where, d, ("bone", "axis", "degrees"))
    if "bone" not in d or "degrees" not in d:
        raise KgarmentError(f"{where}: a rotation needs bone and degrees")
    axis = d.get("axis", "x")
    if isinstance(axis, list):
        axis = tuple(float(a) for a in axis)
    elif axis not in NAMED_AXES:
        raise unknown(f"axis in {where}", axis, NAMED_AXES)
    return Rotation(str(d["bone"]), axis, float(d["degrees"]))


def _user_motion(name: str, d: dict) -> Motion:
    where = f"motions.define.{name}"
    _check_keys(where, d, ("rotations", "keyframes", "description"))
    if ("rotations" in d) == ("keyframes" in d):
        raise KgarmentError(f"[{where}]: give either rotations or keyframes")
    frames = [d["rotations"]] if "rotations" in d else d["keyframes"]
    kfs = tuple(tuple(_rotation(r, where) for r in kf) for kf in frames)
    if not kfs or not all(kfs):
        raise KgarmentError(f"[{where}]: a motion needs at least one rotation")
    return Motion(name, kfs, str(d.get("description", "user motion")))


def parse_problem(data: dict, base: Path = Path("."), source: Path | None = None) -> Problem:
    """Validate a parsed TOML dict into a :class:`Problem` (errors name the field)."""
    known = ("body", "motions", "garment", "clutches", "materials", "design", "solver")
    _check_keys("problem", data, known)
    b = data.get("body", {})
    _check_keys("body", b, ("model", "phenotype", "rest", "rig", "motions"))
    model = b.get("model", "anny")
    if model not in ("anny", "meshes"):
        raise unknown("body model", model, ("anny", "meshes"))
    if model == "anny":
        body = BodySpec("anny", Phenotype.from_dict(b.get("phenotype", {})))
    else:
        if "rest" not in b or "motions" not in b:
            raise KgarmentError("[body] model = 'meshes' needs rest = FILE and motions = {name = FILE}")
        meshes = tuple((k, _path(base, v, f"body.motions.{k}")) for k, v in b["motions"].items())
        body = BodySpec("meshes", Phenotype(), _path(base, b["rest"], "body.rest"),
                        _path(base, b["rig"], "body.rig") if "rig" in b else None, meshes)
    m = data.get("motions", {})
    _check_keys("motions", m, ("use", "define"))
    user = tuple(_user_motion(k, v) for k, v in m.get("define", {}).items())
    if model == "meshes":
        names = tuple(m.get("use", [k for k, _ in body.meshes]))
        missing = [n for n in names if n not in dict(body.meshes)]
        if missing:
            raise unknown("motion", missing[0], dict(body.meshes))
    else:
        names = tuple(m.get("use", DEFAULT_MOTIONS))
        lib = MotionLibrary({u.name: u for u in user})
        for n in names:
            lib.get(n)
    if not names:
        raise KgarmentError("[motions] use = [] lists no motion")
    g = data.get("garment", {})
    _check_keys("garment", g, ("template", "mask", "attach", "subdivision"))
    sub = g.get("subdivision", 1)
    if sub not in (0, 1, 2, 3):
        raise KgarmentError(f"[garment] subdivision = {sub!r}; allowed: 0, 1, 2, 3")
    if "mask" in g:
        garment = GarmentSpec(None, _path(base, g["mask"], "garment.mask"), tuple(g.get("attach", ())), sub)
    else:
        t = g.get("template", "short_sleeve_shirt")
        if t not in template_names():
            raise unknown("garment", t, template_names())
        garment = GarmentSpec(t, None, (), sub)
    clutches = _clutches(data["clutches"], base) if "clutches" in data else None
    design = _section(DesignSpec, "design", data.get("design", {}), {
        "objective": ("active", "passive", "compliance"), "filter": ("one_ring", "radius")},
        {"target_area": (0.01, 1.0), "er": (1e-4, 0.5), "ar_max": (1e-4, 1.0), "radius": (1e-4, 1.0),
         "tol": (0.0, 1.0), "window": (1, 100), "max_iterations": (1, 100000),
         "protect_clutch_margin": (0.0, 0.2)})
    solver = dict(data.get("solver", {}))
    mats = data.get("materials", {})
    _check_keys("materials", mats, ("preset",))
    if "preset" in mats:
        solver["preset"] = mats["preset"]
    solver = _section(SolverSpec, "solver", solver, {"preset": ("paper", "reference"), "method": ("newton", "lbfgs")},
                      {"tol": (1e-14, 1.0), "evolution_tol": (1e-14, 1.0), "max_iter": (1, 100000),
                       "workers": (0, 256)})
    return Problem(body, names, user, garment, clutches, design, solver, source)


def _section(cls, name: str, d: dict, choices: dict, ranges: dict):
    """Validate a flat TOML table against a dataclass: known fields, types, choices, ranges."""
    import dataclasses

    fields = {f.name: f for f in dataclasses.fields(cls)}
    _check_keys(name, d, list(fields))
    out = {}
    for k, v in d.items():
        default = fields[k].default
        if isinstance(default, bool):
            if not isinstance(v, bool):
                raise KgarmentError(f"[{name}] {k} = {v!r}; allowed: true, false")
        elif isinstance(default, (int, float)):
            if isinstance(v, bool) or not isinstance(v, (int, float)):
                raise KgarmentError(f"[{name}] {k} = {v!r} must be a number")
            if isinstance(default, int) and not float(v).is_integer():
                raise KgarmentError(f"[{name}] {k} = {v!r} must be an integer")
            v = type(default)(v)
        if k in choices and v not in choices[k]:
            raise KgarmentError(f"[{name}] {k} = {v!r}; allowed: {', '.join(choices[k])}")
        if k in ranges and not ranges[k][0] <= v <= ranges[k][1]:
            raise KgarmentError(f"[{name}] {k} = {v!r} is outside [{ranges[k][0]:g}, {ranges[k][1]:g}]")
        out[k] = v
    return cls(**out)


def _clutches(c: dict, base: Path) -> ClutchesSpec:
    from kgarment.clutch.io import _spec
    from kgarment.clutch.layouts import LAYOUTS

    _check_keys("clutches", c, ("layout", "file", "clutch", "side"))
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
    inline = tuple(_spec(r, k, "[clutches]") for k, r in enumerate(recs))
    return ClutchesSpec(layout, f, inline, side)


def clutch_specs(problem: Problem, body: Body) -> list:
    """All the problem's clutch specs (layout, then file, then inline), names unique."""
    from kgarment.clutch.io import load_clutches
    from kgarment.clutch.layouts import default_layout

    c = problem.clutch_spec()
    specs = list(default_layout(c.layout, body, c.side)) if c.layout else []
    if c.file:
        specs += load_clutches(c.file)
    specs += list(c.inline)
    names = [s.name for s in specs]
    dup = sorted({n for n in names if names.count(n) > 1})
    if dup:
        raise KgarmentError(f"[clutches]: duplicate clutch names {dup}")
    return specs


def build_clutches(problem: Problem, body: Body, garment: Garment) -> list:
    """The problem's clutch strips on the garment (landmark names resolved on the body)."""
    from kgarment.clutch import MeshTopology, build_clutch
    from kgarment.clutch.landmarks import body_landmarks

    specs = clutch_specs(problem, body)
    if not specs:
        return []
    topo = MeshTopology(garment.rest_vertices, garment.faces)
    marks = body_landmarks(body) if body.rigged else None
    return [build_clutch(s, garment.rest_vertices, garment.faces, topology=topo, landmarks=marks) for s in specs]


def load_problem(path) -> Problem:
    """Read and validate a TOML problem file."""
    path = Path(path)
    if not path.is_file():
        raise KgarmentError(f"problem file not found: {path}")
    try:
        data = tomllib.loads(path.read_text())
    except tomllib.TOMLDecodeError as exc:
        raise KgarmentError(f"problem file {path} is not valid TOML: {exc}") from None
    return parse_problem(data, path.parent, path)


def build_body(problem: Problem) -> Body:
    if problem.body.model == "anny":
        return load_anny_body(problem.motion_list(), problem.body.phenotype)
    meshes = dict(problem.body.meshes)
    return load_mesh_sequence(problem.body.rest, {n: meshes[n] for n in problem.motions}, problem.body.rig)


def build_garment(problem: Problem, body: Body) -> Garment:
    g = problem.garment
    if g.template:
        return make_garment(body, g.template, g.subdivision)
    mask = load_face_mask(g.mask, len(body.faces))
    return garment_from_mask(body, mask, g.mask.stem, g.subdivision, g.attach)


__all__ = ["BodySpec", "ClutchesSpec", "DesignSpec", "SolverSpec", "GarmentSpec", "build_clutches", "clutch_specs", "PAPER_MOTIONS", "Problem", "build_body", "build_garment",
           "load_problem", "parse_problem"]


def problem_to_dict(problem: Problem, clutch_file: Path | None = None) -> dict:
    """The resolved problem as a TOML-ready dict (paths absolute) that ``parse_problem``
    reads back to an equal problem; clutches are referenced by ``clutch_file`` when given."""
    b = problem.body
    body: dict = {"model": b.model}
    if b.model == "anny":
        body["phenotype"] = asdict(b.phenotype)
    else:
        body["rest"] = str(Path(b.rest).resolve())
        body["motions"] = {k: str(Path(v).resolve()) for k, v in b.meshes}
        if b.rig:
            body["rig"] = str(Path(b.rig).resolve())
    motions: dict = {"use": list(problem.motions)}
    if problem.user_motions:
        motions["define"] = {
            m.name: {"keyframes": [[{"bone": r.bone, "axis": r.axis if isinstance(r.axis, str) else list(r.axis),
                                     "degrees": r.degrees} for r in kf] for kf in m.keyframes],
                     "description": m.description} for m in problem.user_motions}
    g = problem.garment
    garment: dict = {"subdivision": g.subdivision}
    if g.template:
        garment["template"] = g.template
    else:
        garment["mask"] = str(Path(g.mask).resolve())
        garment["attach"] = list(g.attach)
    out = {"body": body, "motions": motions, "garment": garment,
           "design": asdict(problem.design), "solver": asdict(problem.solver)}
    if clutch_file is not None:
        out["clutches"] = {"file": str(Path(clutch_file).resolve())}
    return out
