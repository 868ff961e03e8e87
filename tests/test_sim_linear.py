"""The sparse factorisations behind Newton: MKL PARDISO, CHOLMOD (simplicial and
supernodal) and SciPy's splu, each checked against an independent dense or sparse solve."""

import numpy as np
import pytest
import scipy.sparse as sp
from scipy.sparse.linalg import spsolve

from kgarment.sim import SimState, SolverOptions, build_model, solve_states
from kgarment.sim import pardiso as pardiso_mod
from kgarment.sim.assembly import NotPositiveDefinite, SparseCholesky, build_pattern
from kgarment.sim.synthetic import Tube

needs_mkl = pytest.mark.skipif(not pardiso_mod.available(), reason="Intel MKL (pip install mkl) not installed")
TRI = np.array([[0, 1, 2], [1, 3, 2], [2, 3, 4], [3, 5, 4]])


def small_pattern(seed: int, shift: float = 0.0):
    """The Hessian pattern of a 6-vertex strip with random values (numpy's eigvalsh gives
    the smallest eigenvalue of the full symmetric matrix); ``shift`` is added to the diagonal."""
    pat = build_pattern(6, TRI, np.zeros((0, 4), np.int64))
    low = sp.tril(sp.random(pat.n_dof, pat.n_dof, density=1.0, random_state=seed)).tocsc()
    data = np.asarray(low[pat.indices, np.repeat(np.arange(pat.n_dof), np.diff(pat.indptr))]).ravel()
    data[pat.diag_pos] += shift
    H = pat.matrix(data)
    full = (H + H.T - sp.diags(H.diagonal())).toarray()
    return pat, data, full


def full_matrix(pat, data) -> sp.csc_matrix:
    H = pat.matrix(data)
    return (H + H.T - sp.diags(H.diagonal())).tocsc()


MODES = ["simplicial", "supernodal", "splu", pytest.param("pardiso", marks=needs_mkl)]


@pytest.mark.parametrize("mode,woodbury_max", [("simplicial", 0), ("supernodal", 48), ("supernodal", 1),
                                               ("supernodal", 2), ("splu", 0),
                                               pytest.param("pardiso", 12, marks=needs_mkl),
                                               pytest.param("pardiso", 1, marks=needs_mkl),
                                               pytest.param("pardiso", 2, marks=needs_mkl)])
def test_rank_updates_accumulate(mode, woodbury_max):
    """Two add_outer calls solve (H + C1 C1^T + C2 C2^T) x = b, in every factorisation mode
    (checked against scipy's sparse LU on the assembled matrix): by the Woodbury identity
    (48, 12), by refactorising (1), and the first by Woodbury, the second by refactorising
    (2).  The supernodal path used to drop the first update when a second came (measured:
    4x the Newton iterations)."""
    rng = np.random.default_rng(3)
    pat, data, _ = small_pattern(4, shift=20.0)  # diagonally dominant: positive definite
    chol = SparseCholesky(pat, mode=mode)
    assert chol.mode == mode
    chol.WOODBURY_MAX = {mode: woodbury_max}
    chol.factorize(data)

    def vertex_columns(verts):  # one column per vertex, on its 3 unknowns (as contact anticipation adds)
        rows = (3 * np.asarray(verts)[:, None] + np.arange(3)).ravel()
        cols = np.repeat(np.arange(len(verts)), 3)
        return sp.csc_matrix((rng.normal(size=len(rows)), (rows, cols)), shape=(pat.n_dof, len(verts)))

    cs = [vertex_columns([0, 4]), vertex_columns([2, 4, 5])]
    for c in cs:
        chol.add_outer(c)
    full = full_matrix(pat, data) + sum(c @ c.T for c in cs)
    b = rng.normal(size=pat.n_dof)
    assert np.allclose(chol.solve(b), spsolve(full.tocsc(), b), rtol=1e-9, atol=1e-12)


@pytest.mark.parametrize("mode", MODES)
def test_indefinite_matrices_are_rejected(mode):
    """Every Cholesky mode raises NotPositiveDefinite on an indefinite matrix (the shift
    strategy of ``newton`` relies on it: supernodal LL' and PARDISO stop at the first bad
    pivot, simplicial LDL' and splu (symmetric mode, no pivoting) are judged by their pivots) and factorises it once shifted past its
    smallest eigenvalue (from numpy's eigvalsh), solving like a dense solve."""
    pat, data, full = small_pattern(5)
    lam = np.linalg.eigvalsh(full)[0]
    chol = SparseCholesky(pat, mode=mode)
    with pytest.raises(NotPositiveDefinite):
        chol.factorize(data, beta=-lam - 0.05)  # smallest eigenvalue -0.05
    chol.factorize(data, beta=-lam + 0.05)
    b = np.random.default_rng(6).normal(size=pat.n_dof)
    assert np.allclose(chol.solve(b), np.linalg.solve(full + (-lam + 0.05) * np.eye(pat.n_dof), b), rtol=1e-8)


