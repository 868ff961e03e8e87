"""Clutch holding force (sim.slip): derivatives, convexity, a strip in uniaxial tension."""

from __future__ import annotations

import numpy as np
import pytest
import torch
from tube_strip import pull_strip

from kgarment.sim import build_model
from kgarment.sim.materials import REFERENCE
from kgarment.sim.slip import (
    EPS0,
    HARDENING,
    SMOOTH,
    SliderSet,
    axial_coefficients,
    electrostatic_stress,
    slider_energy,
    slider_law,
)
from kgarment.sim.synthetic import Tube


def _sliders(rng, q=40):
    """q random triangles (x (3q, 3) rest) with sliders along random in-plane directions."""
    from kgarment.sim.membrane import TriangleElements

    rest = rng.normal(size=(3 * q, 3)) * 0.01
    tri = np.arange(3 * q).reshape(q, 3)
    el = TriangleElements.from_mesh(rest, tri)
    coef = np.empty((q, 3))
    for i in range(q):  # a centre line through the triangle along a random in-plane direction
        p = rest[tri[i]]
        d = (p[1] - p[0]) * rng.uniform(0.2, 1) + (p[2] - p[0]) * rng.uniform(-1, 1)
        line = np.stack([p.mean(0) - d, p.mean(0) + d])
        local = np.concatenate([p, line])
        coef[i] = axial_coefficients(local, np.array([[0, 1, 2]]), el.shape_grad[i:i + 1], np.array([3, 4]))[0]
    k = rng.uniform(1e3, 1e4, q)
    t = lambda a, dt=torch.float64: torch.as_tensor(a, dtype=dt)
    s = SliderSet(element=t(np.arange(q), torch.long), tri=t(tri, torch.long), coef=t(coef),
                  area=t(el.area), k=t(k), cap=t(k * rng.uniform(0.02, 0.1, q)))
    return rest, s


def _deformed(rest, s, rng, strains):
    """Each triangle stretched along its slider axis to the strains (q,) (plus a rotation)."""
    x = rest.copy()
    coef = s.coef.numpy()
    for i, e in enumerate(strains):
        p = rest[3 * i: 3 * i + 3]
        v = np.einsum("bi,b->i", p, coef[i])  # rest axial vector, length 1
        c = p.mean(0)
        # stretch along v by (1 + e): p -> p + e (p - c).v v
        x[3 * i: 3 * i + 3] = p + e * ((p - c) @ v)[:, None] * v[None, :]
    q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
    return x @ q.T


def check_slider_derivatives(x, s, g, H, vertices, h=1e-7):
    """The sliders' gradient g and exact Hessian H at x against central differences of the
    energy and of the gradient, moving each of ``vertices`` along each axis."""
    for i in vertices:
        for c in range(3):
            dx = torch.zeros_like(x)
            dx[i, c] = h
            ep, gp, _ = slider_energy(x + dx, s, order=1)
            em, gm, _ = slider_energy(x - dx, s, order=1)
            el, b = divmod(int(i), 3)
            fd = float((ep - em)[el]) / (2 * h)
            assert float(g[el, b, c]) == pytest.approx(fd, rel=1e-5, abs=1e-9 * float(s.k.max() * s.area.max()) / 0.01)
            fdh = ((gp - gm)[el] / (2 * h)).reshape(9)
            assert np.allclose(H[el, :, 3 * b + c].numpy(), fdh.numpy(), rtol=1e-4, atol=1e-6 * float(H.abs().max()))


def test_rest_axial_vector_has_unit_length():
    rng = np.random.default_rng(0)
    rest, s = _sliders(rng)
    v = torch.einsum("qbi,qb->qi", torch.as_tensor(rest)[s.tri], s.coef)
    assert torch.allclose(torch.linalg.vector_norm(v, dim=1), torch.ones(len(v), dtype=torch.float64), atol=1e-12)
    e, _, _ = slider_energy(torch.as_tensor(rest), s)
    assert float(e.abs().max()) < 1e-12 * float((s.k * s.area).max())


