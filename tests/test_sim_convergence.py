"""Mesh-refinement (convergence) tests of the simulator's membrane discretisation.

In the style of scikit-fem's ``tests/test_convergence.py``: solve the same boundary-value
problem on a sequence of meshes, each with half the element size of the previous one, and
pin the observed rate at which the elastic energy converges.  Every reference number below
comes from mathematics -- a closed-form solution or Richardson extrapolation with the
theoretical rate -- never from a previous run of the code.

The model (``src/kgarment/sim/membrane.py``, ``materials.py``) is a constant-strain
triangle (CST, linear shape functions) with the compressible 2D neo-Hookean energy and
*plane-stress* Lame parameters ``mu = Y / (2 (1 + nu))``, ``lambda = Y nu / (1 - nu^2)``.
Its small-strain limit is plane-stress linear elasticity, ``W = mu eps:eps + lambda/2
(tr eps)^2``.  For linear triangles the energy-norm error is O(h), and at the discrete
minimiser the energy error is the squared energy-norm error: O(h^2).  Halving h must
therefore divide the energy error by 4.

Tests
-----
1. ``test_affine_patch_test`` (cheap): an affine deformation is represented exactly by
   CSTs, so on a distorted mesh the energy equals ``W(F) * area * t`` to round-off, the
   interior nodal forces vanish and the Dirichlet minimiser is the affine map itself.
   A uniform field says nothing about rates (it is exact at every h), hence
2. ``test_lame_annulus_energy_converges_at_second_order``: Lame's thick ring, a NON-uniform
   strain field with a closed-form energy, solved on polar meshes; the error against the
   analytic energy must fall by ~4 per refinement, and the Richardson extrapolation
   ``(4 E_h/2 - E_h) / 3`` must agree with the analytic energy to a small fraction of the
   finest mesh's error (which fails if the continuum limit is wrong, e.g. with the 3D
   lambda, even when the rate is right);
3. ``test_finite_strain_energy_converges_at_second_order``: the nonlinear regime (4-26%
   strain) on the project's own square grid (``synthetic.square_sheet``) with a
   non-affine boundary displacement; no closed form exists, so the rate is measured from
   successive differences ``(E_h - E_h/2) / (E_h/2 - E_h/4) -> 2^2`` (the Richardson
   argument: ``E_h = E + C h^2 + o(h^2)``).

How the problems are solved
---------------------------
Through the simulator's own energy object, :class:`kgarment.sim.StateProblem` (the model
of :func:`kgarment.sim.build_model`, the compiled membrane kernels, the CSC Hessian
assembly, and the contact term with a body far away), minimised by a small Newton loop
in this file over the in-plane coordinates of the interior vertices only.  Boundary
vertices are held exactly at the prescribed positions (a Dirichlet condition; the
simulator's attachment penalty would add an O(h) drift, see ``sim/model.py``) and every
vertex stays in the plane z = 0 (by symmetry the in-plane solution is an equilibrium; a
membrane without bending has no out-of-plane stiffness at zero stress).

Wrinkling relaxation: garment triangles are ``relaxed`` (``SimModel.relaxed``).  The
relaxed energy differs from the neo-Hookean one only outside the normal branch
(``l_min sqrt(l_max) < 1``), i.e. where a principal stretch is compressive enough.  All
problems here are pre-stretched so that every triangle is in biaxial tension, and each
test asserts that every element is in the normal branch at the solution; the relaxation
(which is only C0 across its branch boundary) is deliberately not part of the rate test.

Small-strain limit and the amplitude extrapolation (test 2)
-----------------------------------------------------------
The discrete energy at displacement amplitude ``delta`` is ``E_h(delta) = E2_h delta^2
+ E3_h delta^3 + O(delta^4)`` (neo-Hookean, not linear); ``E2_h`` is exactly the energy
of the linear-elastic CST solution.  ``q(delta) = E_h(delta) / delta^2`` has a linear
error term, removed by Richardson extrapolation in the amplitude:
``2 q(delta/2) - q(delta) = E2_h + O(delta^2)``.  With strains of ~1e-4 the remainder is
~1e-8 relative (the O(delta) term alone is ~8e-5, ten times the finest discretisation
error of ~6e-6: without the extrapolation the rate would be lost), and the energy
(W ~ 1e-2 Pa out of terms of ~1e2 Pa) is still computed to ~1e-10 relative.

Units: SI throughout (m, Pa, N, J).
"""

