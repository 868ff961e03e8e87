"""The problem as frozen dataclasses: body, motions, garment, clutches, design, solver, materials.

Parsed once from a TOML file (:mod:`kgarment.problem.parse`); everything else reads these.
Defaults and ranges come from :mod:`kgarment.constants`.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, field
from pathlib import Path

from kgarment import constants as C
from kgarment.body import Motion, MotionLibrary, Phenotype

DEFAULT_MOTIONS = ("arms_forward", "arms_raise", "bend_forward")
DEFAULT_LAYOUT = {"short_sleeve_shirt": "shirt", "long_sleeve_shirt": "long_sleeve", "arm_sleeve": "sleeve"}
OBJECTIVE_NAMES = ("active", "passive", "compliance")
COMBINE_NAMES = ("sum", "product")
FILTERS = ("one_ring", "radius")
PRESET_NAMES = C.PRESET_NAMES
METHODS = ("newton", "lbfgs")


@dataclass(frozen=True)
class BodySpec:
    """[body]: ``model`` "anny" (with a phenotype) or "meshes" (posed mesh files).

    phenotypes : ((name, Phenotype), ...) the wearers of a multi-body design (``[body]
    phenotypes``; two or more, names unique), the first of which is ``phenotype``: the body
    the garment is cut from; () for one body.
    """

    model: str = "anny"
    phenotype: Phenotype = field(default_factory=Phenotype)
    rest: Path | None = None
    rig: Path | None = None
    meshes: tuple[tuple[str, Path], ...] = ()
    phenotypes: tuple[tuple[str, Phenotype], ...] = ()

    @property
    def names(self) -> tuple[str, ...]:
        """The wearers' names (() for one body)."""
        return tuple(n for n, _ in self.phenotypes)


@dataclass(frozen=True)
class GarmentSpec:
    """[garment]: a template name, or a face mask with the boundary loops to attach."""

    template: str | None = "short_sleeve_shirt"
    mask: Path | None = None
    attach: tuple[str, ...] = ()
    subdivision: int = 1


@dataclass(frozen=True)
class ClutchHardware:
    """[clutches] hardware: how an ON clutch holds (``kgarment.sim.slip``).

    model : "locked" (the paper's: an ON clutch never slips), "slip" (it holds up to its
        holding force and slides at it beyond) or "cable" (as slip, but the strip carries one
        pull-only force between its ends, ``kgarment.sim.cable``: slack when shortened on the
        whole however its parts are stretched).
    holding_stress : Pa of overlap (width x length) a clutch holds (21 N/cm^2 measured).
    voltage : V; > 0: the holding stress from the parallel-plate formula with
        ``dielectric_thickness`` (m), ``permittivity`` (relative) and ``friction``.
    holding_force : ((clutch name or "*", N), ...) overriding the stress per clutch.
    buckle : ON clutch strips take no compression (they buckle, as the cloth wrinkles: the
        wrinkling relaxation on the strips too, and a slipping clutch's slider pulls only);
        False is the paper's model, where a clutch resists being shortened with its full
        stiffness (a 0.35 mm strip 1 cm wide buckles at well under 1 N).
    channel : each clutch runs in a channel of the connecting material sewn along it to the
        garment: its centre line is held to the garment as stiffly as reinforced fabric
        (``kgarment.sim.model``, ``tie``), where without a channel (the paper's build: the
        clutch snapped on at its two ends) it is held only weakly and a strip pulled taut over
        a bent elbow can roll off sideways, restrained by skin friction alone.
    """

    model: str = "locked"
    holding_stress: float = C.HOLDING_STRESS
    voltage: float = 0.0
    dielectric_thickness: float = C.DIELECTRIC_THICKNESS
    permittivity: float = C.DIELECTRIC_PERMITTIVITY
    friction: float = C.CLUTCH_FRICTION
    holding_force: tuple[tuple[str, float], ...] = ()
    buckle: bool = False
    channel: bool = False

    def __str__(self) -> str:
        return ", ".join(f"{k} {v}" for k, v in self.to_dict().items()) or "model locked"

    def to_dict(self) -> dict:
        """The fields that differ from the defaults (TOML-ready; {} for the default)."""
        base = ClutchHardware()
        out = {k: v for k, v in asdict(self).items() if v != getattr(base, k) and k != "holding_force"}
        if self.holding_force:
            out["holding_force"] = (self.holding_force[0][1] if self.holding_force[0][0] == "*"
                                    else dict(self.holding_force))
        return out