def test_slider_law_integrates_and_holds():
    """psi' is the derivative of psi and psi'' of psi' (finite differences along e), the force
    is k e below the ramp, q from e2 on (+ the hardening), and the law is odd in e."""
    k, q = torch.tensor(1e4, dtype=torch.float64), torch.tensor(300.0, dtype=torch.float64)
    e_h = float(q / k)
    e = torch.linspace(-4 * e_h, 4 * e_h, 2001, dtype=torch.float64)
    psi, dpsi, ddpsi = slider_law(e, k, q)
    de = 1e-7
    p1, d1, _ = slider_law(e + de, k, q)
    p0, d0, _ = slider_law(e - de, k, q)
    assert torch.allclose((p1 - p0) / (2 * de), dpsi, rtol=1e-6, atol=1e-6 * float(q))
    kink = ((e.abs() - (1 + SMOOTH) * e_h).abs() < 2 * de)  # psi'' jumps from 0 to the hardening there
    assert torch.allclose(((d1 - d0) / (2 * de))[~kink], ddpsi[~kink], rtol=1e-5, atol=1e-5 * float(k))
    low = e.abs() <= (1 - SMOOTH) * e_h
    assert torch.allclose(dpsi[low], k * e[low], rtol=1e-12)
    high = e.abs() >= (1 + SMOOTH) * e_h
    expected = q * (1 + HARDENING * (e[high].abs() - (1 + SMOOTH) * e_h)) * torch.sign(e[high])
    assert torch.allclose(dpsi[high], expected, rtol=1e-12)
    assert torch.allclose(psi, psi.flip(0)) and torch.allclose(dpsi, -dpsi.flip(0))
    assert bool((ddpsi >= 0).all())


@pytest.mark.parametrize("regime", ["compressed", "stuck", "ramp", "sliding"])
def test_slider_gradient_and_hessian_match_finite_differences(regime):
    rng = np.random.default_rng({"compressed": 1, "stuck": 2, "ramp": 3, "sliding": 4}[regime])
    rest, s = _sliders(rng)
    e_h = (s.cap / s.k).numpy()
    strains = e_h * {"compressed": -rng.uniform(0.1, 3.0, len(e_h)), "stuck": rng.uniform(0.1, 0.4, len(e_h)),
                     "ramp": rng.uniform(0.6, 1.4, len(e_h)), "sliding": rng.uniform(2.0, 4.0, len(e_h))}[regime]
    x = torch.as_tensor(_deformed(rest, s, rng, strains) + rng.normal(size=rest.shape) * 1e-5)
    e, g, H = slider_energy(x, s, order=2, project=False)  # the exact Hessian
    assert (e.numpy() > 0).all()
    check_slider_derivatives(x, s, g, H, rng.choice(len(rest), 6, replace=False))
    _, _, Hp = slider_energy(x, s, order=2)  # projected: PSD everywhere, exact in tension
    eig = torch.linalg.eigvalsh(Hp)
    assert float(eig.min()) >= -1e-9 * float(eig.max())
    if regime != "compressed":
        assert torch.allclose(Hp, H)


def test_electrostatic_stress_is_the_parallel_plate_formula():
    # friction 0.5, eps_r 2, 100 V over 10 um: 0.5 * eps0 * 2 * 1e4 / (2 * 1e-10)
    assert electrostatic_stress(100.0, 10e-6, 2.0, 0.5) == pytest.approx(0.5 * EPS0 * 1e14, rel=1e-12)


