"""Every tolerance, margin, default and range kgarment uses, in one place (SI units).

Other modules import these names instead of repeating the numbers: the problem file's
defaults and validation ranges (:mod:`kgarment.problem`), the simulator's library default
(:class:`kgarment.sim.SolverOptions`), the design loop's "target reached" test and the
evaluation tolerance all read them from here.
"""

from __future__ import annotations

import re

# ----- design variable (the manual's method page, docs/method/index.md, "BESO") ------------
X_MIN = 1e-3      # soft-kill minimum: the design value of plain cloth
PENALTY = 1.6     # material interpolation exponent p: Y(d) = d^p Y1 + (1 - d^p) Y0

# ----- solver tolerances: the scaled force residual of kgarment.sim.options --------------------
# The simulation model's version: what a run's checkpoint and a reproduction's data record, so
# that a run is not resumed, nor a report extended, under other physics.  1: the skin-tight
# garment and the attachment targets on the body's mesh; 2 (2026-11-26): both moved onto its
# contact surface (kgarment.sim.contact.onto_surface).
SIM_MODEL = 2
SOLVER_TOL = 1e-5      # a direct kgarment.sim.solve_states call (the library default)
DESIGN_TOL = 1e-3      # [solver] tol: iteration 0, the fully reinforced reference (why: problem.spec.SolverSpec)
EVOLUTION_TOL = 3e-2   # [solver] evolution_tol: every later design iteration, at A* too
                       # (why: docs/notes/solver.md)
EVALUATION_TOL = 1e-4  # evaluations (evaluate, simulate, studio, reproduce, fabricate) solve to
                       # min([solver] tol, EVALUATION_TOL)
ADAPTIVE_VERTICES = 4000  # evaluations solve garments of more vertices with the adaptive Hessian, not the
                          # shifted exact one (kgarment.sim.newton, "auto"; the shirt: 1,702 vertices at
                          # subdivision 0, 6,635 at 1, 26,188 at 2; the arm sleeve 302, 1,167, 4,586)
NESTED_VERTICES = 4000  # evaluations and a design run's iteration 0 start garments of more vertices (subdivided
                        # ones) from their equilibria one level down (kgarment.case.levels: nested
                        # iteration); smaller garments, where the slide from the skin-tight start is cheap,
                        # from their own starts
MAX_NEWTON = 200       # [solver] max_iter: Newton iterations per state
MAX_WORKERS = 8        # [solver] workers = 0 means one process per core, at most this many

PRESET_NAMES = ("paper", "reference")  # material presets (kgarment.sim.materials.PRESETS)

# ----- skin-garment friction ([materials] skin_friction; kgarment.sim.friction) ---------------------
FRICTION = 0.0         # [materials] skin_friction: the coefficient; 0 is the paper's frictionless body
FRICTION_MAX = 2.0     # its allowed range is [0, FRICTION_MAX]
FRICTION_SLIP = 2e-3   # metres: the slip at which friction reaches mu x the normal force (the skin's
                       # tangential give; below it the garment sticks)
FRICTION_LAGS = 3      # re-solves with the normal forces of the last equilibrium, at most
FRICTION_SETTLED = 0.1  # the normal forces have settled when none moved by more than this share of
                        # the largest

# ----- BESO (docs/method/index.md, "BESO"; the paper's values) ------------------------------
TARGET_AREA = 0.15     # A*, the reinforced share of the garment's area (0.20 for the sleeves)
ER = 0.015             # evolution ratio: the target area shrinks by this share per iteration
AR_MAX = 0.015         # at most this share of the faces is added per iteration
FILTER_RADIUS = 0.02   # metres, the "radius" filter's reach
CONVERGENCE_TOL = 1e-3  # relative change of the objective over `window` iterations
WINDOW = 5
MAX_ITERATIONS = 200
# The step guard (kgarment.optimize.guard, [design] guard): a motion's objective term below this
# (J per J of the fully reinforced garment's ON energy) is no load path worth guarding; the
# guard lets a step through after this many rejections in a row, and keeps the guarded faces'
# area below this share of the target area.
GUARD_FLOOR = 0.05
GUARD_RETRIES = 3
GUARD_AREA = 0.25
# "target reached": |area - A*| <= TARGET_MARGIN + er * A* (one BESO step plus the
# granularity of whole faces)
TARGET_MARGIN = 0.005

