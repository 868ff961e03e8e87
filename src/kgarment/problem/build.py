"""What a problem builds: the posed body, the garment, the clutch strips, the simulation
model and the solver options (one function for every command, so a problem file's
``[solver]`` and ``[materials]`` mean the same everywhere)."""

from __future__ import annotations

import os

import numpy as np

from kgarment import constants as C
from kgarment.body import Body, load_anny_body, load_mesh_sequence
from kgarment.clutch import ClutchSpec, ClutchStrip, MeshTopology, build_clutch, load_clutches
from kgarment.clutch.landmarks import body_landmarks
from kgarment.clutch.layouts import default_layout, layout_names
from kgarment.errors import KgarmentError
from kgarment.garment import Garment, garment_from_mask, load_face_mask, make_garment
from kgarment.problem.spec import ClutchHardware, Problem
from kgarment.sim import SimModel, SolverOptions
from kgarment.sim import build_model as build_sim_model
from kgarment.sim.slip import electrostatic_stress

PURPOSES = ("design", "evolution", "evaluate")


def build_body(problem: Problem) -> Body:
    """The body posed in the problem's motions (Anny, or the problem's mesh files)."""
    if problem.body.model == "anny":
        return load_anny_body(problem.motion_list(), problem.body.phenotype)
    meshes = dict(problem.body.meshes)
    return load_mesh_sequence(problem.body.rest, {n: meshes[n] for n in problem.motions}, problem.body.rig)


def build_garment(problem: Problem, body: Body) -> Garment:
    """The problem's garment on ``body`` (template or face mask, subdivided)."""
    g = problem.garment
    if g.template:
        return make_garment(body, g.template, g.subdivision)
    mask = load_face_mask(g.mask, len(body.faces))
    return garment_from_mask(body, mask, g.mask.stem, g.subdivision, g.attach)


def clutch_names(problem: Problem) -> list[str]:
    """The names of the problem's clutches, in :func:`clutch_specs`' order, without building the body."""
    c = problem.clutch_spec()
    names = list(layout_names(c.layout, c.side)) if c.layout else []
    if c.file:
        names += [s.name for s in load_clutches(c.file)]
    return names + [s.name for s in c.inline]


def clutch_specs(problem: Problem, body: Body) -> list[ClutchSpec]:
    """All the problem's clutch specs (layout, then file, then inline), names unique."""
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


def build_clutches(problem: Problem, body: Body, garment: Garment, specs=None) -> list[ClutchStrip]:
    """The clutch strips (the problem's, or ``specs``) on the garment; landmark names are
    resolved on the body."""
    specs = clutch_specs(problem, body) if specs is None else list(specs)
    if not specs:
        return []
    topo = MeshTopology(garment.rest_vertices, garment.faces)
    marks = body_landmarks(body) if body.rigged else None
    return [build_clutch(s, garment.rest_vertices, garment.faces, topology=topo, landmarks=marks) for s in specs]


def build_model(problem: Problem, garment: Garment, strips) -> SimModel:
    """The simulation model of the garment and ``strips`` in the problem's material preset
    and clutch hardware (no clutches for the passive objective)."""
    strips = list(strips) if problem.design.objective != "passive" else []
    hw = problem.clutch_spec().hardware
    return build_sim_model(garment.rest_vertices, garment.faces, strips, preset=problem.materials.preset,
                           holding_force=holding_forces(hw, strips), clutch_buckle=hw.buckle,
                           friction=problem.materials.skin_friction, clutch_cable=hw.model == "cable",
                           clutch_channel=hw.channel)


def holding_forces(hw: ClutchHardware, strips) -> np.ndarray | None:
    """(K,) newtons each clutch holds (``kgarment.sim.slip``, ``kgarment.sim.cable``), or None
    for locked clutches:
    ``holding_force`` by name (or ``"*"``), else the holding stress (``holding_stress``, or the
    electrostatic formula where ``voltage`` is set) times the strip's width x length."""
    if hw.model == "locked":
        return None
    names = [s.name for s in strips]
    given = dict(hw.holding_force)
    unknown_names = sorted(set(given) - set(names) - {"*"})
    if unknown_names:
        raise KgarmentError(f"[clutches] holding_force names unknown clutch(es) {unknown_names}; "
                            f"the clutches are: {', '.join(names) or 'none'}")
    tau = (electrostatic_stress(hw.voltage, hw.dielectric_thickness, hw.permittivity, hw.friction)
           if hw.voltage > 0 else hw.holding_stress)
    return np.array([given.get(s.name, given.get("*", tau * s.width * s.length)) for s in strips], dtype=np.float64)


def solver_options(problem: Problem, purpose: str = "design", device: str = "cpu") -> SolverOptions:
    """The solver options of ``problem``'s ``[solver]`` for one purpose.

    ``design``: ``tol`` (iteration 0, the fully reinforced reference);  ``evolution``:
    ``max(tol, evolution_tol)`` (every later design iteration);  ``evaluate``:
    ``min(tol, EVALUATION_TOL)`` (measuring a design: evaluate, simulate, the studio,
    reproduce, fabricate), with the Hessian strategy ``"auto"``: the adaptive one on fine
    garments, whose slow slides the shifted one crawls through (``kgarment.sim.newton``).
    ``workers = 0`` becomes one process per core, at most
    :data:`kgarment.constants.MAX_WORKERS`.
    """
    if purpose not in PURPOSES:
        raise ValueError(f"purpose must be one of {PURPOSES}, not {purpose!r}")
    s = problem.solver
    tol = {"design": s.tol, "evolution": max(s.tol, s.evolution_tol), "evaluate": min(s.tol, C.EVALUATION_TOL)}[purpose]
    return SolverOptions(method=s.method, tol=tol, max_iter=s.max_iter, device=device,
                         hessian="auto" if purpose == "evaluate" else "shifted",
                         workers=s.workers or min(os.cpu_count() or 1, C.MAX_WORKERS))

