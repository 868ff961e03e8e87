"""Membrane energy: hand values, analytic uniaxial stretch, wrinkling, derivatives."""

import math

import numpy as np
import pytest
import torch
from scipy.optimize import brentq, minimize_scalar

from kgarment.sim import (
    PAPER,
    REFERENCE,
    garment_material,
    lame_plane_stress,
    log_stiffness_derivative,
)
from kgarment.sim.membrane import TriangleElements, membrane

Y, NU, T = 0.5e6, 0.33, 0.27e-3
MU, LAM = (float(v) for v in lame_plane_stress(Y, NU))
REST = np.array([[0.0, 0.0, 0.0], [0.1, 0.0, 0.0], [0.0, 0.1, 0.0]])  # legs 10 cm, area 5e-3 m^2


def _tri(rest=REST):
    el = TriangleElements.from_mesh(rest, np.array([[0, 1, 2]]))
    return torch.tensor(el.tri), torch.tensor(el.shape_grad), float(el.area[0])


def energy(x, relaxed, rest=REST, order=0, projection="none", mu=MU, lam=LAM, t=T):
    tri, G, area = _tri(rest)
    f64 = torch.float64
    return membrane(torch.as_tensor(x, dtype=f64), tri, G, torch.tensor([area * t], dtype=f64),
                    torch.tensor([mu], dtype=f64), torch.tensor([lam], dtype=f64),
                    torch.tensor([relaxed]), order=order, projection=projection)


def stretched(l1, l2):
    return REST * np.array([l1, l2, 1.0])


def test_single_triangle_by_hand():
    # F = diag(1.2, 1): I_C = 1.44 + 1 = 2.44, J = 1.2
    mu = 0.5e6 / (2 * 1.33)
    lam = 0.5e6 * 0.33 / (1 - 0.33**2)
    w = mu / 2 * (2.44 - 2) - mu * math.log(1.2) + lam / 2 * math.log(1.2) ** 2
    # mu = 187969.92 Pa, lam = 185164.40 Pa: 41353.38 - 34270.97 + 3077.54 = 10159.95 Pa
    assert w == pytest.approx(10159.953, rel=1e-6)
    e = w * 5e-3 * 0.27e-3  # W * area * thickness = 1.37159e-2 J
    for relaxed in (False, True):
        assert float(energy(stretched(1.2, 1.0), relaxed)[0][0]) == pytest.approx(e, rel=1e-12)
    assert e == pytest.approx(1.371594e-2, rel=1e-6)


@pytest.mark.parametrize("relaxed", [False, True])
def test_zero_energy_and_force_at_rest(relaxed):
    rot = np.linalg.qr(np.random.default_rng(1).normal(size=(3, 3)))[0]
    x = REST @ rot.T + np.array([0.3, -0.2, 1.0])  # rigid motion
    e, g, _ = energy(x, relaxed, order=1)
    assert abs(float(e[0])) < 1e-18
    assert float(g.abs().max()) < 1e-9 * Y * T * 0.1


def test_uniaxial_stretch_matches_analytic():
    """Stretch l1 along x, free lateral contraction: S_22 = 0 gives
    mu (l2^2 - 1) + lam ln(l1 l2) = 0."""
    for l1 in (1.05, 1.3, 1.8):
        l2 = brentq(lambda s, l1=l1: MU * (s * s - 1) + LAM * math.log(l1 * s), 0.3, 1.0)
        w_exact = MU / 2 * (l1**2 + l2**2 - 2) - MU * math.log(l1 * l2) + LAM / 2 * math.log(l1 * l2) ** 2
        res = minimize_scalar(lambda s, l1=l1: float(energy(stretched(l1, s), False)[0][0]),
                              bounds=(0.3, 1.0), method="bounded", options={"xatol": 1e-10})
        assert res.x == pytest.approx(l2, rel=1e-6)
        assert res.fun == pytest.approx(w_exact * 5e-3 * T, rel=1e-9)
        # stress: the lateral nodal forces of the analytic state vanish
        _, g, _ = energy(stretched(l1, l2), False, order=1)
        assert float(g[0, :, 1].abs().max()) < 1e-9 * float(g[0, :, 0].abs().max())


def w_uniaxial(lmax):
    """The relaxed energy density: C evaluated at (l_max, l_max^-1/2)."""
    lm = lmax**-0.5
    return MU / 2 * (lmax + lm - 2) - MU * math.log(math.sqrt(lmax * lm)) + LAM / 2 * math.log(math.sqrt(lmax * lm)) ** 2


