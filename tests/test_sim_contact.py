"""IMLS body contact and springs: values, derivatives, neighbour cache."""

import numpy as np
import pytest
import torch

from kgarment.sim import ImplicitBody, update_neighbors
from kgarment.sim.contact import NeighborStore, contact, gather, imls
from kgarment.sim.springs import attachment_springs, binding_springs, springs
from kgarment.sim.synthetic import sphere_body

R = 0.1


@pytest.fixture(scope="module")
def body():
    v, n, f = sphere_body(R, 4)
    return ImplicitBody.from_mesh(v, n, f)


def _args(body, p, cache=None):
    c = update_neighbors(body, p, cache)
    T = torch.tensor
    return c, (T(body.vertices), T(body.normals), T(body.support), T(c.index), T(c.valid, dtype=torch.float64),
               T(c.nearest))


def _points(n, radii, seed=0):
    d = np.random.default_rng(seed).normal(size=(n, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    return d * np.asarray(radii)[:, None]


def test_support_is_twice_mean_squared_neighbour_distance(body):
    d, _ = body.tree.query(body.vertices, k=7)
    assert np.allclose(body.support, 2 * np.mean(d[:, 1:] ** 2, 1))


def test_imls_approximates_signed_distance(body):
    r = np.linspace(R - 0.003, R + 0.003, 200)
    p = _points(200, r)
    _, a = _args(body, p)
    f, g, _ = imls(torch.tensor(p), *a, order=1)
    sd = np.linalg.norm(p, axis=1) - R
    spacing = np.sqrt(np.median(body.support) / 2)
    assert np.abs(f.numpy() - sd).max() < 0.1 * spacing  # ~0.1 mm here
    assert np.all(np.sign(f.numpy()[np.abs(sd) > 5e-4]) == np.sign(sd[np.abs(sd) > 5e-4]))
    radial = p / np.linalg.norm(p, axis=1, keepdims=True)
    assert np.all(np.sum(g.numpy() * radial, 1) > 0.9)


def test_contact_derivatives_finite_differences(body):
    p = _points(40, np.full(40, R - 0.001), seed=2)
    k = torch.full((40,), 1e4, dtype=torch.float64)
    _, a = _args(body, p)
    pt = torch.tensor(p)
    e, g, H = contact(pt, k, *a, order=2, exact_hessian=True)
    assert float(e.min()) > 0
    h = 1e-7
    for c in range(3):
        dp = torch.zeros_like(pt)
        dp[:, c] = h
        ep, gp, _ = contact(pt + dp, k, *a, order=1)
        em, gm, _ = contact(pt - dp, k, *a, order=1)
        assert torch.allclose((ep - em) / (2 * h), g[:, c], rtol=1e-6, atol=1e-9)
        assert torch.allclose((gp - gm) / (2 * h), H[:, :, c], rtol=1e-5, atol=1e-6)
    # Gauss-Newton Hessian: PSD and close to the exact one at small penetration
    _, _, Hgn = contact(pt, k, *a, order=2)
    assert float(torch.linalg.eigvalsh(Hgn).min()) >= -1e-9
    assert float((Hgn - H).abs().max()) < 0.05 * float(H.abs().max())
    # outside: no energy, no force
    q = _points(10, np.full(10, R + 0.002), seed=3)
    _, aq = _args(body, q)
    eq, gq, _ = contact(torch.tensor(q), k[:10], *aq, order=1)
    assert float(eq.abs().max()) == 0.0 and float(gq.abs().max()) == 0.0


def test_neighbor_cache_is_exact_and_lazy(body):
    p = _points(300, np.full(300, R + 0.001), seed=4)
    c0, _a0 = _args(body, p)
    assert c0.index.shape[1] < 60  # pruned to the candidates that can matter
    rng = np.random.default_rng(5)
    for step in (0.2, 0.9, 3.0):
        q = p + step * c0.threshold.min() * rng.normal(size=p.shape) / np.sqrt(3)
        _c1, a1 = _args(body, q, c0)
        _, af = _args(body, q)  # fresh query
        f1 = imls(torch.tensor(q), *a1)[0]
        ff = imls(torch.tensor(q), *af)[0]
        assert torch.allclose(f1, ff, rtol=0, atol=1e-15)
    same = update_neighbors(body, p + 1e-9, c0)
    assert same is c0


def test_energy_does_not_depend_on_where_the_lists_were_queried(body):
    """Lists kept from earlier positions (a design run's last solve) give the same bits as
    a fresh query: each row is in canonical order, so the kernels sum the same terms in
    the same order; a partial gather equals the full one."""
    p = _points(300, np.full(300, R - 0.0005), seed=6)
    c0 = update_neighbors(body, p + 0.4 * np.sqrt(body.support.min()) * np.random.default_rng(7).normal(size=p.shape))
    stale = update_neighbors(body, p, c0)
    assert stale.changed is not None and 0 < len(stale.changed) < len(p)
    fresh = update_neighbors(body, p)
    T = torch.tensor
    k = torch.full((300,), 1e4, dtype=torch.float64)
    bodyt = (T(body.vertices), T(body.normals), T(body.support))
    out = []
    for c in (fresh, stale):
        lists = (T(c.index), T(c.valid, dtype=torch.float64), T(c.nearest))
        out.append(contact(T(p), k, *bodyt, *lists, order=2, pre=gather(*bodyt, *lists)))
        if c is stale:  # only the re-queried rows of c0's gathered quantities recomputed
            l0 = (T(c0.index), T(c0.valid, dtype=torch.float64), T(c0.nearest))
            part = gather(*bodyt, *lists, rows=T(c.changed), into=gather(*bodyt, *l0))
            assert all(torch.equal(a, b) for a, b in zip(part, gather(*bodyt, *lists)))
    assert float(out[0][0].sum()) > 0
    for a, b in zip(*out):
        assert torch.equal(a, b)


def test_neighbor_store_keeps_the_most_recent_within_its_bounds(body):
    store = NeighborStore(max_entries=2)
    caches = [update_neighbors(body, _points(50, np.full(50, R), seed=s)) for s in range(3)]
    for i, c in enumerate(caches):
        store.put(("state", i), c)
    assert store.get(("state", 0)) is None and store.get(("state", 2)) is caches[2]
    small = NeighborStore(max_bytes=caches[0].nbytes + 1)
    small.put("a", caches[0])
    small.put("b", caches[1])
    assert small.get("a") is None and small.get("b") is caches[1]


def test_springs_gradient():
    faces = np.array([[0, 1, 2], [1, 3, 2]])
    s1 = attachment_springs(faces, np.array([1]), np.array([[0.1, 0.2, 0.3]]))
    s2 = binding_springs(np.array([4]), faces, np.array([0]), np.array([[0.2, 0.3, 0.5]]), "anchor")
    rng = np.random.default_rng(0)
    x = torch.tensor(rng.normal(size=(5, 3)))
    for s in (s1, s2):
        args = (torch.tensor(s.index), torch.tensor(s.coef), torch.tensor(s.target),
                torch.tensor([7.0], dtype=torch.float64))
        _e, g = springs(x, *args, order=1)
        h = 1e-6
        for i in range(5):
            for c in range(3):
                dx = torch.zeros_like(x)
                dx[i, c] = h
                fd = (springs(x + dx, *args)[0] - springs(x - dx, *args)[0]) / (2 * h)
                assert float(fd) == pytest.approx(float(g[i, c]), rel=1e-7, abs=1e-9)
    # residual of an anchor: clutch vertex minus its barycentric point
    A = s2.operator(5).toarray()
    assert np.allclose(A[0], [-0.2, -0.3, -0.5, 0.0, 1.0])


def test_points_moved_onto_the_contact_surface(body):
    """``onto_surface`` puts points given 3 mm inside and outside the sphere's mesh on the
    IMLS zero set (|f| below a micrometre), moving each along the surface normal (radially
    on a sphere) by its offset from that set."""
    from kgarment.sim.contact import onto_surface

    p = _points(300, np.random.default_rng(3).uniform(R - 0.003, R + 0.003, 300), seed=4)
    q = onto_surface(body, p)
    _, a = _args(body, q)
    f, _, _ = imls(torch.tensor(q), *a, order=0)
    assert np.abs(f.numpy()).max() < 1e-6
    radial = p / np.linalg.norm(p, axis=1, keepdims=True)
    move = q - p
    tangential = move - np.sum(move * radial, 1)[:, None] * radial
    assert np.abs(tangential).max() < 0.05 * np.abs(move).max()
    _, a = _args(body, p)
    f0, _, _ = imls(torch.tensor(p), *a, order=0)
    assert np.allclose(np.linalg.norm(move, axis=1), np.abs(f0.numpy()), rtol=0.05, atol=2e-5)


def test_points_no_support_covers_get_the_same_bits_whatever_the_lists_held(body):
    """A point deeper inside than any support reaches falls back to the plane of its
    nearest body vertex: given the body's tree, the vertex nearest to it now, not at its
    list's last query (which depends on the solves before). Stale lists and fresh ones then
    give the same bits; with the stale nearest vertex they do not (checked, so the test
    can fail)."""
    from kgarment.sim.contact import imls_fast, imls_value

    rng = np.random.default_rng(3)
    T = torch.tensor
    bodyt = (T(body.vertices), T(body.normals), T(body.support))
    p0 = _points(400, np.full(400, 0.6 * R), seed=8)  # 40 mm deep: no support reaches
    c0 = update_neighbors(body, p0)
    step = rng.normal(size=p0.shape)
    p = p0 + 0.5 * c0.threshold[:, None] * step / np.linalg.norm(step, axis=1, keepdims=True)  # within the lists' thresholds
    stale = update_neighbors(body, p, c0)
    assert stale is c0  # nothing re-queried: the lists (and nearest vertices) of p0
    fresh = update_neighbors(body, p)
    assert (stale.nearest != fresh.nearest).sum() > 10  # the nearest vertex changed for these points
    k = torch.full((len(p),), 1e4, dtype=torch.float64)
    pt = T(p)
    out, raw, lin = [], [], []
    for c in (fresh, stale):
        lists = (T(c.index), T(c.valid, dtype=torch.float64), T(c.nearest))
        pre = gather(*bodyt, *lists)
        assert not bool(imls_value(pt, pre, with_covered=True)[1].any())
        raw.append(contact(pt, k, *bodyt, *lists, order=2, pre=pre))
        out.append(contact(pt, k, *bodyt, *lists, order=2, pre=pre, tree=body.tree))
        lin.append(imls_fast(pt, *bodyt, *lists, order=2, tree=body.tree))
    assert not torch.equal(raw[0][0], raw[1][0])  # the stale plane: other energies
    for a, b in zip(out[0], raw[0]):  # fresh lists are already exact
        assert torch.equal(a, b)
    for a, b in zip(*out):
        assert torch.equal(a, b)
    for a, b in zip(*lin):
        assert torch.equal(a, b)
    assert float(out[0][0].sum()) > 0
    from kgarment.sim import kernels

    kernels.ENABLED = False  # the torch path (GPU, no numba) falls back the same way
    try:
        lists = (T(stale.index), T(stale.valid, dtype=torch.float64), T(stale.nearest))
        slow = imls_fast(pt, *bodyt, *lists, order=2, tree=body.tree)
    finally:
        kernels.ENABLED = True
    for a, b in zip(slow, lin[0]):
        assert torch.allclose(a, b, rtol=1e-12, atol=1e-15)