from __future__ import annotations

import math

import numpy as np
import pytest
import scipy.sparse as sp
import scipy.sparse.linalg as spla
import torch

from kgarment.sim import REFERENCE, Motion, SimState, StateProblem, build_model, prepare_state
from kgarment.sim.synthetic import sphere_body, square_sheet

# The ``reference`` preset's reinforced cloth at design d = 1: d^p = 1 exactly, so every
# element has exactly these values (garment_material).  Poisson's ratio 0.33.
Y = REFERENCE.young_reinforced  # Pa (5.7 MPa)
T = REFERENCE.thick_reinforced  # m (0.35 mm)
NU = REFERENCE.poisson
# Plane-stress Lame parameters, written out here (not taken from kgarment): Pa.
MU = Y / (2.0 * (1.0 + NU))
LAM = Y * NU / (1.0 - NU**2)


# --------------------------------------------------------------------------- helpers


def annulus_mesh(r_in: float, r_out: float, n_r: int, n_theta: int):
    """Polar grid of the annulus r_in <= r <= r_out (m) in the plane z = 0.

    ``n_r`` radial intervals, ``n_theta`` angular ones (periodic), each quad split into two
    triangles (counter-clockwise).  Boundary vertices lie exactly on the two circles.
    Returns vertices (n, 3) m, faces (m, 3) int64 and boundary (n,) bool.
    """
    r = np.linspace(r_in, r_out, n_r + 1)
    th = np.linspace(0.0, 2.0 * np.pi, n_theta, endpoint=False)
    R, TH = np.meshgrid(r, th, indexing="ij")
    v = np.stack([R * np.cos(TH), R * np.sin(TH), np.zeros_like(R)], -1).reshape(-1, 3)
    i, j = np.meshgrid(np.arange(n_r), np.arange(n_theta), indexing="ij")
    i, j = i.ravel(), j.ravel()
    jp = (j + 1) % n_theta
    p00, p10 = i * n_theta + j, (i + 1) * n_theta + j
    p11, p01 = (i + 1) * n_theta + jp, i * n_theta + jp
    f = np.concatenate([np.stack([p00, p10, p11], 1), np.stack([p00, p11, p01], 1)])
    ring = np.zeros(R.shape, bool)
    ring[[0, -1]] = True
    return v, f.astype(np.int64), ring.ravel()


def membrane_problem(vertices: np.ndarray, faces: np.ndarray) -> StateProblem:
    """The simulator's energy of a flat sheet: vertices (n, 3) m, faces (m, 3).

    ``reference`` preset, design d = 1 everywhere (Y, T above), no clutches, no attached
    faces.  The body (an icosphere of radius 5 cm) sits 1 m below the sheet: every sheet
    vertex is far outside it, so the contact term is identically zero (asserted by the
    tests).
    """
    model = build_model(vertices, faces, [], preset="reference")
    bv, bn, bf = sphere_body(0.05, 2)
    motion = Motion.create("far", vertices, bv + np.array([0.0, 0.0, -1.0]), bn,
                           np.zeros(0, np.int64), np.zeros((0, 3)), bf)
    return prepare_state(model, np.ones(len(faces)), SimState.create(motion, []))