@dataclass(frozen=True)
class ClutchesSpec:
    """[clutches]: a default layout by name, a clutch file, and/or inline clutches (none of
    them: the garment's default layout), and the clutch hardware."""

    layout: str | None = None
    file: Path | None = None
    inline: tuple = ()
    side: str = "R"
    hardware: ClutchHardware = field(default_factory=ClutchHardware)
    default: bool = False  # the section names no clutches (only hardware): the default layout


@dataclass(frozen=True)
class BesoParams:
    """BESO settings (the paper's defaults; the manual's method page, docs/method/index.md).

    target_area : A*, reinforced area fraction to reach (0.15; 0.20 for the sleeve).
    er : evolution ratio, the target area shrinks by this fraction per iteration.
    ar_max : at most this fraction of the faces may be added per iteration.
    filter : "one_ring" (paper) or "radius" (classic BESO mesh-independent filter).
    radius : filter radius in metres for "radius".
    history : average sensitivities with the previous iteration's (halves flicker).
    tol, window : converged when the target is reached and the objective changed less than
        ``tol`` (relative) over ``window`` iterations.
    max_iterations : hard stop.
    connected : repair every update into one part holding every clutch end
    (:mod:`kgarment.optimize.connect`); False is the paper's plain BESO.
    settle : once the target area is reached, the faces that may be added per iteration
    halve every ``settle`` iterations at the target (``ar_max`` 2^(-k / settle) after k),
    so that the exchange cools down and the run settles (0: off, the paper's BESO;
    :func:`kgarment.optimize.beso.settled_ar`).

    The material interpolation (``p``, ``x_min``) is the simulator's
    (:data:`kgarment.constants.PENALTY`, :data:`kgarment.constants.X_MIN`).
    """

    target_area: float = C.TARGET_AREA
    er: float = C.ER
    ar_max: float = C.AR_MAX
    filter: str = "one_ring"
    radius: float = C.FILTER_RADIUS
    history: bool = True
    tol: float = C.CONVERGENCE_TOL
    window: int = C.WINDOW
    max_iterations: int = C.MAX_ITERATIONS
    connected: bool = True
    settle: int = 0

    def reached(self, area: float) -> bool:
        """Whether the reinforced area share ``area`` is at A* (:func:`kgarment.constants.target_reached`)."""
        return C.target_reached(area, self.target_area, self.er)


MOTION_WEIGHT_MAX = 10.0  # [design] weights: the largest weight of a motion


@dataclass(frozen=True)
class DesignSpec:
    """[design]: the objective, the BESO parameters and what is kept reinforced.

    objective : "active" (the paper: ON - OFF), "passive" (EG 2022, no clutches) or
    "compliance" (ON only);  beso : BesoParams (its fields are flat keys of [design]);
    protect_attachments : keep the attachment rings reinforced;
    protect_clutch_margin : metres around clutch anchors kept reinforced (0: off);
    lockout : weight of the penalty on the energy that other motions' activation sets
    store in a motion (0: none; :mod:`kgarment.optimize.objective`);
    balance : weight of the reward for every clutch of a motion's set carrying load on its
    own (``solo:`` states; 0: none; :mod:`kgarment.optimize.objective`), every motion the
    same, or ((motion, weight), ...) for the motions named only (a table in the file: the
    solo states cost one solve per clutch and motion, so a five-motion garment can reward
    its clutches in the one motion each should carry);
    levels : coarser subdivision levels to design at first, increasing, each below the
    garment's (coarse-to-fine, :mod:`kgarment.optimize.refine`); () designs at the garment's
    level throughout;  guard : a BESO step after which some motion's objective term falls
    by more than this share is taken back (0: off; :mod:`kgarment.optimize.guard`);
    combine : how the motions' terms make the objective: "sum" (the paper's) or
    "product" (each motion's sensitivities weighted by the inverse of its term, so that no
    motion is given up for the others; :mod:`kgarment.optimize.objective`);  early :
    ((motion, t), ...) motions also designed for at the share t in (0, 1) of their
    movement (the body posed part of the way; one more motion ``MOTION@t`` of the design
    objective, ON with the motion's clutch set and OFF; design runs only, evaluations stay
    at the target poses): a design that holds the beginning of the motion anchors its
    clutches before the end can find another equilibrium;
    weights : ((motion, w), ...) each named motion's weight in the objective, w > 0 (a
    motion not named: 1; its early poses share it): a designer's priorities where the
    paper counts every motion equally (:mod:`kgarment.optimize.objective`).
    """

    objective: str = "active"
    beso: BesoParams = field(default_factory=BesoParams)
    protect_attachments: bool = False
    protect_clutch_margin: float = 0.0
    lockout: float = 0.0
    balance: float | tuple[tuple[str, float], ...] = 0.0
    levels: tuple[int, ...] = ()
    guard: float = 0.0
    combine: str = "sum"
    early: tuple[tuple[str, float], ...] = ()
    weights: tuple[tuple[str, float], ...] = ()

    def flat(self) -> dict:
        """The [design] table as written in a problem file (BESO fields flattened)."""
        out = {"objective": self.objective, **asdict(self.beso)}
        if not self.beso.settle:  # written only when used: problem files and hashes of earlier runs stay
            del out["settle"]
        out.update(protect_attachments=self.protect_attachments, protect_clutch_margin=self.protect_clutch_margin,
                   lockout=self.lockout)
        if self.balance:  # written only when used: problem files and hashes of earlier runs stay as they were
            out["balance"] = dict(self.balance) if isinstance(self.balance, tuple) else self.balance
        if self.levels:
            out["levels"] = list(self.levels)
        if self.guard:
            out["guard"] = self.guard
        if self.combine != "sum":
            out["combine"] = self.combine
        if self.early:
            out["early"] = dict(self.early)
        if self.weights:
            out["weights"] = dict(self.weights)
        return out

    def balance_of(self, motion: str) -> float:
        """The balance weight of ``motion`` (a motion name of [motions] use)."""
        return balance_weight(self.balance, motion)