def test_auto_picks_pardiso_when_mkl_is_there():
    pat, _, _ = small_pattern(5)
    assert SparseCholesky(pat).mode == ("pardiso" if pardiso_mod.available() else "simplicial")
    assert SparseCholesky(pat, use_cholmod=False).mode == "splu"
    with pytest.raises(ValueError, match="factorization must be one of"):
        SolverOptions(factorization="lu")


@needs_mkl
def test_pardiso_solver_against_scipy():
    """A larger SPD matrix (a 2D Laplacian plus identity, 2,500 unknowns): one analysis,
    several numerical factorisations of new values, single and multiple right-hand sides,
    all against scipy's spsolve; a matrix with a negative pivot reports False."""
    n1 = 50
    lap1 = sp.diags([-1.0, 2.0, -1.0], [-1, 0, 1], shape=(n1, n1))
    A = (sp.kron(sp.eye(n1), lap1) + sp.kron(lap1, sp.eye(n1)) + sp.eye(n1 * n1)).tocsc()
    low = sp.tril(A).tocsc()
    low.sort_indices()
    solver = pardiso_mod.PardisoSolver(low.indptr, low.indices)
    assert solver.nnz_factor > low.nnz
    rng = np.random.default_rng(0)
    for scale in (1.0, 3.0):
        data = low.data * scale
        assert solver.factorize(data)
        full = (A * scale).tocsc()
        b = rng.normal(size=(A.shape[0], 3))
        x = solver.solve(b)
        assert x.shape == b.shape
        assert np.allclose(x, spsolve(full, b), rtol=1e-10, atol=1e-12)
        assert np.allclose(solver.solve(b[:, 1]), x[:, 1], rtol=1e-12)
    bad = low.data.copy()
    bad[low.indptr[:-1][1234]] = -5.0  # a diagonal entry: the matrix is indefinite
    assert not solver.factorize(bad)
    with pytest.raises(pardiso_mod.PardisoError):
        solver.solve(np.ones(A.shape[0]))


@pytest.mark.parametrize("mode", ["simplicial", "splu", pytest.param("pardiso", marks=needs_mkl)])
def test_newton_is_the_same_with_every_factorisation(mode):
    """The factorisations are exact, so Newton takes the same path with each: same
    iteration count and equilibrium to round-off (tube twisted under a clutch, ON)."""
    tube = Tube(0.05, 0.0, 0.3, 24, 12)
    model = build_model(tube.vertices, tube.faces, [tube.clutch("c0", 0.3, 0.08, 0.22, 0.01, 14, prestrain=0.97)],
                        preset="paper")
    state = SimState.create(tube.motion("twist", 0.1, 0.5), [1.0], name="on")
    d = np.where(np.arange(model.n_faces) % 3 == 0, 1.0, 0.001)
    ref = solve_states(model, d, [state], options=SolverOptions(factorization="supernodal"))[0]
    got = solve_states(model, d, [state], options=SolverOptions(factorization=mode))[0]
    assert ref.converged and got.converged
    assert abs(got.convergence.iterations - ref.convergence.iterations) <= 1
    assert np.allclose(got.x, ref.x, rtol=0, atol=1e-9 * np.abs(ref.x).max())


def test_contact_passes_follow_the_tolerance():
    """One anticipation pass at the design loop's tolerances, three below (measured in
    ``SolverOptions.passes``), unless set."""
    assert SolverOptions(tol=1e-2).passes == 1 and SolverOptions(tol=1e-3).passes == 1
    assert SolverOptions(tol=1e-4).passes == 3 and SolverOptions().passes == 3
    assert SolverOptions(tol=1e-2, contact_passes=2).passes == 2


def test_shared_factorisations_are_per_pattern_and_thread():
    """``SparseCholesky.shared`` hands back the same object for an equal pattern (also a
    copy, as a worker process receives), another one for another pattern, mode or
    thread, and keeps at most ``SHARED_MAX``; reuse leaves solves exact."""
    import copy
    import threading

    pat, data, full = small_pattern(7, shift=20.0)
    a = SparseCholesky.shared(pat)
    assert SparseCholesky.shared(copy.deepcopy(pat)) is a
    assert SparseCholesky.shared(pat, mode="splu") is not a
    other = build_pattern(7, np.array([[0, 1, 2], [1, 3, 2], [2, 3, 4], [3, 5, 4], [4, 5, 6]]),
                          np.zeros((0, 4), np.int64))
    assert SparseCholesky.shared(other) is not a
    assert SparseCholesky.shared(pat) is not a  # three patterns/modes used since: a was dropped
    box = []
    th = threading.Thread(target=lambda: box.append(SparseCholesky.shared(pat)))
    th.start()
    th.join()
    assert box[0] is not SparseCholesky.shared(pat)
    b = np.random.default_rng(1).normal(size=pat.n_dof)
    for scale in (1.0, 2.0):
        chol = SparseCholesky.shared(pat)
        chol.factorize(data * scale)
        assert np.allclose(chol.solve(b), np.linalg.solve(full * scale, b), rtol=1e-9)