def solve_dirichlet(prob: StateProblem, x0: np.ndarray, free: np.ndarray, force_scale: float,
                    max_iter: int = 30) -> np.ndarray:
    """Minimise the state's energy over the x and y coordinates of the ``free`` vertices.

    prob : StateProblem of n vertices;  x0 : (n, 3) m, the initial guess, which also holds
    the prescribed positions of all other vertices (and z = 0 of every vertex);
    free : (q,) int vertex ids;  force_scale : N, a typical nodal force of the problem.
    Newton with the exact (unprojected) assembled Hessian and Armijo backtracking; stops
    when every free force component is below ``1e-8 * force_scale``: the energy is then
    exact to ~(1e-8)^2 relative, and the round-off floor of the forces (measured ~1e-10
    force_scale at strains of 1e-4, where the stress is a difference of O(mu) terms) is
    still well below.  Returns x (n, 3) m; raises if not converged.
    """
    x = torch.tensor(np.asarray(x0, dtype=np.float64))
    dofs = torch.from_numpy((3 * np.asarray(free)[:, None] + np.arange(2)).ravel())
    d_np = dofs.numpy()
    pattern = prob.model.pattern
    E, g, H = prob.evaluate(x, order=2, exact=True)
    for _ in range(max_iter):
        r = g.reshape(-1)[dofs].numpy()
        if np.abs(r).max() <= 1e-8 * force_scale:
            return x.numpy()
        low = pattern.matrix(H)  # lower triangle (CSC) of the full 3N x 3N Hessian
        K = (low + low.T - sp.diags(low.diagonal())).tocsr()[d_np][:, d_np].tocsc()
        step = torch.from_numpy(spla.spsolve(K, -r))
        slope = float(r @ step.numpy())
        assert slope < 0.0, "Newton direction is not a descent direction"
        alpha = 1.0
        for _ in range(30):
            xt = x.clone()
            xt.view(-1)[dofs] += alpha * step
            Et, _, _ = prob.evaluate(xt, order=0, check=False)
            if Et <= E + 1e-4 * alpha * slope + 1e-14 * abs(E):
                break
            alpha *= 0.5
        x = xt
        E, g, H = prob.evaluate(x, order=2, exact=True)
    r_max = float(g.reshape(-1)[dofs].abs().max())
    raise AssertionError(f"Newton did not converge: max free force {r_max:.3e} N "
                         f"(tolerance {1e-8 * force_scale:.3e} N)")


def membrane_energy(prob: StateProblem, x: np.ndarray) -> float:
    """Garment membrane energy (J) at x (n, 3) m; asserts that no other term is active and
    that every element is in the normal (unrelaxed) branch of the wrinkling rule."""
    xt = torch.tensor(x)
    terms, _ = prob.terms(xt)
    assert all(v == 0.0 for k, v in terms.items() if k != "membrane_garment"), terms
    assert np.all(prob.branches(xt) == 0), "an element left the normal (biaxial tension) branch"
    return terms["membrane_garment"]


def neo_hookean_density(F: np.ndarray) -> float:
    """W (Pa) of the 2D compressible neo-Hookean law for an in-plane F (2, 2) (membrane.py
    docstring): ``mu/2 (tr C - 2) - mu ln J + lambda/2 (ln J)^2`` with plane-stress Lame."""
    C = F.T @ F
    J = math.sqrt(np.linalg.det(C))
    return MU / 2.0 * (np.trace(C) - 2.0) - MU * math.log(J) + LAM / 2.0 * math.log(J) ** 2


# --------------------------------------------------------------------------- 1. patch test