def balance_weight(balance, motion: str) -> float:
    """The balance weight of ``motion`` from ``balance``: a number (every motion), a
    mapping or ((motion, weight), ...) (the motions named; others 0).  A design state's
    name ``MOTION@...`` (a wearer's, or the beginning of a motion) takes MOTION's weight."""
    if isinstance(balance, (int, float)):
        return float(balance)
    table = dict(balance)
    if motion in table:
        return float(table[motion])
    return float(table.get(motion.partition("@")[0], 0.0))


@dataclass(frozen=True)
class SolverSpec:
    """[solver]: simulator settings.

    tol : the scaled force residual of :class:`kgarment.sim.SolverOptions` (its module doc):
    the tolerance of iteration 0 (the fully reinforced garment, the reference of rho).  1e-3:
    a membrane without bending stiffness on a frictionless body has many nearly equal
    equilibria, so per-face energy densities are defined to about that accuracy and no
    better.  Evaluations (``kgarment evaluate``, ``simulate``, ``reproduce``, ``fabricate``,
    the studio) solve to ``min(tol, EVALUATION_TOL)`` (1e-4;
    :func:`kgarment.problem.solver_options`).
    evolution_tol : the tolerance of every design iteration after iteration 0; the final
    design is evaluated at ``min(tol, EVALUATION_TOL)``.  The ranking that moves the design
    needs sensitivities, not digits, and the objectives that decide convergence at A* are
    total energies, whose error is of second order in the residual.  Set it equal to
    ``tol`` to solve every iteration alike.
    max_iter : Newton iterations per state.
    skin_start : every design iteration also solves each state from the evaluator's two
    starts (the skin-tight garment and the fully reinforced garment's equilibrium) and keeps
    the lowest-energy equilibrium (the evaluator's rule, :mod:`kgarment.evaluate`), so that
    the run optimises the state the evaluation reports; triples the solves.  For clutches
    that a frictionless limb lets slide off the stretched side.
    path_start : every ``path_start``-th design iteration (0: never) also solves each ON state
    over its motion from rest as the evaluator does (``evaluate --path``: the design's rest
    equilibrium, ``path_frames`` frames each from the ones before, friction holding each
    where the one before left it, at the evaluator's tolerance;
    :func:`kgarment.optimize.motion_start.motion_ends`): the state a wearer reaches, which
    neither the warm-started path through the designs nor the two starts need find.  With
    ``skin_start`` the state becomes the evaluator's (the lower of its two starts and that
    end), without it the end is kept where lower by more than 1%; the later iterations start
    from it, and the guard does not judge an iteration whose state the check moved.  Needs a
    posable body.
    path_frames : the frames of that motion from rest (the last one the target pose), for the
    check and the run's final evaluation (``evaluate --path``'s count).  With skin friction
    the motion's end depends on it where the garment slips part way
    (``evaluate --path K --converge`` checks it).
    workers : processes solving states in parallel; 0 = one per core, at most 8 (results do
    not depend on it).

    Measurements behind these defaults: docs/notes/solver.md.
    """

    method: str = "newton"
    tol: float = C.DESIGN_TOL
    evolution_tol: float = C.EVOLUTION_TOL
    max_iter: int = C.MAX_NEWTON
    skin_start: bool = False
    path_start: int = 0
    path_frames: int = C.PATH_FRAMES
    workers: int = 0


