"""The total energy of one state (design + motion + activation): value, gradient, Hessian.

``E(x) = E_membrane(garment) + E_membrane(clutches) + E_contact + E_attach + E_anchor
+ E_tie`` on x (N, 3); with slipping clutches (:mod:`kgarment.sim.slip`) an ON clutch's
membrane is its OFF one plus an axial slider, counted in its elements' membrane energy;
with cable clutches (:mod:`kgarment.sim.cable`) its OFF one plus one pull-only force along
the strip, its energy shared among the strip's elements by area.
:class:`StateProblem` holds the per-state tensors (materials, penalty weights, body,
springs, sliders) and the contact neighbour cache; it is the object the solvers minimise.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch

from kgarment.sim.cable import LOCKED_CAP, SPACING, Cable, cable_energy
from kgarment.sim.contact import NEIGHBORS, contact, gather, imls_fast, update_neighbors
from kgarment.sim.friction import friction, normal_forces, strip_directions, strip_neighbours
from kgarment.sim.materials import (
    check_design,
    clutch_material,
    garment_material,
    lame_plane_stress,
)
from kgarment.sim.membrane import branches, membrane
from kgarment.sim.model import SimModel, SimState
from kgarment.sim.slip import SliderSet, slider_energy
from kgarment.sim.springs import GROUPS, SpringSet, attachment_springs, springs

TERMS = ("membrane_garment", "membrane_clutch", "contact") + GROUPS


class SimulationError(ValueError):
    """A state produced a non-finite energy or gradient."""


@dataclass(frozen=True)
class StateMaterials:
    """Per-element materials of one state: young, thick, stiffness (= Y t) : (M,)."""

    young: np.ndarray
    thick: np.ndarray

    @property
    def stiffness(self) -> np.ndarray:
        return self.young * self.thick


def state_materials(model: SimModel, design: np.ndarray, activation) -> StateMaterials:
    """design : (m,) in [x_min, 1]; activation : (K,) in [0, 1]."""
    d = check_design(design, model.n_faces, model.preset)
    g = np.asarray(activation, dtype=np.float64).reshape(-1)
    if len(g) != model.n_clutches:
        raise ValueError(f"activation has {len(g)} entries for {model.n_clutches} clutches")
    y, t = garment_material(d, model.preset)
    ys, ts = [y], [t]
    fo = model.face_offsets
    for k in range(model.n_clutches):
        yc, tc = clutch_material(g[k], model.preset)
        nk = fo[k + 2] - fo[k + 1]
        ys.append(np.full(nk, yc))
        ts.append(np.full(nk, tc))
    return StateMaterials(np.concatenate(ys), np.concatenate(ts))


def slider_arrays(model: SimModel, mats: StateMaterials, activation) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The slipping clutch elements of a state (``sim.slip``): element ids (q,), slider
    stiffness ``k`` (q,) N/m -- what the activation adds to the OFF membrane, from the
    state's materials ``mats`` -- and holding force per unit width ``cap`` (q,) N/m; the
    elements of every clutch with a finite holding force and activation g > 0 (every clutch
    with g > 0 for cable clutches, ``sim.cable``; a locked one's cap is ``LOCKED_CAP``)."""
    g = np.asarray(activation, dtype=np.float64).reshape(-1)
    hold = model.holding(g)
    fo = model.face_offsets
    on = [k for k in range(model.n_clutches) if g[k] > 0.0 and (model.clutch_cable or np.isfinite(hold[k]))]
    hold = np.minimum(hold, LOCKED_CAP * model.strip_width)
    if not on:
        return np.zeros(0, np.int64), np.zeros(0), np.zeros(0)
    ids = np.concatenate([np.arange(fo[k + 1], fo[k + 2]) for k in on])
    s_off = model.preset.young_clutch_off * model.preset.thick_clutch_off
    caps = np.concatenate([np.full(fo[k + 2] - fo[k + 1], hold[k] / model.strip_width[k]) for k in on])
    return ids, np.maximum(mats.stiffness[ids] - s_off, 1e-12 * s_off), caps


def vertex_stiffness(model: SimModel, mats: StateMaterials) -> np.ndarray:
    """(N,) largest membrane stiffness ``Y t`` (N/m) over the elements around each vertex."""
    s_v = np.zeros(model.n_vertices)
    np.maximum.at(s_v, model.elements.tri.ravel(), np.repeat(mats.stiffness, 3))
    return s_v