def test_affine_patch_test():
    """Affine F on a distorted mesh: energy W(F) A t exactly, zero interior forces, and the
    Dirichlet minimiser from a perturbed start is the affine map again."""
    L, n = 0.1, 9
    v, f = square_sheet(L, n)
    rng = np.random.default_rng(7)
    interior = np.nonzero((np.abs(v[:, 0]) < L / 2 - 1e-12) & (np.abs(v[:, 1]) < L / 2 - 1e-12))[0]
    h = L / (n - 1)
    v = v.copy()
    # distort the interior (the boundary is untouched, so the total area stays L^2)
    v[interior, :2] += rng.uniform(-0.25 * h, 0.25 * h, size=(len(interior), 2))
    prob = membrane_problem(v, f)
    F = np.array([[1.20, 0.10], [0.05, 1.10]])  # in-plane deformation gradient, biaxial tension
    x = v.copy()
    x[:, :2] = v[:, :2] @ F.T
    W = neo_hookean_density(F)
    e_exact = W * L * L * T  # J
    assert membrane_energy(prob, x) == pytest.approx(e_exact, rel=1e-12)
    # a rigid rotation out of the plane changes nothing
    rot = np.linalg.qr(rng.normal(size=(3, 3)))[0]
    e_rot, _, _ = prob.evaluate(torch.tensor(x @ rot.T + np.array([0.3, -0.1, 2.0])), order=0)
    assert e_rot == pytest.approx(e_exact, rel=1e-12)
    # interior nodal forces vanish (constant stress)
    _, g, _ = prob.evaluate(torch.tensor(x), order=1)
    force_scale = Y * T * 0.1 * h  # N: stress resultant of 10% strain over one edge
    assert float(g[torch.from_numpy(interior)].abs().max()) < 1e-12 * force_scale
    # the Dirichlet minimiser is the affine map (to the solver tolerance: forces below
    # 1e-8 force_scale leave displacements of ~1e-9 h times the stiffness's conditioning)
    x0 = x.copy()
    x0[interior, :2] += rng.uniform(-0.1 * h, 0.1 * h, size=(len(interior), 2))
    xs = solve_dirichlet(prob, x0, interior, force_scale)
    assert np.abs(xs - x).max() < 1e-8 * h


# --------------------------------------------------------------------------- 2. Lame's ring

R_IN, R_OUT = 0.05, 0.10  # m


def lame_displacement(r: np.ndarray, delta: float) -> np.ndarray:
    """Radial displacement u_r (m) at radii r (n,) m: Lame's ``u_r = A r + B / r``.

    Any such field solves the Navier equations (div sigma = 0) for every Lame pair.  A is
    a uniform biaxial pre-strain, B / r^2 the non-uniform part; ``A = delta``,
    ``B = 0.8 delta R_IN^2`` gives eps_rr = A - B/r^2 >= 0.2 delta and
    eps_tt = A + B/r^2 <= 1.8 delta: biaxial tension everywhere (no wrinkling).
    """
    A, B = delta, 0.8 * delta * R_IN**2
    return A * r + B / r


def lame_energy(delta: float) -> float:
    """Plane-stress linear-elastic energy (J) of ``lame_displacement(., delta)`` on the
    annulus: with eps_rr = A - B/r^2, eps_tt = A + B/r^2,
    W = mu (eps_rr^2 + eps_tt^2) + lambda/2 (eps_rr + eps_tt)^2 = 2 (mu + lambda) A^2
    + 2 mu B^2 / r^4, and E = t int W 2 pi r dr =
    2 pi t [(mu + lambda) A^2 (R_OUT^2 - R_IN^2) + mu B^2 (1/R_IN^2 - 1/R_OUT^2)]."""
    A, B = delta, 0.8 * delta * R_IN**2
    return 2.0 * np.pi * T * ((MU + LAM) * A**2 * (R_OUT**2 - R_IN**2)
                              + MU * B**2 * (1.0 / R_IN**2 - 1.0 / R_OUT**2))


def annulus_quadratic_energy(n_r: int, delta: float) -> float:
    """E2_h (J per unit delta^2): the small-strain energy coefficient on the polar mesh with
    ``n_r`` radial and ``12 n_r`` angular intervals (the angular spacing is 0.5-1 times
    the radial one), from the
    amplitude extrapolation ``2 q(delta / 2) - q(delta)``, q = E_h / amplitude^2."""
    v, f, ring = annulus_mesh(R_IN, R_OUT, n_r, 12 * n_r)
    prob = membrane_problem(v, f)
    free = np.nonzero(~ring)[0]
    r = np.hypot(v[:, 0], v[:, 1])
    h = (R_OUT - R_IN) / n_r
    q = []
    for amp in (delta, delta / 2.0):
        x0 = v.copy()
        # initial guess: the continuum field (boundary vertices: the prescribed values)
        x0[:, :2] *= (1.0 + lame_displacement(r, amp) / r)[:, None]
        x = solve_dirichlet(prob, x0, free, force_scale=Y * T * amp * h)
        q.append(membrane_energy(prob, x) / amp**2)
    return 2.0 * q[1] - q[0]