def test_relaxed_energy_branches():
    a = 5e-3 * T
    # biaxial compression: slack
    e, g, _ = energy(stretched(0.9, 0.8), True, order=1)
    assert float(e[0]) == 0.0 and float(g.abs().max()) == 0.0
    # tension + compression: uniaxial value, independent of the compressed stretch
    for l2 in (0.5, 0.7, 0.85):
        assert float(energy(stretched(1.3, l2), True)[0][0]) == pytest.approx(w_uniaxial(1.69) * a, rel=1e-12)
    # the unrelaxed energy is larger there
    assert float(energy(stretched(1.3, 0.5), False)[0][0]) > w_uniaxial(1.69) * a
    # biaxial tension: normal energy
    assert float(energy(stretched(1.2, 1.1), True)[0][0]) == pytest.approx(
        float(energy(stretched(1.2, 1.1), False)[0][0]), rel=1e-14)
    # continuity at the slack / uniaxial boundary (l_max = 1)
    assert float(energy(stretched(1.0 + 1e-7, 0.5), True)[0][0]) < 1e-12 * Y * a


def _fd_check(x, relaxed, h=1e-7):
    x = np.asarray(x, dtype=np.float64)
    _e, g, H = energy(x, relaxed, order=2, projection="none")
    g = g.reshape(-1).numpy()
    H = H[0].numpy()
    gf, Hf = np.zeros(9), np.zeros((9, 9))
    for k in range(9):
        xp, xm = x.copy().reshape(-1), x.copy().reshape(-1)
        xp[k] += h
        xm[k] -= h
        ep, gp, _ = energy(xp.reshape(3, 3), relaxed, order=1)
        em, gm, _ = energy(xm.reshape(3, 3), relaxed, order=1)
        gf[k] = (float(ep[0]) - float(em[0])) / (2 * h)
        Hf[:, k] = ((gp - gm) / (2 * h)).reshape(-1).numpy()
    scale_g = max(np.abs(gf).max(), 1e-300)
    scale_h = max(np.abs(Hf).max(), 1e-300)
    assert np.abs(g - gf).max() <= 1e-6 * scale_g + 1e-12
    assert np.abs(H - Hf).max() <= 1e-5 * scale_h + 1e-9
    assert np.allclose(H, H.T, rtol=0, atol=1e-12 * scale_h)


@pytest.mark.parametrize("seed", range(4))
@pytest.mark.parametrize("kind", ["biaxial", "uniaxial", "mixed", "nearly_isotropic"])
def test_membrane_derivatives_finite_differences(seed, kind):
    rng = np.random.default_rng(seed)
    rot = np.linalg.qr(rng.normal(size=(3, 3)))[0]
    s = {"biaxial": (1.25, 1.15), "uniaxial": (1.3, 0.6), "mixed": (1.15, 0.93),
         "nearly_isotropic": (1.02, 1.0)}[kind]
    x = (stretched(*s) + 0.004 * rng.normal(size=(3, 3))) @ rot.T
    for relaxed in (False, True):
        _fd_check(x, relaxed)


def test_relaxed_hessian_bounded_near_repeated_eigenvalues():
    # l_max ~ 1 + 1e-6, l_min just below l_max^-1/2: r -> 0 in the uniaxial branch
    for eps in (1e-4, 1e-6, 1e-8):
        x = stretched(math.sqrt(1 + eps), math.sqrt(1 - eps))
        _e, _g, H = energy(x, True, order=2, projection="none")
        assert torch.isfinite(H).all() and float(H.abs().max()) < 10 * Y * T
    _fd_check(stretched(math.sqrt(1 + 1e-3), math.sqrt(1 - 1e-3)), True)


@pytest.mark.parametrize("projection", ["analytic", "full"])
def test_projected_hessians_are_psd(projection):
    rng = np.random.default_rng(3)
    for relaxed in (False, True):
        for s in [(1.3, 0.6), (0.8, 0.7), (1.2, 1.1), (1.05, 0.95), (0.9, 1.4)]:
            x = stretched(*s) + 0.01 * rng.normal(size=(3, 3))
            _, _, H = energy(x, relaxed, order=2, projection=projection)
            ev = torch.linalg.eigvalsh(H[0])
            assert float(ev.min()) >= -1e-9 * float(ev.abs().max())
    # exact where the stress is tensile
    x = stretched(1.2, 1.1)
    Hn = energy(x, False, order=2, projection="none")[2]
    Ha = energy(x, False, order=2, projection="analytic")[2]
    assert torch.allclose(Hn, Ha, rtol=1e-12, atol=1e-9)


def test_material_presets_and_interpolation():
    assert PAPER.young_reinforced == 0.5e9 and PAPER.young_clutch_on == 3.0e9
    assert REFERENCE.young_reinforced == 5.7e6 and REFERENCE.thick_clutch_on == 0.35e-3
    y, t = garment_material(np.array([PAPER.x_min, 1.0]), PAPER)
    assert y[1] == 0.5e9 and t[1] == 0.35e-3
    assert y[0] == pytest.approx(0.5e6, rel=2e-2) and t[0] == pytest.approx(0.27e-3, rel=1e-4)
    d = np.array([0.2, 0.5, 0.9])
    h = 1e-6
    fd = (np.log(np.prod(garment_material(d + h, PAPER), 0)) - np.log(np.prod(garment_material(d - h, PAPER), 0))) / (2 * h)
    assert np.allclose(log_stiffness_derivative(d, PAPER), fd, rtol=1e-6)