def penalty_weights(model: SimModel, mats: StateMaterials, spr: SpringSet):
    """Contact weights (N,) and spring stiffnesses (S,) in N/m (formulas in ``model``)."""
    pen = model.penalties
    L2 = model.mean_edge**2
    s_v = vertex_stiffness(model, mats)
    k_contact = pen.contact * s_v * model.vertex_area / L2
    k = np.empty(spr.size)
    grp = spr.group
    s_max = np.max(np.where(spr.coef != 0, s_v[spr.index], 0.0), axis=1)
    att = grp == GROUPS.index("attach")
    if att.any():
        P = model.garment_rest[spr.index[att, :3]]  # (a, 3, 3) rest triangle of the face
        a_f = 0.5 * np.linalg.norm(np.cross(P[:, 1] - P[:, 0], P[:, 2] - P[:, 0]), axis=1)
        k[att] = pen.attach * s_max[att] * a_f / L2
    anc = grp == GROUPS.index("anchor")
    k[anc] = pen.anchor * s_max[anc]
    tie = grp == GROUPS.index("tie")
    s_tie = (pen.channel * model.preset.young_reinforced * model.preset.thick_reinforced if model.clutch_channel
             else pen.tie * model.preset.cloth_stiffness)
    k[tie] = s_tie * model.vertex_area[spr.index[tie, 0]] / L2
    return k_contact, k