@pytest.mark.parametrize("stretch", [0.001, 0.03])
@pytest.mark.parametrize("activation", [1.0, 0.5])
def test_a_strip_holds_up_to_its_holding_force_and_slides_at_it_beyond(stretch, activation):
    """A 14 x 1 cm clutch along a tube stretched along its axis (as test_sim_forces), with a
    holding force of 0.5 N: the strip carries the slider's force (k = (Y t)(g) - (Y t)_off:
    ``k w eps`` below the ramp, ``g^2 F_h (1 + HARDENING (eps - e2))`` beyond it) plus the
    textile guide (the OFF membrane, ``s_off w eps``) that is always there.  A 20 N holding
    force never slips here and gives the locked clutch's tension."""
    hold = 0.5
    s_on = ((activation * REFERENCE.young_clutch_on + (1 - activation) * REFERENCE.young_clutch_off)
            * (activation * REFERENCE.thick_clutch_on + (1 - activation) * REFERENCE.thick_clutch_off))
    s_off = REFERENCE.young_clutch_off * REFERENCE.thick_clutch_off
    eps, t, w, _, _, _ = pull_strip(stretch, hold, activation)
    cap = activation**2 * hold
    e_h = cap / ((s_on - s_off) * w)
    assert not (1 - SMOOTH) * e_h < eps < (1 + SMOOTH) * e_h  # a case on the ramp would test less
    slider = (s_on - s_off) * w * eps if eps < e_h else cap * (1 + HARDENING * (eps - (1 + SMOOTH) * e_h))
    assert t == pytest.approx(slider + s_off * w * eps, rel=0.05)
    eps_l, t_l, _, _, _, _ = pull_strip(stretch, None, activation)
    _, t_h, _, _, _, _ = pull_strip(stretch, 20.0, activation)
    assert t_h == pytest.approx(t_l, rel=0.05)  # the same strip; the slider has no Poisson coupling
    assert t_l == pytest.approx(s_on * w * eps_l, rel=0.05)
    if (s_on - s_off) * w * eps_l > 1.5 * activation**2 * hold:  # it slides: lower force, longer strip
        assert t < 0.75 * t_l and eps > eps_l


def test_holding_force_must_be_positive():
    tube = Tube(0.05, 0.0, 0.3, 12, 8)
    clutch = tube.clutch("c0", 0.3, 0.08, 0.22, 0.01, 8)
    with pytest.raises(ValueError, match="holding_force"):
        build_model(tube.vertices, tube.faces, [clutch], holding_force=[0.0])
    with pytest.raises(ValueError, match="holding_force"):
        build_model(tube.vertices, tube.faces, [clutch], holding_force=[1.0, 2.0])


def test_clutch_hardware_in_the_problem_file(tmp_path):
    """[clutches] model / holding_force / voltage: parsed, the garment's default layout kept
    when the section names no clutches, written back only where not the default, and the
    holding forces resolved per clutch (stress x width x length, the electrostatic formula,
    or by name)."""
    from types import SimpleNamespace

    from kgarment.problem import parse_problem, problem_to_dict
    from kgarment.problem.build import holding_forces

    plain = parse_problem({})
    assert "clutches" not in problem_to_dict(plain)  # default hardware: files and hashes as before
    p = parse_problem({"clutches": {"model": "slip"}})
    assert p.clutch_spec().layout == "shirt" and p.clutch_spec().hardware.model == "slip"
    again = parse_problem(problem_to_dict(p))
    assert again.clutch_spec() == p.clutch_spec()
    strips = [SimpleNamespace(name="a", width=0.01, length=0.15), SimpleNamespace(name="b", width=0.02, length=0.1)]
    assert holding_forces(plain.clutch_spec().hardware, strips) is None
    assert holding_forces(p.clutch_spec().hardware, strips) == pytest.approx([315.0, 420.0])  # 21 N/cm^2
    q = parse_problem({"clutches": {"layout": "shirt", "voltage": 300.0, "permittivity": 3.0,
                                    "dielectric_thickness": 1e-5, "friction": 0.5, "holding_force": {"b": 7.5}}})
    hw = q.clutch_spec().hardware
    assert hw.model == "slip"  # a voltage implies it
    tau = 0.5 * EPS0 * 3.0 * 300.0**2 / (2 * 1e-10)
    assert holding_forces(hw, strips) == pytest.approx([tau * 0.01 * 0.15, 7.5])
    assert parse_problem(problem_to_dict(q)).clutch_spec().hardware == hw
    every = parse_problem({"clutches": {"holding_force": 40}})
    assert holding_forces(every.clutch_spec().hardware, strips) == pytest.approx([40.0, 40.0])
