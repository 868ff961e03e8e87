"""The compiled CPU kernels (kgarment.sim.kernels) agree with the torch reference code.

The finite-difference tests in test_sim_membrane / test_sim_contact check the derivatives
themselves (they run through the kernels on the CPU); here the two implementations are
compared on many random triangles covering every branch of the wrinkling rule, and on
IMLS points inside, outside and beyond the reach of the body's support.
"""

import numpy as np
import pytest
import torch

from kgarment.sim import ImplicitBody, kernels, lame_plane_stress, update_neighbors
from kgarment.sim.contact import gather, imls, imls_fast, imls_value
from kgarment.sim.membrane import TriangleElements, branches, membrane
from kgarment.sim.synthetic import sphere_body

pytestmark = pytest.mark.skipif(not kernels.AVAILABLE, reason="numba (the solver extra) not installed")


@pytest.fixture
def torch_only():
    kernels.ENABLED = False
    yield
    kernels.ENABLED = True


def _triangles(m=600, seed=0):
    """m independent triangles with random rest shapes and random deformations spanning
    slack (shrunk), uniaxial (stretched one way, squeezed the other) and normal states."""
    rng = np.random.default_rng(seed)
    rest = rng.normal(size=(m, 3, 3)) * 0.01
    scale = rng.uniform(0.7, 1.4, size=(m, 1, 3))
    rot = np.linalg.qr(rng.normal(size=(m, 3, 3)))[0]
    x = np.einsum("mij,maj->mai", rot, rest * scale) + rng.normal(size=(m, 1, 3))
    faces = np.arange(3 * m).reshape(m, 3)
    el = TriangleElements.from_mesh(rest.reshape(-1, 3), faces)
    mu, lam = lame_plane_stress(rng.uniform(0.5e6, 0.5e9, m), 0.33)
    T = torch.as_tensor
    args = (T(el.tri), T(el.shape_grad), T(el.area * 3e-4), T(mu), T(lam), T(rng.random(m) < 0.8))
    return T(x.reshape(-1, 3)), args


@pytest.mark.parametrize("projection", ["analytic", "none"])
def test_membrane_kernel_matches_torch(projection):
    x, args = _triangles()
    kinds = np.bincount(branches(x, args[0], args[1], args[5]).numpy(), minlength=3)
    assert np.all(kinds > 30), kinds  # normal, slack and uniaxial triangles all present
    e, g, H = membrane(x, *args, order=2, projection=projection)
    kernels.ENABLED = False
    try:
        e0, g0, H0 = membrane(x, *args, order=2, projection=projection)
    finally:
        kernels.ENABLED = True
    assert torch.allclose(e, e0, rtol=1e-12, atol=0)
    assert torch.allclose(g, g0, rtol=1e-10, atol=1e-12 * float(g0.abs().max()))
    assert torch.allclose(H, H0, rtol=1e-10, atol=1e-12 * float(H0.abs().max()))


def test_imls_kernel_matches_torch():
    R = 0.1
    v, n, f = sphere_body(R, 3)
    body = ImplicitBody.from_mesh(v, n, f)
    rng = np.random.default_rng(1)
    d = rng.normal(size=(300, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    p = d * rng.uniform(R - 0.004, R + 0.03, size=(300, 1))  # some points beyond every support
    c = update_neighbors(body, p)
    T = torch.tensor
    a = (T(body.vertices), T(body.normals), T(body.support), T(c.index), T(c.valid, dtype=torch.float64),
         T(c.nearest))
    pt = T(p)
    for order in (1, 2):
        f1, g1, h1 = imls_fast(pt, *a, order=order)
        f0, g0, h0 = imls(pt, *a, order=order)
        assert torch.allclose(f1, f0, rtol=1e-12, atol=1e-15)
        assert torch.allclose(g1, g0, rtol=1e-10, atol=1e-12)
        if order == 2:
            assert torch.allclose(h1, h0, rtol=1e-9, atol=1e-9 * float(h0.abs().max()))
    pre = gather(*a)
    f1, cov1 = imls_value(pt, pre, with_covered=True)
    kernels.ENABLED = False
    try:
        f0, cov0 = imls_value(pt, pre, with_covered=True)
    finally:
        kernels.ENABLED = True
    assert torch.allclose(f1, f0, rtol=1e-9, atol=1e-12)
    assert torch.equal(cov1, cov0) and 0 < int(cov1.sum()) < len(p)  # points beyond every support too
    assert torch.allclose(f1, imls(pt, *a)[0], rtol=1e-9, atol=1e-12)


def test_torch_path_is_used_when_disabled(torch_only):
    x, args = _triangles(50)
    e, _, H = membrane(x, *args, order=2, projection="none")
    assert torch.isfinite(H).all() and e.shape == (50,)


def test_degenerate_triangle_gives_non_finite_values_not_an_exception():
    """A triangle collapsed onto a line: inf / nan like the torch code (the solver then
    names the state and term), not a ZeroDivisionError from the compiled loop."""
    el = TriangleElements.from_mesh(np.array([[0, 0, 0], [0.1, 0, 0], [0, 0.1, 0.0]]), np.array([[0, 1, 2]]))
    T = torch.as_tensor
    args = (T(el.tri), T(el.shape_grad), T(np.ones(1)), T(np.full(1, 1e5)), T(np.full(1, 1e5)), T(np.array([False])))
    x = T(np.array([[0, 0, 0], [0.1, 0, 0], [0.05, 0, 0.0]]))
    e, _, H = membrane(x, *args, order=2, projection="none")
    kernels.ENABLED = False
    try:
        e0, _, _ = membrane(x, *args, order=2, projection="none")
    finally:
        kernels.ENABLED = True
    assert not torch.isfinite(e).all() and not torch.isfinite(e0).all() and not torch.isfinite(H).all()
