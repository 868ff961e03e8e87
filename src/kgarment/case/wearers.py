"""One garment for several bodies at once: a multi-body design (``[body] phenotypes``).

A size range gets one cut pattern: the garment is cut from the first wearer's body and
carried face for face to the others (:mod:`kgarment.case.transfer`: Anny keeps its mesh
topology for every phenotype, so the same faces, attachment rings and clutch spots exist on
every body).  Each wearer's motions are further states of the one design, named
``MOTION@BODY`` (``arms_forward@S``); every one is normalised by its own fully reinforced
garment like any motion (docs/method/index.md, "The relative energy density"), so a small body's smaller energies weigh
as much as a large one's.  The design, its area budget and its clutch ends are the first
wearer's faces; rho of each state uses its own body's face areas.
"""

from __future__ import annotations

import dataclasses
import logging
from dataclasses import dataclass, field

import numpy as np

from kgarment.case.keys import split_wearer, wearer_motion
from kgarment.case.transfer import clutches_on, garment_on
from kgarment.garment.topology import triangle_areas
from kgarment.problem import Problem, build_body, build_model, clutch_specs
from kgarment.sim import SimModel, garment_motions

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class ClutchEnds:
    """The garment faces under one clutch's two ends (the faces its anchors bind to).

    a, b : (3,) int face ids under end A (the start) and end B.
    """

    a: np.ndarray
    b: np.ndarray


@dataclass(frozen=True)
class Wearer:
    """One body of a multi-body design (``[body] phenotypes``) for one of its motions.

    name : the wearer's name;  motion : the problem's motion name (the case's is
    ``MOTION@NAME``);  model : SimModel of the garment on this body (same faces, this body's
    rest shape, the clutches at the same spots);  areas : (m,) rest face areas on this body,
    m^2;  clutch_area : total rest area of its clutches, m^2 (0 for the passive objective);
    body : the kgarment Body, posed in the motions (renders);  ends : per clutch, the
    garment faces under its ends on this body (the same clutch spans other faces on
    another body).
    """

    name: str
    motion: str
    model: SimModel = field(repr=False)
    areas: np.ndarray = field(repr=False)
    clutch_area: float
    body: object = field(repr=False, default=None)
    ends: tuple[ClutchEnds, ...] = field(repr=False, default=())


def clutch_ends(model: SimModel) -> tuple[ClutchEnds, ...]:
    """The garment faces under each clutch's two ends (its anchors' bind faces) in ``model``."""
    out = []
    for c in model.clutches:
        a, bind = np.asarray(c.anchors), np.asarray(c.bind_face)
        out.append(ClutchEnds(bind[a[[0, 1, 2]]], bind[a[[3, 4, 5]]]))
    return tuple(out)


def wearer_key(motion: str, body: str) -> str:
    """The state name of ``motion`` on wearer ``body``: ``MOTION@BODY``."""
    return wearer_motion(motion, body)


def split_key(key: str) -> tuple[str, str | None]:
    """(motion, wearer) of a motion key (wearer None for a one-body design's)."""
    return split_wearer(key)


def on_phenotype(problem: Problem, phenotype) -> Problem:
    """``problem`` on one Anny body of ``phenotype`` alone (a one-body problem)."""
    return dataclasses.replace(problem, body=dataclasses.replace(problem.body, phenotype=phenotype, phenotypes=()))


def wearer_problem(problem: Problem, name: str) -> Problem:
    """``problem`` on one of its wearers alone (a one-body problem with that phenotype)."""
    ph = dict(problem.body.phenotypes).get(name)
    if ph is None:
        raise KeyError(name)
    return on_phenotype(problem, ph)


def wearer_motions(problem: Problem, body, garment, strips, model, motions: dict, activation: dict, specs=None):
    """The motions, activations and :class:`~kgarment.case.wearers.Wearer` of every wearer.

    body, garment, strips, model : the first wearer's (the garment is cut from it);
    motions : {motion: Motion} and activation : {motion: (K,)} on that body.  Returns
    ({MOTION@BODY: Motion}, {MOTION@BODY: (K,)}, {MOTION@BODY: Wearer}).
    """
    clutched = problem.design.objective != "passive"
    specs = clutch_specs(problem, body) if specs is None else list(specs)
    out_m, out_a, out_w = {}, {}, {}
    for i, (name, _) in enumerate(problem.body.phenotypes):
        if i == 0:
            b, g, st, mdl = body, garment, list(strips), model
        else:
            b = build_body(wearer_problem(problem, name))
            g = garment_on(b, garment)
            st = clutches_on(specs, body, garment, g) if specs else []
            mdl = build_model(problem, g, st)
            log.info("wearer %s: the garment's %d faces and %d clutches carried over", name, g.n_faces, len(st))
        areas = triangle_areas(g.rest_vertices, g.faces)
        c_area = sum(float(triangle_areas(c.vertices, c.faces).sum()) for c in mdl.clutches) if clutched else 0.0
        ms = motions if i == 0 else garment_motions(b, g, problem.motions)
        for m in problem.motions:
            key = wearer_key(m, name)
            out_m[key] = dataclasses.replace(ms[m], name=key)
            if m in activation:
                out_a[key] = np.asarray(activation[m])
            out_w[key] = Wearer(name, m, mdl, areas, c_area, body=b, ends=clutch_ends(mdl))
    return out_m, out_a, out_w