@dataclass(frozen=True)
class MaterialSpec:
    """[materials]: ``preset`` "paper" (0.5 MPa / 0.5 GPa / 3 GPa, the paper's text) or
    "reference" (0.5 / 5.7 / 25.7 MPa, the reference implementation; kgarment.sim.materials);
    ``skin_friction``: the skin-garment friction coefficient (kgarment.sim.friction; 0, the
    default, is the paper's frictionless body; cloth on skin is about 0.3 to 0.6)."""

    preset: str = "paper"
    skin_friction: float = C.FRICTION


@dataclass(frozen=True)
class Problem:
    """A whole problem; ``clutches`` None means the garment's default layout;
    ``source`` is the file it was read from (None: built in)."""

    body: BodySpec = field(default_factory=BodySpec)
    motions: tuple[str, ...] = DEFAULT_MOTIONS
    user_motions: tuple[Motion, ...] = ()
    garment: GarmentSpec = field(default_factory=GarmentSpec)
    clutches: ClutchesSpec | None = None
    design: DesignSpec = field(default_factory=DesignSpec)
    solver: SolverSpec = field(default_factory=SolverSpec)
    materials: MaterialSpec = field(default_factory=MaterialSpec)
    source: Path | None = None
    activation: tuple[tuple[str, tuple[tuple[str, float], ...]], ...] = ()

    def activation_of(self, motion: str) -> dict[str, float] | None:
        """{clutch name: activation in [0, 1]} switched on in ``motion``
        ([motions.activation]); None: every clutch (the default)."""
        return next((dict(v) for m, v in self.activation if m == motion), None)

    def library(self) -> MotionLibrary:
        return MotionLibrary({m.name: m for m in self.user_motions})

    def motion_list(self) -> list[Motion]:
        lib = self.library()
        return [lib.get(n) for n in self.motions]

    def clutch_spec(self) -> ClutchesSpec:
        """The clutches section, or the garment template's default layout when absent."""
        if self.clutches is not None and not self.clutches.default:
            return self.clutches
        t = (self.garment.template or "").split(".")[0]
        side = "L" if (self.garment.template or "").endswith(".left") else "R"
        hw = self.clutches.hardware if self.clutches is not None else ClutchHardware()
        return ClutchesSpec(layout=DEFAULT_LAYOUT.get(t), side=side, hardware=hw)

    def describe(self) -> str:
        """The resolved problem, in full, for the start of a run."""
        lines = [f"problem: {self.source or '(built-in default)'}", f"body: {self.body.model}"]
        if self.body.phenotypes:
            lines += [f"  {n}: {asdict(ph)}" for n, ph in self.body.phenotypes]
        elif self.body.model == "anny":
            lines.append(f"  phenotype: {asdict(self.body.phenotype)}")
        else:
            lines.append(f"  rest: {self.body.rest}; rig: {self.body.rig}")
        lines.append(f"motions: {', '.join(self.motions)}")
        for m, v in self.activation:
            lines.append(f"  {m} switches on: " + ", ".join(n if a == 1.0 else f"{n} {a:g}" for n, a in v))
        g = self.garment
        lines.append(f"garment: {g.template or g.mask}; subdivision {g.subdivision}"
                     + (f"; attach {list(g.attach)}" if g.attach else ""))
        c = self.clutch_spec()
        parts = ([f"layout {c.layout} ({c.side})"] if c.layout else []) + ([f"file {c.file}"] if c.file else []) \
            + ([f"{len(c.inline)} inline"] if c.inline else [])
        lines.append(f"clutches: {'; '.join(parts) or 'none'}" + (f"; {c.hardware}" if c.hardware.to_dict() else ""))
        lines.append("design: " + ", ".join(f"{k} {v}" for k, v in self.design.flat().items()))
        lines.append("solver: " + ", ".join(f"{k} {v}" for k, v in asdict(self.solver).items()))
        lines.append(f"materials: preset {self.materials.preset}"
                     + (f"; skin friction {self.materials.skin_friction:g}" if self.materials.skin_friction else ""))
        return "\n".join(lines)
