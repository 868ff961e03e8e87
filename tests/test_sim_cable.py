"""The cable clutch (sim.cable): derivatives, slack when shortened on the whole, a strip in
uniaxial tension, the assembled Hessian, the problem file."""

from __future__ import annotations

import numpy as np
import pytest
import torch
from tube_strip import pull_strip

from kgarment.sim import (
    StateProblem,
    build_model,
)
from kgarment.sim.cable import Cable, cable_energy, strip_path
from kgarment.sim.materials import REFERENCE
from kgarment.sim.membrane import TriangleElements
from kgarment.sim.slip import (
    HARDENING,
    SMOOTH,
    SliderSet,
    axial_coefficients,
    path_length,
    rest_width,
    slider_energy,
    slider_law,
)
from kgarment.sim.synthetic import Tube

T = lambda a, dt=torch.float64: torch.as_tensor(np.asarray(a), dtype=dt)


def _strips(n_seg=(12, 9), k=(4e3, 9e3), cap=(60.0, 150.0), spacing=0.0):
    """Two straight strips (Tube.clutch meshes, 1 cm wide) side by side in one vertex array:
    the rest positions (nv, 3), their cables, the strips, and their elements' sliders (the
    slip model's, for comparison)."""
    tube = Tube(0.05, 0.0, 0.3, 24, 16)
    strips = [tube.clutch("a", 0.3, 0.05, 0.2, 0.01, n_seg[0]), tube.clutch("b", 2.0, 0.1, 0.22, 0.01, n_seg[1])]
    rest, cables, tri, coef, area, kk, cc, off = [], [], [], [], [], [], [], 0
    for c, s in enumerate(strips):
        r = s.rest_vertices()
        el = TriangleElements.from_mesh(r, s.faces)
        ids, W = strip_path(s.anchors, s.centerline)
        cables.append(Cable(clutch=c, vertices=T(off + ids, torch.long), W=T(W), rest=path_length(W @ r[ids]),
                            width=rest_width(r, s.faces, s.centerline), k=T(k[c]), cap=T(cap[c]),
                            elements=T(np.arange(len(s.faces)), torch.long), share=T(el.area / el.area.sum()),
                            spacing=spacing))
        rest.append(r)
        tri.append(s.faces + off)
        coef.append(axial_coefficients(r, s.faces, el.shape_grad, s.centerline))
        area.append(el.area)
        kk.append(np.full(len(s.faces), k[c]))
        cc.append(np.full(len(s.faces), cap[c]))
        off += len(r)
    tri = np.concatenate(tri)
    sliders = SliderSet(element=T(np.arange(len(tri)), torch.long), tri=T(tri, torch.long), coef=T(np.concatenate(coef)),
                        area=T(np.concatenate(area)), k=T(np.concatenate(kk)), cap=T(np.concatenate(cc)), pull_only=True)
    return np.concatenate(rest), cables, strips, sliders


def _stretched(rest, strips, strains, rng):
    """Each strip stretched along its own axis by its strain (a profile along the strip from
    start to end: a callable of the rest arc parameter in [0, 1]), then rotated and moved."""
    x, off = rest.copy(), 0
    for s, strain in zip(strips, strains):
        r = rest[off: off + len(s.vertices)]
        line = r[s.centerline]
        axis = (line[-1] - line[0]) / np.linalg.norm(line[-1] - line[0])
        u = (r - line[0]) @ axis  # rest coordinate along the strip
        t = np.linspace(0, u.max(), 400)
        disp = np.concatenate([[0], np.cumsum(strain(t[1:] / u.max()) * np.diff(t))])  # integral of the strain
        x[off: off + len(r)] = r + np.interp(u, t, disp)[:, None] * axis
        off += len(r)
    q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
    return x @ q.T + rng.normal(size=3)