class StateProblem:
    """Energy of one state on x (N, 3) (torch float64 on ``device``).

    Not a frozen structure: it carries the contact neighbour cache, refreshed as x moves.
    """

    def __init__(self, model: SimModel, design: np.ndarray, state: SimState,
                 device: str | torch.device = "cpu", projection: str = "analytic",
                 exact_contact_hessian: bool = False):
        self.model, self.state, self.name = model, state, state.name
        self.device = torch.device(device)
        self.projection = projection
        self.exact_contact_hessian = exact_contact_hessian
        mot = state.motion
        if mot.garment_x0.shape != (model.n_garment, 3):
            raise ValueError(f"motion {mot.name!r}: garment_x0 must be ({model.n_garment}, 3)")
        self.mats = state_materials(model, design, state.activation)
        spr = SpringSet.concat([attachment_springs(model.garment_faces, mot.attach_faces,
                                                   mot.attach_targets), model.static_springs])
        k_contact, k_spring = penalty_weights(model, self.mats, spr)
        s_v = vertex_stiffness(model, self.mats)
        self.dof_stiffness = np.repeat(s_v, 3)
        self.force_scale = self._t(np.maximum(s_v, model.preset.cloth_stiffness) * model.mean_edge)
        T = self._t
        el = model.elements
        # a slipping clutch element is the clutch's OFF membrane plus an axial slider (sim.slip);
        # its penalties keep the ON stiffness (mats), which the anchors must hold
        young, thick = self.mats.young.copy(), self.mats.thick.copy()
        sid, sk, scap = slider_arrays(model, self.mats, state.activation)
        young[sid], thick[sid] = model.preset.young_clutch_off, model.preset.thick_clutch_off
        self.sliders, self.cables = None, []
        self.cable_pos, self.cable_sel = [], []  # the cables' dense Hessian blocks in the pattern
        if len(sid) and model.clutch_cable:
            self.cables = self._cables(sid, sk, scap)
        elif len(sid):
            self.sliders = SliderSet(
                element=T(sid, torch.long), tri=T(el.tri[sid], torch.long),
                coef=T(model.slip_coef[sid - model.n_faces]), area=T(el.area[sid]), k=T(sk), cap=T(scap),
                pull_only=model.clutch_buckle)
        mu, lam = lame_plane_stress(young, model.preset.poisson)
        self.tri = T(el.tri, torch.long)
        self.G = T(el.shape_grad)
        self.weight = T(el.area * thick)
        self.mu, self.lam = T(mu), T(lam)
        self.relaxed = T(model.relaxed, torch.bool)
        self.k_contact = T(k_contact)
        self.model_k_contact = k_contact
        self.body = mot.body
        self.bv, self.bn, self.bh = T(mot.body.vertices), T(mot.body.normals), T(mot.body.support)
        self.springs = spr
        self.s_index, self.s_coef = T(spr.index, torch.long), T(spr.coef)
        self.s_target, self.s_k, self.s_group = T(spr.target), T(k_spring), T(spr.group, torch.long)
        pat = model.pattern
        sel, pos = pat.spring_positions(spr.index)
        vals = (k_spring[:, None, None, None] * spr.coef[:, :, None, None] * spr.coef[:, None, :, None]
                * np.ones(3)).ravel()[sel]
        self.spring_hess = np.bincount(pos, weights=vals, minlength=pat.nnz)
        self.elem_sel, self.elem_pos = T(pat.elem_select, torch.long), T(pat.elem_pos, torch.long)
        self.vert_sel, self.vert_pos = T(pat.vert_select, torch.long), T(pat.vert_pos.ravel(), torch.long)
        # neighbour lists from this state's last solve in this process, where exact (contact.NeighborStore)
        self._store_key = (state.name, model.n_vertices, mot.body.key)
        self.cache = NEIGHBORS.get(self._store_key)
        self._cache_obj = self._pre = None
        self.m_garment = model.n_faces
        self.n_evals = 0
        # skin friction (sim.friction) on every vertex, the garment's and the clutches': anchors
        # at the state's (a motion's frame: where the frame before left it, held_after) or at the
        # skin-tight start, the normal forces and normals lagged (set_friction), none until set
        self.friction_on = model.friction > 0.0
        if self.friction_on:
            x0 = self.initial_positions() if state.anchor is None else np.asarray(state.anchor, dtype=np.float64)
            if x0.shape != (model.n_vertices, 3):
                raise ValueError(f"state {state.name}: friction anchor of shape {x0.shape}, expected "
                                 f"({model.n_vertices}, 3)")
            self.fr_anchor, self.fr_strip = T(x0), strip_neighbours(model)
            self.fr_normal, self.fr_along = T(np.zeros_like(x0)), T(np.zeros_like(x0))
            self.fr_bound = T(np.zeros(len(x0)))

    def _cables(self, sid: np.ndarray, sk: np.ndarray, scap: np.ndarray) -> list[Cable]:
        """The cables (``sim.cable``) of the ON clutches whose elements are ``sid`` (q,), with
        the slider stiffness ``sk`` (q,) N/m and cap ``scap`` (q,) N/m of each element."""
        model, T = self.model, self._t
        fo, el = model.face_offsets, model.elements
        clutch = np.searchsorted(fo, sid, side="right") - 2  # (q,) clutch of each element
        out = []
        for k in np.unique(clutch):
            mine = sid[clutch == k]
            ids, W, rest = model.cable_paths[k]
            first = np.searchsorted(sid, mine[0])
            area = el.area[mine]
            width = float(model.strip_width[k])
            spacing = SPACING * width * min(scap[first], sk[first]) / (rest / (len(W) - 1))
            out.append(Cable(clutch=int(k), vertices=T(ids, torch.long), W=T(W), rest=rest, width=width,
                             k=T(sk[first]), cap=T(scap[first]), elements=T(mine, torch.long),
                             share=T(area / area.sum()), spacing=float(spacing)))
            self.cable_pos.append(T(model.pattern.dense_pos[k], torch.long))
            self.cable_sel.append(T(model.pattern.dense_select[k], torch.long))
        return out

    def _t(self, a, dtype=torch.float64):
        return torch.as_tensor(np.ascontiguousarray(a), dtype=dtype, device=self.device)

    def initial_positions(self) -> np.ndarray:
        return self.model.initial_positions(self.state.motion.garment_x0)

    def _contact_args(self, x: torch.Tensor):
        """(bv, bn, bh, index, valid, nearest) for the current neighbour lists at x."""
        prev = self.cache
        self.cache = c = update_neighbors(self.body, x.detach().cpu().numpy(), prev)
        if self._cache_obj is not c:
            self._cache_t = (self._t(c.index, torch.long), self._t(c.valid), self._t(c.nearest, torch.long))
            # a few lists re-queried: recompute only their rows of the gathered quantities
            partial = self._cache_obj is prev and c.changed is not None and 2 * len(c.changed) < len(c.index)
            rows = self._t(c.changed, torch.long) if partial else None
            self._pre = gather(self.bv, self.bn, self.bh, *self._cache_t, rows=rows, into=self._pre)
            self._cache_obj = c
            NEIGHBORS.put(self._store_key, c)
        return (self.bv, self.bn, self.bh) + self._cache_t

    def _check(self, value: torch.Tensor, term: str, what: str = "energy") -> None:
        if not bool(torch.isfinite(value).all()):
            raise SimulationError(f"state {self.name!r}: non-finite {what} in term {term!r}")

    def evaluate(self, x: torch.Tensor, order: int = 0, check: bool = True, exact: bool = False):
        """Total energy (float, J), gradient (N, 3) tensor (order >= 1) and Hessian CSC
        values (nnz,) numpy (order 2).  With ``check`` a non-finite term raises
        SimulationError; without, a non-finite energy is returned as ``inf``.  ``exact``
        asks for the exact (unprojected, full contact) Hessian instead of the PSD one."""
        self.n_evals += 1
        proj = "none" if exact else self.projection
        e_m, g_m, h_m = self._membrane(x, order, proj)
        e_k, g_k, h_k = self._cable_terms(x, order, proj == "none")
        e_c, g_c, h_c = contact(x, self.k_contact, *self._contact_args(x), order=order,
                                exact_hessian=exact or self.exact_contact_hessian, pre=self._pre,
                                tree=self.body.tree)
        e_s, g_s = springs(x, self.s_index, self.s_coef, self.s_target, self.s_k, order=min(order, 1))
        e_f, g_f, h_f = self._friction(x, order)
        total = e_m.sum() + e_c.sum() + e_s.sum() + e_f.sum() + sum(e_k)
        if check:
            if not bool(torch.isfinite(total)):
                for term, val in self._split_terms(self._with_cables(e_m, e_k), e_c, e_s, e_f).items():
                    self._check(val, term)
        elif not bool(torch.isfinite(total)):
            total = torch.tensor(float("inf"))
        if order == 0:
            return float(total), None, None
        grad = g_c + g_s
        grad.index_add_(0, self.tri.reshape(-1), g_m.reshape(-1, 3))
        for cab, gk in zip(self.cables, g_k):
            grad.index_add_(0, cab.vertices, gk)
        if g_f is not None:
            grad[: len(g_f)] += g_f
        if check and not bool(torch.isfinite(grad).all()):
            self._check(g_m, "membrane", "gradient")
            self._check(g_c, "contact", "gradient")
            self._check(g_s, "springs", "gradient")
            if g_f is not None:
                self._check(g_f, "friction", "gradient")
        if order == 1:
            return float(total), grad, None
        if h_f is not None:
            h_c[: len(h_f)] += h_f
        data = torch.zeros(self.model.pattern.nnz, dtype=x.dtype, device=x.device)
        data.index_add_(0, self.elem_pos, h_m.reshape(-1)[self.elem_sel])
        data.index_add_(0, self.vert_pos, h_c.reshape(-1, 9)[:, self.vert_sel].reshape(-1))
        for block, sel, pos in zip(h_k, self.cable_sel, self.cable_pos):
            data.index_add_(0, pos, block.reshape(-1)[sel])
        hess = data.cpu().numpy() + self.spring_hess
        if check and not np.all(np.isfinite(hess)):
            raise SimulationError(f"state {self.name!r}: non-finite Hessian")
        return float(total), grad, hess

    def _membrane(self, x: torch.Tensor, order: int, projection: str):
        """Per-element membrane energy (M,), gradient (M, 3, 3) and Hessian (M, 9, 9), the
        sliders of slipping clutch elements added to their elements."""
        e, g, h = membrane(x, self.tri, self.G, self.weight, self.mu, self.lam, self.relaxed,
                           order=order, projection=projection)
        if self.sliders is not None:
            es, gs, hs = slider_energy(x, self.sliders, order, project=projection != "none")
            idx = self.sliders.element
            e = e.index_add(0, idx, es)
            if gs is not None:
                g = g.index_add(0, idx, gs)
            if hs is not None:
                h = h.index_add(0, idx, hs)
        return e, g, h

    def _cable_terms(self, x: torch.Tensor, order: int, exact: bool = False):
        """Per ON cable (``sim.cable``): energies (J), gradients over its vertices (v, 3) and
        Hessian blocks (3v, 3v) (``exact``: unprojected); empty lists without cables."""
        out = [cable_energy(x, c, order, project=not exact) for c in self.cables]
        return [o[0] for o in out], [o[1] for o in out], [o[2] for o in out]

    def _with_cables(self, e_m: torch.Tensor, e_k) -> torch.Tensor:
        """Per-element membrane energies (M,) with each cable's energy shared among its
        strip's elements by rest area."""
        for c, ek in zip(self.cables, e_k):
            e_m = e_m.index_add(0, c.elements, ek * c.share)
        return e_m

    def _split_terms(self, e_m, e_c, e_s, e_f) -> dict[str, torch.Tensor]:
        m = self.m_garment
        out = {"membrane_garment": e_m[:m].sum(), "membrane_clutch": e_m[m:].sum(), "contact": e_c.sum()}
        for i, g in enumerate(GROUPS):
            out[g] = e_s[self.s_group == i].sum()
        if self.friction_on:
            out["friction"] = e_f.sum()
        return out

    def _friction(self, x: torch.Tensor, order: int):
        """The friction potential on every vertex (``sim.friction``): energy (N,) (zeros
        without friction), gradient (N, 3) and Hessian (N, 3, 3) or None."""
        if not self.friction_on:
            return x.new_zeros(1), None, None
        return friction(x, self.fr_anchor, self.fr_normal, self.fr_bound, self.model.friction_slip,
                        order=order, along=self.fr_along)

    def friction_lag(self, x: torch.Tensor) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The friction bounds ``mu lambda`` (N,) N, unit contact normals (N, 3) and the
        strips' directions (N, 3) (zero off the strips) of every vertex at x
        (``sim.friction.normal_forces``, ``strip_directions``), for :meth:`set_friction`."""
        model = self.model
        _, g_m, _ = self._membrane(x, 1, self.projection)
        _, g_s = springs(x, self.s_index, self.s_coef, self.s_target, self.s_k, order=1)
        g = g_s.clone()
        g.index_add_(0, self.tri.reshape(-1), g_m.reshape(-1, 3))
        for c, gk in zip(self.cables, self._cable_terms(x, 1)[1]):
            g.index_add_(0, c.vertices, gk)
        f, gf = self.contact_linearization(x)
        normal = gf / np.maximum(np.linalg.norm(gf, axis=1), 1e-300)[:, None]
        lam = normal_forces(g.cpu().numpy(), normal, f, near=0.1 * model.mean_edge)
        along = strip_directions(x.detach().cpu().numpy(), self.fr_strip, normal)
        return model.friction * lam, normal, along

    def set_friction(self, bound: np.ndarray, normal: np.ndarray, along: np.ndarray) -> None:
        """Hold the friction bounds (N,) N, normals (N, 3) and strip directions (N, 3) for
        the next solves."""
        self.fr_bound, self.fr_normal, self.fr_along = self._t(bound), self._t(normal), self._t(along)

    def terms(self, x: torch.Tensor) -> tuple[dict[str, float], np.ndarray]:
        """Energy by term (J; ``friction`` is the dissipation potential, not stored energy)
        and per-element membrane energy (M,) J at x."""
        e_m, _, _ = self._membrane(x, 0, self.projection)
        e_m = self._with_cables(e_m, self._cable_terms(x, 0)[0])
        e_c, _, _ = contact(x, self.k_contact, *self._contact_args(x), order=0, pre=self._pre,
                            tree=self.body.tree)
        e_s, _ = springs(x, self.s_index, self.s_coef, self.s_target, self.s_k, order=0)
        e_f, _, _ = self._friction(x, 0)
        split = self._split_terms(e_m, e_c, e_s, e_f)
        for term, val in split.items():
            self._check(val, term)
        return {k: float(v) for k, v in split.items()}, e_m.cpu().numpy()

    def contact_linearization(self, x: torch.Tensor):
        """IMLS value f (N,) and gradient (N, 3) at every vertex (numpy)."""
        args = self._contact_args(x)
        f, gf, _ = imls_fast(x, *args, order=1, tree=self.body.tree)
        return f.cpu().numpy(), gf.cpu().numpy()

    def add_contact_stiffness(self, data: np.ndarray, vertices: np.ndarray, gradf: np.ndarray) -> np.ndarray:
        """Return ``data`` (nnz,) plus the Gauss-Newton contact block ``2 k grad f grad f^T``
        on ``vertices`` (a,) with IMLS gradients ``gradf`` (a, 3)."""
        k = self.model_k_contact[vertices]
        blocks = (2.0 * k)[:, None, None] * gradf[:, :, None] * gradf[:, None, :]
        out = data.copy()
        pos = self.model.pattern.vert_pos[vertices]  # (a, 6)
        out[pos.ravel()] += blocks.reshape(-1, 9)[:, self.model.pattern.vert_select].ravel()
        return out

    def branches(self, x: torch.Tensor) -> np.ndarray:
        """(M,) element branch: 0 normal, 1 slack, 2 uniaxial (see ``membrane.branches``)."""
        return branches(x, self.tri, self.G, self.relaxed).cpu().numpy()

    def max_force(self, grad: torch.Tensor) -> float:
        """Largest nodal force norm, N."""
        return float(torch.linalg.vector_norm(grad, dim=1).max())

    def residual(self, grad: torch.Tensor) -> float:
        """Convergence measure: ``max_v |dE/dx_v| / (s_v L)`` (dimensionless, see ``options``)."""
        return float((torch.linalg.vector_norm(grad, dim=1) / self.force_scale).max())