# ----- validation ranges of the problem file: (low, high), both allowed -------------------------
DESIGN_RANGES = {"target_area": (0.01, 1.0), "er": (1e-4, 0.5), "ar_max": (1e-4, 1.0), "radius": (1e-4, 1.0),
                 "tol": (1e-12, 1.0), "window": (1, 100), "max_iterations": (1, 100000),
                 "protect_clutch_margin": (0.0, 0.2), "lockout": (0.0, 10.0),
                 "balance": (0.0, 10.0), "guard": (0.0, 0.95), "settle": (0, 1000)}
SOLVER_RANGES = {"tol": (1e-14, 1.0), "evolution_tol": (1e-14, 1.0), "max_iter": (1, 100000), "workers": (0, 256),
                 "path_start": (0, 100000), "path_frames": (1, 200)}
PATH_FRAMES = 10  # frames of the motion from rest (the last one the target pose): `evaluate --path`'s default and
                  # [solver] path_frames' (path_start's check, the evaluator's own, so that the loop reads what it reads)
PATH_CONVERGE_TOL = 0.05  # `evaluate --path K --converge`: the largest energy change between two frame counts,
                          # relative to the motion's ON energy at the target (kgarment.evaluate.path_converge)
PATH_MAX_FRAMES = 80      # and the frames of the finest path it solves
SUBDIVISIONS = (0, 1, 2, 3)
NAME = re.compile(r"[A-Za-z0-9_][A-Za-z0-9_.+-]{0,63}")  # a motion or clutch name: file names are made of it
BODY_NAME = re.compile(r"[A-Za-z0-9_.-]{1,32}")  # a wearer of a multi-body design ([body] phenotypes)
BODY_SEP = "@"  # a multi-body design's motions are MOTION@BODY
ROTATION_DEGREES = (-180.0, 180.0)  # a motion's rotation of one bone, degrees
BUDGET_RANGE = DESIGN_RANGES["target_area"]   # the studio's budget slider


def target_reached(area: float, target: float, er: float) -> bool:
    """Whether a reinforced area share ``area`` counts as the target ``target`` (A*)."""
    return abs(area - target) <= TARGET_MARGIN + er * target

# ----- clutch hardware: how much an ON clutch holds (kgarment.sim.slip; docs/method/index.md) ---
CLUTCH_MODELS = ("locked", "slip", "cable")  # locked: an ON clutch never slips (the paper's model);
                           # slip: its elements hold up to the holding force (kgarment.sim.slip);
                           # cable: one pull-only force along it, up to the holding force (kgarment.sim.cable)
HOLDING_STRESS = 2.1e5     # Pa of overlap (width x length): 21 N/cm^2, measured for the textile
                           # electrostatic clutches the paper used (Hinchet & Shea 2020)
DIELECTRIC_THICKNESS = 25e-6  # m: the paper's P(VDF-TrFE-CTFE) layer on the insulating strip
DIELECTRIC_PERMITTIVITY = 40.0  # relative permittivity of P(VDF-TrFE-CTFE)
CLUTCH_FRICTION = 0.3      # friction coefficient between the strips
CLUTCH_RANGES = {"holding_stress": (1.0, 1e8), "voltage": (0.0, 1e4), "dielectric_thickness": (1e-7, 1e-2),
                 "permittivity": (1.0, 1e5), "friction": (1e-3, 2.0), "holding_force": (1e-3, 1e5)}
SLIPPING = 0.98            # a clutch slips where its tension reaches this share of its holding force

# ----- judging a design as a garment (docs/method/index.md, "Judging a design as a garment") --
LOADED_SHARE = 0.10    # a clutch is "loaded" in a motion when switching it on alone gives, or
                       # switching it off alone loses, at least this share of the energy that
                       # switching all clutches on adds (kgarment.evaluate.loads)
MIN_GAIN = 0.01        # below this share of the OFF energy, switching the clutches on changes nothing
LOAD_TOL = 1e-3        # solver tolerance of the one-clutch-ON states behind the shares
PLAN_EXHAUSTIVE = 6     # kgarment plan tries every clutch subset up to this many clutches, greedy sets beyond
PLAN_KEEP = 0.9         # the recommended set of a motion keeps this share of its all-ON resistance
PLAN_LOCK = 0.5         # a set "locks" another motion where it resists it with this share of its all-ON resistance
UNCONTROLLABLE = 0.005  # a motion where switching the clutches ON changes the fully reinforced garment's
                        # energy by less than this share is reported as one they cannot control
                        # (kgarment.evaluate.control; measured with SIM_MODEL 2, paper preset, subdivision
                        # 0: shirt motions 1.4-4.2%, a 120-degree overhead reach 0.34% (design.control); with model 1:
                        # shirt 1-3% with either preset, sleeves 6-14%, the reach 0.04-0.07%)