@pytest.mark.parametrize("spacing", [0.0, 300.0])
@pytest.mark.parametrize("regime", ["slack", "stuck", "ramp", "sliding"])
def test_cable_gradient_and_hessian_match_finite_differences(regime, spacing):
    """Strips stretched unevenly (a sine profile about a level in units of the strain e_h
    at which the cable reaches its holding force) and bent (noise): energy, gradient and
    Hessian against central differences (the exact one, unprojected); the projected Hessian
    PSD; nothing at all when slack without the spacing term (which stores only the
    segments' unevenness, unchanged by an even stretch)."""
    rng = np.random.default_rng({"slack": 1, "stuck": 2, "ramp": 3, "sliding": 4}[regime])
    rest, cables, strips, _ = _strips(spacing=spacing)
    level = [{"slack": -0.5, "stuck": 0.3, "ramp": 1.0, "sliding": 3.0}[regime] * float(c.cap / c.k) for c in cables]
    strains = [lambda t, m=m: m * (1 + 0.8 * np.sin(3 * t)) for m in level]
    x = T(_stretched(rest, strips, strains, rng) + rng.normal(size=rest.shape) * 1e-4)
    for c, m in zip(cables, level):
        assert np.sign(float(c.strain(x))) == np.sign(m)
        energy, g, H = cable_energy(x, c, order=2, project=False)
        if regime == "slack" and spacing == 0.0:
            assert float(energy) == 0.0 and float(g.abs().max()) == 0.0 and float(H.abs().max()) == 0.0
            assert c.tension(x) == 0.0
            continue
        assert c.tension(x) == pytest.approx(c.width * float(slider_law(c.strain(x), c.k, c.cap, True)[1]), rel=1e-12)
        ids = c.vertices
        step = 1e-7
        for i in rng.choice(3 * len(ids), 12, replace=False):
            dx = torch.zeros_like(x)
            dx[ids[i // 3], i % 3] = step
            ep, gp, _ = cable_energy(x + dx, c, order=1)
            em, gm, _ = cable_energy(x - dx, c, order=1)
            assert float(g.reshape(-1)[i]) == pytest.approx(float(ep - em) / (2 * step), rel=1e-5,
                                                            abs=1e-6 * float(g.abs().max()))
            assert torch.allclose(H[:, i], (gp - gm).reshape(-1) / (2 * step), rtol=1e-4, atol=1e-6 * float(H.abs().max()))
        assert torch.allclose(H, H.T)
        eig = torch.linalg.eigvalsh(cable_energy(x, c, order=2)[2])
        assert float(eig.min()) >= -1e-9 * float(eig.max())
    if spacing:  # an even stretch of the straight strips changes no segment's share
        x = T(_stretched(rest, strips, [lambda t: 0.0 * t, lambda t: 0.0 * t], rng))
        e0 = [float(cable_energy(x, c)[0]) for c in cables]
        x = T(_stretched(rest, strips, [lambda t: 0.0 * t - 0.05, lambda t: 0.0 * t - 0.05], rng))
        assert [float(cable_energy(x, c)[0]) for c in cables] == pytest.approx(e0, abs=1e-9)


def test_a_strip_shortened_on_the_whole_is_slack_however_its_parts_are_stretched():
    """The strain profile that made the band model lock (docs/notes/design.md): one half of
    the strip buckled -12%, the other stretched 4%.  The cable stores nothing; per-element
    pull-only sliders (the slip model with buckling strips) store the stretched half's energy."""
    rng = np.random.default_rng(5)
    rest, cables, strips, sliders = _strips(cap=(1e4, 1e4))  # holding forces far above: quadratic
    profile = lambda t: np.where(t < 0.5, -0.12, 0.04)
    x = T(_stretched(rest, strips, [profile, profile], rng))
    for c in cables:
        assert float(c.strain(x)) == pytest.approx(-0.04, abs=2e-3)  # the mean of the two halves
        assert float(cable_energy(x, c)[0]) == 0.0
    e_sl, _, _ = slider_energy(x, sliders)
    v = torch.einsum("qbi,qb->qi", x[sliders.tri], sliders.coef)
    lam = torch.linalg.vector_norm(v, dim=1).numpy()
    full = (sliders.area * 0.5 * sliders.k * 0.04**2).numpy()  # k e^2 / 2 per area, below the holding force
    assert 0.999 * full[lam > 1.039].sum() <= float(e_sl.sum()) <= 1.001 * full[lam > 1.0].sum()
    assert full[lam > 1.039].sum() > 0.3 * full.sum()


@pytest.mark.parametrize("stretch", [0.001, 0.03, -0.02])
@pytest.mark.parametrize("activation", [1.0, 0.5])
def test_a_cable_strip_in_uniaxial_tension_follows_the_hand_calculation(stretch, activation):
    """A 14 x 1 cm clutch along a tube stretched (or shortened) along its axis, holding
    0.5 N: the cable carries ``k w eps`` (k = (Y t)(g) - (Y t)_off) below the holding force,
    ``g^2 F_h (1 + HARDENING (eps - e2))`` beyond, plus the textile guide ``s_off w eps``;
    shortened, nothing (the free cloth around takes the shortening; the cable is slack and
    the strip nearly unstrained).  Evenly stretched, the cable and the slip model agree."""
    hold = 0.5
    s_on = ((activation * REFERENCE.young_clutch_on + (1 - activation) * REFERENCE.young_clutch_off)
            * (activation * REFERENCE.thick_clutch_on + (1 - activation) * REFERENCE.thick_clutch_off))
    s_off = REFERENCE.young_clutch_off * REFERENCE.thick_clutch_off
    eps, t, w, model, state, r = pull_strip(stretch, hold, activation, cable=True)
    cap = activation**2 * hold
    e_h = cap / ((s_on - s_off) * w)
    assert not (1 - SMOOTH) * e_h < eps < (1 + SMOOTH) * e_h
    if stretch < 0:
        (c,) = StateProblem(model, np.ones(model.n_faces), state).cables
        x = torch.as_tensor(r.x)
        assert eps < 0 and float(c.strain(x)) < 0 and c.tension(x) == 0.0 and abs(t) < 0.01 * cap
        assert float(cable_energy(x, c)[0]) < 1e-3 * cap * 0.14 * abs(stretch)  # the spacing term's only
        return
    if eps < e_h:
        cable = (s_on - s_off) * w * eps
    else:
        cable = cap * (1 + HARDENING * (eps - (1 + SMOOTH) * e_h))
    assert t == pytest.approx(cable + s_off * w * eps, rel=0.05, abs=0.02 * s_off * w * abs(eps))
    if stretch > 0:
        _, t_slip, _, _, _, _ = pull_strip(stretch, hold, activation)
        assert t == pytest.approx(t_slip, rel=0.03)


def test_the_assembled_hessian_holds_the_cable_block():
    """With a cable ON, the simulator's Hessian (CSC pattern with the strip's dense block)
    times a direction equals the finite difference of its gradient along it (contact off:
    its Hessian is the IMLS's approximation, checked in test_sim_contact)."""
    _, _, _, model, state, r = pull_strip(0.03, 1e5, cable=True)
    prob = StateProblem(model, np.ones(model.n_faces), state)
    assert len(prob.cables) == 1 and len(model.pattern.dense_pos) == 1
    prob.k_contact = torch.zeros_like(prob.k_contact)
    x = torch.as_tensor(r.x)
    _, _, data = prob.evaluate(x, order=2, exact=True)
    L = model.pattern.matrix(data)
    H = (L + L.T).toarray() - np.diag(L.diagonal())
    rng = np.random.default_rng(0)
    dx = np.zeros_like(r.x)
    off = model.vertex_offsets
    dx[off[1]: off[2]] = rng.normal(size=(off[2] - off[1], 3)) * 1e-7
    _, gp, _ = prob.evaluate(x + torch.as_tensor(dx), order=1)
    _, gm, _ = prob.evaluate(x - torch.as_tensor(dx), order=1)
    fd = ((gp - gm) / 2).numpy().reshape(-1)
    hd = H @ dx.reshape(-1)
    assert np.allclose(hd, fd, rtol=1e-4, atol=1e-6 * np.abs(hd).max())


def test_cable_clutches_in_the_problem_file():
    from kgarment.problem import parse_problem, problem_to_dict
    from kgarment.problem.build import holding_forces

    p = parse_problem({"clutches": {"model": "cable"}})
    hw = p.clutch_spec().hardware
    assert hw.model == "cable"
    assert parse_problem(problem_to_dict(p)).clutch_spec().hardware == hw
    from types import SimpleNamespace

    strips = [SimpleNamespace(name="a", width=0.01, length=0.15)]
    assert holding_forces(hw, strips) == pytest.approx([315.0])  # 21 N/cm^2 x 1 x 15 cm
    tube = Tube(0.05, 0.0, 0.3, 12, 8)
    clutch = tube.clutch("c0", 0.3, 0.08, 0.22, 0.01, 8)
    with pytest.raises(ValueError, match="holding_force"):
        build_model(tube.vertices, tube.faces, [clutch], clutch_cable=True)
