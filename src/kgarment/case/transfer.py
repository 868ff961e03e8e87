"""A design on another body: the same garment, face for face, fitted to another wearer.

Anny keeps its mesh topology for every phenotype, so a garment cut from one body's faces
can be cut from the same faces of another: :func:`garment_on` takes the design run's
garment's body faces (not the template's cut planes, which could select other faces on
another body) and builds the garment on the other body with the same subdivision, the same
attachment rings and so the same faces, and a design (m,) applies to it unchanged.

The clutches are the same hardware (length, width, prestrain) placed at the same spot of
the garment: :func:`clutch_on_mesh` turns each clutch spec into one given on the mesh --
its start as (face, barycentric point) and its start direction as a barycentric vector of
the start face -- which :func:`kgarment.clutch.build_clutch` walks out again on the other
garment's rest surface (a larger body carries the same 15 cm clutch over a smaller share of
its back).
"""

from __future__ import annotations

import dataclasses

import numpy as np

from kgarment.body import Body
from kgarment.clutch import ClutchSpec, ClutchStrip, MeshTopology, build_clutch
from kgarment.clutch.landmarks import body_landmarks
from kgarment.clutch.spec import BaryDirection, SurfacePoint, resolve_start
from kgarment.errors import KgarmentError
from kgarment.garment import Garment, garment_from_mask
from kgarment.garment.templates import builtin_templates


def garment_on(body: Body, garment: Garment) -> Garment:
    """``garment`` (cut from another body of the same topology) cut from the same faces of
    ``body``: the same faces, vertices in the same order, the same attachment rings."""
    if garment.embedding.shape[1] != body.n_vertices:
        raise KgarmentError(f"the body has {body.n_vertices} vertices, the garment was cut from one with "
                            f"{garment.embedding.shape[1]}: a design moves only between bodies of one topology")
    mask = np.zeros(len(body.faces), bool)
    mask[garment.body_face] = True
    tpl = builtin_templates().get(garment.name)  # names the boundary loops; None for a mask garment
    out = garment_from_mask(body, mask, garment.name, garment.subdivision, (), tpl, clean=False)
    if not np.array_equal(out.faces, garment.faces):
        raise KgarmentError("the garment's faces differ on the other body")
    return dataclasses.replace(out, attached=garment.attached.copy())  # the same attachment rings


def clutch_on_mesh(spec: ClutchSpec, topology: MeshTopology, landmarks=None) -> ClutchSpec:
    """``spec`` given on the mesh (start face + barycentric point, barycentric start
    direction), valid on every garment with the faces of ``topology``, the rest garment it
    was placed on (``landmarks`` resolve landmark names there).  On that garment it builds
    the same strip: the straight walk is sensitive to its start direction where it passes
    near a vertex, so the direction is the spec's own, not one estimated from the strip."""
    st = resolve_start(spec, topology.V, topology.F, topology, landmarks)
    d = topology.grad[st.face] @ st.direction  # the barycentric coordinates' change along it
    direction = (-float(d[1] + d[2]), float(d[1]), float(d[2]))
    return dataclasses.replace(spec, start=SurfacePoint(st.face, tuple(float(b) for b in st.bary)),
                               direction=BaryDirection(direction))


def clutches_on(specs, body_from: Body, garment_from: Garment, garment_to: Garment) -> list[ClutchStrip]:
    """The clutches ``specs`` (placed on ``garment_from``, on ``body_from``) at the same
    spots of ``garment_to`` (same faces), each walked out again on its rest surface."""
    marks = body_landmarks(body_from) if body_from.rigged else None
    source = MeshTopology(garment_from.rest_vertices, garment_from.faces)
    topo = MeshTopology(garment_to.rest_vertices, garment_to.faces)
    return [build_clutch(clutch_on_mesh(s, source, marks), garment_to.rest_vertices, garment_to.faces,
                         topology=topo) for s in specs]
