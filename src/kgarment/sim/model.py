"""Simulation model (garment + clutches, built once), motions and states.

Degrees of freedom: ``x = [garment (n); clutch 1 (nc1); ...; clutch K]`` (N, 3), metres.

Penalty weights (SI, chosen per state from the materials actually present)
--------------------------------------------------------------------------
With ``s_e = Y_e t_e`` (N/m) the membrane stiffness of element e in this state (design and
activation included), ``s_v`` the largest ``s_e`` over the elements around vertex v,
``A_v`` the lumped rest area of v, ``A_f`` a face's rest area and ``L`` the garment's mean
rest edge length:

* contact   ``k_v = alpha_contact * s_v * A_v / L^2``      (energy ``k_v min(f, 0)^2``)
* attach    ``k_f = alpha_attach * max_{v in f} s_v * A_f / L^2``
* anchor    ``k   = alpha_anchor * max(s_v over the clutch vertex and its garment face)``
* tie       ``k_v = alpha_tie * (Y t)_cloth * A_v / L^2``; in a channel
            ``k_v = alpha_channel * (Y t)_reinforced * A_v / L^2``

Why: a membrane under tension ``T = s eps`` over a body of curvature ``kappa`` presses
with ``p = T kappa``; on a vertex that is a force ``s eps kappa A_v`` against the penalty
force ``2 k_v delta``, so the penetration is ``delta = eps kappa L^2 / (2 alpha_contact)``
-- independent of the material (the 1000x stiffer reinforced cloth of the ``paper``
preset gets a 1000x stiffer penalty) and of the local mesh density.  With
``alpha_contact = 10``, strain 0.5, a 3 cm radius and 5 mm edges, delta = 10 micrometres.
The force an attached face carries is about ``T L`` (tension over its share of the
attachment line), so the drift is ``~ eps L / (0.43 alpha_attach)`` (A_f ~ 0.43 L^2):
0.6 mm at eps = 0.5, L = 5 mm, ``alpha_attach = 20``.  Taking the maximum over the
neighbourhood covers a reinforced strip that ends on a cloth attachment face.  Anchors
carry the clutch tension over a third of its width (~ 2 L / 3); ``alpha_anchor = 30``
keeps their drift below eps * 0.02 L.  Ties only keep the strip on the garment, so they
are scaled with plain cloth and kept weak (0.1): the paper's build snaps a clutch on at its
ends only.  A clutch sewn along its length into a channel of the connecting material
(``clutch_channel``, ``[clutches] channel``) is held as stiffly as that material holds
(``alpha_channel = 1`` times reinforced ``Y t``, 1000 x the weak tie in the ``paper`` preset):
the strip then follows the garment under it instead of rolling off a bent elbow by itself.  Penalties of order 10 x the local
membrane stiffness keep the Hessian well conditioned (the stiffness ratio between
materials, up to ~8000 in the ``paper`` preset, is intrinsic to the problem).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from kgarment.clutch.strip import ClutchStrip
from kgarment.constants import FRICTION_SLIP
from kgarment.sim.assembly import HessianPattern, build_pattern
from kgarment.sim.cable import strip_path
from kgarment.sim.contact import ImplicitBody, onto_surface
from kgarment.sim.materials import MaterialPreset, get_preset
from kgarment.sim.membrane import TriangleElements
from kgarment.sim.slip import axial_coefficients, path_length, rest_width
from kgarment.sim.springs import SpringSet, binding_springs


@dataclass(frozen=True)
class PenaltyParams:
    """Dimensionless penalty factors (see the module docstring for the formulas)."""

    contact: float = 10.0
    attach: float = 20.0
    anchor: float = 30.0
    tie: float = 0.1
    channel: float = 1.0


@dataclass(frozen=True)
class SimModel:
    """Precomputed structure of garment + clutches (motion- and state-independent).

    Attributes
    ----------
    preset : MaterialPreset
    garment_rest : (n, 3) rest vertices, m;  garment_faces : (m, 3) int64
    clutches : tuple of ClutchStrip
    vertex_offsets : (K + 2,) clutch k owns vertices [off[k+1], off[k+2]); garment [0, n)
    face_offsets : (K + 2,) same for elements (garment faces first)
    elements : TriangleElements over all M elements (clutch ones on their rest shape)
    relaxed : (M,) bool, wrinkling relaxation (garment elements; clutch elements too where
        ``clutch_buckle``)
    vertex_area : (N,) lumped rest area, m^2
    mean_edge : mean garment rest edge length L, m
    static_springs : anchors and ties (motion-independent)
    pattern : HessianPattern
    penalties : PenaltyParams
    holding_force : (K,) N each clutch holds before it slides (``sim.slip``); inf: locked
        (the paper's model, an ON clutch never slips).  None: every clutch locked.
    slip_coef : (M - m, 3) axial shape coefficients of the clutch elements (1/m)
    strip_width : (K,) each strip's mean rest width, m
    clutch_buckle : the clutch strips take no compression (``[clutches] buckle``): their
        elements relax like the cloth's and their sliders (``sim.slip``) only pull
    friction : skin-garment friction coefficient (``sim.friction``; 0: frictionless, the
        paper's model);  friction_slip : the slip (m) at which friction reaches its force
    clutch_channel : each clutch's centre line is held to the garment by a channel of
        reinforced fabric (the ``tie`` springs as stiff as that; module doc)
    clutch_cable : an ON clutch carries one pull-only force along its length (``sim.cable``)
        instead of stiffening its elements;  cable_paths : per clutch with ``clutch_cable``,
        (vertex ids (v,), W (P, v), rest length m) of its path along the strip
        (``sim.cable.strip_path``); the Hessian pattern couples each path's vertices
    """

    preset: MaterialPreset
    garment_rest: np.ndarray
    garment_faces: np.ndarray
    clutches: tuple[ClutchStrip, ...]
    vertex_offsets: np.ndarray
    face_offsets: np.ndarray
    elements: TriangleElements
    relaxed: np.ndarray
    vertex_area: np.ndarray
    mean_edge: float
    static_springs: SpringSet
    pattern: HessianPattern = field(repr=False)
    penalties: PenaltyParams = PenaltyParams()
    holding_force: np.ndarray | None = None
    slip_coef: np.ndarray | None = field(default=None, repr=False)
    strip_width: np.ndarray | None = None
    clutch_buckle: bool = False
    friction: float = 0.0
    friction_slip: float = FRICTION_SLIP
    clutch_cable: bool = False
    cable_paths: tuple = field(default=(), repr=False)
    clutch_channel: bool = False

    @property
    def slips(self) -> bool:
        """Whether any clutch has a finite holding force."""
        return self.holding_force is not None and bool(np.isfinite(self.holding_force).any())

    def holding(self, activation) -> np.ndarray:
        """(K,) force each clutch holds at ``activation`` (K,) in [0, 1]: ``g^2 F_h`` N
        (``sim.slip``: the force goes with the voltage squared); inf where it is locked."""
        if self.holding_force is None:
            return np.full(self.n_clutches, np.inf)
        g = np.asarray(activation, dtype=np.float64).reshape(-1)
        hold = self.holding_force.copy()
        finite = np.isfinite(hold)
        hold[finite] *= g[finite] ** 2
        return hold

    @property
    def n_garment(self) -> int:
        return len(self.garment_rest)

    @property
    def n_faces(self) -> int:
        return len(self.garment_faces)

    @property
    def n_vertices(self) -> int:
        return int(self.vertex_offsets[-1])

    @property
    def n_clutches(self) -> int:
        return len(self.clutches)

    @property
    def char_force(self) -> float:
        """Characteristic nodal force of plain cloth, ``Y_cloth t_cloth L`` (N)."""
        return self.preset.cloth_stiffness * self.mean_edge

    def initial_positions(self, garment_x: np.ndarray) -> np.ndarray:
        """(N, 3) positions: the garment at ``garment_x`` (n, 3), clutches carried along."""
        gx = np.asarray(garment_x, dtype=np.float64)
        parts = [gx] + [c.bound_positions(gx, self.garment_faces) for c in self.clutches]
        return np.concatenate(parts)

    def split(self, x: np.ndarray) -> tuple[np.ndarray, list[np.ndarray]]:
        """Split (N, 3) positions into the garment's (n, 3) and each clutch's (nc_k, 3)."""
        off = self.vertex_offsets
        return x[: off[1]], [x[off[k + 1]: off[k + 2]] for k in range(self.n_clutches)]


def build_model(
    garment_vertices: np.ndarray,
    garment_faces: np.ndarray,
    clutches: list[ClutchStrip] | tuple[ClutchStrip, ...] = (),
    preset: str | MaterialPreset = "paper",
    penalties: PenaltyParams = PenaltyParams(),
    holding_force=None,
    clutch_buckle: bool = False,
    friction: float = 0.0,
    clutch_cable: bool = False,
    clutch_channel: bool = False,
) -> SimModel:
    """Build the simulation model.

    garment_vertices : (n, 3) rest positions, m;  garment_faces : (m, 3) int;
    clutches : ClutchStrip list (bound to this garment);  preset : "paper" | "reference";
    holding_force : None (every clutch locked, the paper's model) or (K,) newtons per
    clutch, ``inf`` for a locked one (``sim.slip``);  clutch_buckle : the strips take no
    compression (the paper's model: False);  friction : skin-garment friction coefficient
    (``sim.friction``; 0, the paper's model: frictionless);  clutch_cable : an ON clutch is
    a pull-only cable along its length (``sim.cable``; needs ``holding_force``), not a
    stiff band (the paper's model: False);  clutch_channel : the clutches' centre lines held
    to the garment by a channel of reinforced fabric (the paper's model: False, the weak tie).
    """
    X = np.ascontiguousarray(garment_vertices, dtype=np.float64)
    F = np.ascontiguousarray(garment_faces, dtype=np.int64)
    if X.ndim != 2 or X.shape[1] != 3 or F.ndim != 2 or F.shape[1] != 3:
        raise ValueError("garment vertices must be (n, 3) and faces (m, 3)")
    if F.min() < 0 or F.max() >= len(X):
        raise ValueError("garment face index out of range")
    mat = get_preset(preset)
    clutches = tuple(clutches)
    n, m = len(X), len(F)
    voff, foff = [0, n], [0, m]
    parts = [TriangleElements.from_mesh(X, F)]
    springs, coef, width, paths = [], [], [], []
    for c in clutches:
        cf = np.asarray(c.faces, dtype=np.int64)
        nc = len(c.vertices)
        if np.asarray(c.bind_face).max() >= m:
            raise ValueError(f"clutch {c.name!r} binds to a face outside the garment")
        rest = c.rest_vertices()
        parts.append(TriangleElements.from_mesh(rest, cf, offset=voff[-1]))
        coef.append(axial_coefficients(rest, cf, parts[-1].shape_grad, c.centerline))
        width.append(rest_width(rest, cf, c.centerline))
        anchors = np.asarray(c.anchors, dtype=np.int64)
        ties = np.setdiff1d(np.asarray(c.centerline, dtype=np.int64), anchors)
        for ids, grp in ((anchors, "anchor"), (ties, "tie")):
            springs.append(binding_springs(ids + voff[-1], F, np.asarray(c.bind_face)[ids],
                                           np.asarray(c.bind_bary)[ids], grp))
        if clutch_cable:
            ids, W = strip_path(anchors, c.centerline)
            paths.append((voff[-1] + ids, W, path_length(W @ rest[ids])))
        voff.append(voff[-1] + nc)
        foff.append(foff[-1] + len(cf))
    elems = TriangleElements.concat(parts)
    n_all = voff[-1]
    relaxed = np.zeros(len(elems.area), bool)
    relaxed[:m] = True
    relaxed[m:] = bool(clutch_buckle)
    varea = np.zeros(n_all)
    np.add.at(varea, elems.tri.ravel(), np.repeat(elems.area / 3.0, 3))
    e = np.concatenate([F[:, [0, 1]], F[:, [1, 2]], F[:, [2, 0]]])
    e = np.unique(np.sort(e, axis=1), axis=0)
    mean_edge = float(np.linalg.norm(X[e[:, 0]] - X[e[:, 1]], axis=1).mean())
    static = SpringSet.concat(springs)
    pattern = build_pattern(n_all, elems.tri, static.index, [ids for ids, _, _ in paths])
    hold = None
    if not (np.isfinite(friction) and friction >= 0.0):
        raise ValueError(f"friction must be a coefficient >= 0, got {friction}")
    if holding_force is not None:
        hold = np.asarray(holding_force, dtype=np.float64).reshape(-1)
        if hold.shape != (len(clutches),) or np.any(np.isnan(hold)) or np.any(hold <= 0):
            raise ValueError(f"holding_force must be {len(clutches)} positive forces (inf: locked)")
    if clutch_cable and clutches and hold is None:
        raise ValueError("clutch_cable needs holding_force (inf for a cable that never slips)")
    return SimModel(preset=mat, garment_rest=X, garment_faces=F, clutches=clutches,
                    vertex_offsets=np.array(voff), face_offsets=np.array(foff), elements=elems,
                    relaxed=relaxed, vertex_area=varea, mean_edge=mean_edge, static_springs=static,
                    pattern=pattern, penalties=penalties, holding_force=hold,
                    slip_coef=np.concatenate(coef) if coef else np.zeros((0, 3)), strip_width=np.array(width),
                    clutch_buckle=bool(clutch_buckle), friction=float(friction), clutch_cable=bool(clutch_cable),
                    cable_paths=tuple(paths), clutch_channel=bool(clutch_channel))


@dataclass(frozen=True)
class Motion:
    """One motion's inputs.

    name : str; garment_x0 : (n, 3) initial deformed garment (skin-tight on the posed
    body: on its contact surface, see :meth:`create`); body : ImplicitBody of the posed
    body; attach_faces : (a,) garment face ids; attach_targets : (a, 3) target centroids, m.
    """

    name: str
    garment_x0: np.ndarray
    body: ImplicitBody
    attach_faces: np.ndarray
    attach_targets: np.ndarray

    @staticmethod
    def create(name: str, garment_x0: np.ndarray, body_vertices: np.ndarray, body_normals: np.ndarray,
               attach_faces: np.ndarray, attach_targets: np.ndarray,
               body_faces: np.ndarray | None = None, on_surface: bool = True,
               garment_faces: np.ndarray | None = None) -> Motion:
        """Build a motion (and its IMLS body) from plain arrays (shapes as in the class doc).

        With ``on_surface`` (``SIM_MODEL`` 2) the skin-tight garment, given on the body's
        mesh, is moved onto its contact surface (:func:`kgarment.sim.contact.onto_surface`,
        typically ~1 mm), and the attachment targets with it: each by the mean move of its
        face's three vertices where ``garment_faces`` (m, 3) is given (targets at the face
        centroids then stay there: no spring is stretched at the start), else onto the
        surface.  So the garment starts touching the body, not inside it, and the held
        rings are not pulled into the body that contact pushes them out of."""
        af = np.asarray(attach_faces, dtype=np.int64).reshape(-1)
        at = np.asarray(attach_targets, dtype=np.float64).reshape(-1, 3)
        if len(af) != len(at):
            raise ValueError("attach_faces (a,) and attach_targets (a, 3) disagree in length")
        body = ImplicitBody.from_mesh(body_vertices, body_normals, body_faces)
        x0 = np.asarray(garment_x0, dtype=np.float64)
        if on_surface:
            moved = onto_surface(body, x0)
            if garment_faces is not None:
                at = at + (moved - x0)[np.asarray(garment_faces)[af]].mean(axis=1)
            else:
                at = onto_surface(body, at)
            x0 = moved
        return Motion(name=name, garment_x0=x0, body=body, attach_faces=af, attach_targets=at)


def garment_motions(body, garment, names=None) -> dict[str, Motion]:
    """{motion name: Motion} of a garment on its posed body: the skin-tight start, the
    posed body's implicit surface and the attachment targets.

    body : kgarment.body.Body posed in the motions;  garment : kgarment.garment.Garment on it
    (its ``attached`` faces are held);  names : motions to build (default: every motion the
    garment is posed in).
    """
    attached = np.flatnonzero(garment.attached)
    return {m: Motion.create(m, garment.vertices(m), body.vertices(m), body.normals(m), attached,
                             garment.attachment_targets(m), body.faces, garment_faces=garment.faces)
            for m in (names or garment.motion_names)}


@dataclass(frozen=True)
class SimState:
    """A motion under one clutch activation pattern: activation (K,) in [0, 1].

    anchor : (N, 3) where skin friction (``sim.friction``) holds each vertex, the garment's
    and the clutches' (m), or None: the skin-tight garment, as if it had followed the skin
    without slipping from the start.  A frame of a motion anchors where the frame before
    left the garment (:func:`kgarment.sim.held_after`, carried with the skin by
    :func:`kgarment.evaluate.path.carried`): what slid stays slid, as Coulomb friction keeps no
    memory of where the garment started.
    """

    name: str
    motion: Motion
    activation: tuple[float, ...] = ()
    anchor: np.ndarray | None = field(default=None, compare=False, repr=False)

    @property
    def clutched(self) -> bool:
        """Whether any clutch is switched on (some activation > 0)."""
        return any(a > 0 for a in self.activation)

    @staticmethod
    def create(motion: Motion, activation, name: str | None = None, anchor: np.ndarray | None = None) -> SimState:
        g = tuple(float(a) for a in np.atleast_1d(np.asarray(activation, dtype=np.float64)))
        if name is None:
            name = f"{motion.name}[{','.join(f'{a:g}' for a in g)}]"
        return SimState(name=name, motion=motion, activation=g,
                        anchor=None if anchor is None else np.asarray(anchor, dtype=np.float64))
