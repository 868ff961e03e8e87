"""Problem files (TOML): body, motions, garment, clutches, design, solver and materials,
parsed once into frozen dataclasses (``spec``), validated with messages that name the
field (``parse``), and turned into the body, garment, clutches, simulation model and solver
options every command uses (``build``).

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

from kgarment.body.motions import PAPER_MOTIONS
from kgarment.problem.build import (
    build_body,
    build_clutches,
    build_garment,
    build_model,
    clutch_specs,
    solver_options,
)
from kgarment.problem.examples import example_files, example_path, example_title, examples_dir
from kgarment.problem.parse import load_problem, override, parse_problem, problem_to_dict
from kgarment.problem.spec import (
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

__all__ = ["PAPER_MOTIONS", "BesoParams", "BodySpec", "ClutchesSpec", "ClutchHardware", "DesignSpec", "GarmentSpec", "MaterialSpec",
           "Problem", "SolverSpec", "build_body", "build_clutches", "build_garment", "build_model", "clutch_specs", "example_files", "example_path", "example_title", "examples_dir",
           "load_problem", "override", "parse_problem", "problem_to_dict", "solver_options"]