def test_lame_annulus_energy_converges_at_second_order():
    delta = 1e-4  # strain amplitude (dimensionless)
    e_exact = lame_energy(1.0)  # J per unit delta^2
    levels = (4, 8, 16, 32)  # radial intervals: h = 12.5, 6.25, 3.1, 1.6 mm
    energies = np.array([annulus_quadratic_energy(n, delta) for n in levels])
    err = np.abs(energies - e_exact) / e_exact
    ratios = err[:-1] / err[1:]
    # the error falls like h^2: ratio 4 per halving (pre-asymptotic at the coarse end)
    assert np.all((ratios > 3.6) & (ratios < 4.8)), (err, ratios)
    assert ratios[-1] == pytest.approx(4.0, abs=0.1), (err, ratios)
    assert np.all(np.diff(np.abs(ratios - 4.0)) < 0), ratios  # approaching 4
    # Richardson: E_h = E + C h^2 + o(h^2), so (4 E_h/2 - E_h) / 3 = E + o(h^2).  It must hit
    # the closed form far better than the finest mesh does (checks the continuum limit).
    extrapolated = (4.0 * energies[-1] - energies[-2]) / 3.0
    assert abs(extrapolated - e_exact) / e_exact < 0.1 * err[-1], (extrapolated, e_exact, err)


# --------------------------------------------------------------------------- 3. finite strain


def finite_map(X: np.ndarray, L: float) -> np.ndarray:
    """Deformed positions (n, 3) m of rest points X (n, 3) m of the square [-L/2, L/2]^2:
    a smooth non-affine in-plane map (biaxial pre-stretch 1.15 / 1.12 plus quadratic and
    trigonometric terms; principal stretches 1.04-1.26, biaxial tension everywhere)."""
    xi, eta = X[:, 0] / L, X[:, 1] / L  # in [-1/2, 1/2]
    x = X.copy()
    x[:, 0] = X[:, 0] + L * (0.15 * xi + 0.10 * xi * xi + 0.04 * np.sin(np.pi * eta))
    x[:, 1] = X[:, 1] + L * (0.12 * eta + 0.08 * xi * eta + 0.03 * xi * xi)
    return x


def test_finite_strain_energy_converges_at_second_order():
    L = 0.1  # m
    levels = (9, 17, 33, 65, 129)  # vertices per side: h = L/8 ... L/128
    energies = []
    for n in levels:
        v, f = square_sheet(L, n)
        prob = membrane_problem(v, f)
        free = np.nonzero((np.abs(v[:, 0]) < L / 2 - 1e-12) & (np.abs(v[:, 1]) < L / 2 - 1e-12))[0]
        x0 = finite_map(v, L)  # boundary: prescribed; interior: initial guess
        x = solve_dirichlet(prob, x0, free, force_scale=Y * T * 0.1 * L / (n - 1))
        assert np.abs(x - x0).max() > 1e-3 * L / (n - 1)  # the interior did move (non-trivial)
        energies.append(membrane_energy(prob, x))
    diff = -np.diff(np.array(energies))  # E_h - E_h/2
    ratios = diff[:-1] / diff[1:]
    # 4 per halving: with E_h = E + C2 h^2 + C3 h^3 + ..., the ratio is 4 (1 + O(h)), so its
    # distance to 4 must shrink with every refinement.  (Here it roughly halves per level,
    # a visible h^3 term, slower than on the annulus; alternating the grid's diagonals
    # does not change that.)
    assert np.all((ratios > 3.5) & (ratios < 4.4)), (energies, ratios)
    assert np.all(np.diff(np.abs(ratios - 4.0)) < 0), ratios
    assert ratios[-1] == pytest.approx(4.0, abs=0.1), (energies, ratios)
