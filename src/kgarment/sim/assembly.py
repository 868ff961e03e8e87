"""Sparse Hessian assembly into a pattern built once, and the sparse Cholesky solve.

The pattern is the lower triangle (CSC, ``row >= col``) of the 3N x 3N Hessian, DOF
``3 * vertex + coordinate``.  It holds every membrane element's 9x9 block, every vertex's
3x3 diagonal block (contact, damping) and the vertex pairs coupled by springs.  Building it
precomputes, for each source of values, where each value lands in the CSC data array, so
an iteration only recomputes values and scatters them with one ``index_add``.

CHOLMOD (scikit-sparse) reads only the lower triangle: ``analyze`` runs once on the
pattern, ``cholesky_inplace(H, beta)`` refactorises numerically each iteration (``beta``
adds the damping ``beta * I``).  The default is the simplicial LDL' factorisation with
nested dissection ordering, whose rank updates (contact anticipation) are cheap.  The
supernodal LL' (``SolverOptions.factorization``; it needs an optimised BLAS such as
Debian's OpenBLAS, with the reference BLAS it is slower) factorises faster at subdivision 1
(70 against 88 ms, 20.7k unknowns, one thread) and applies small rank updates by the
Woodbury identity; on warm solves of the shirt at subdivision 1 (two states, measured
beside a design run) it was no faster overall: 0.46 against 0.44 s per Newton iteration
at tol 1e-5, 17.4 against 16.5 s and 8.8 against 9.1 s at 1e-3, so it is not the default.  Without scikit-sparse we fall back to SciPy's ``splu``
on the full symmetric matrix (much slower; logged once as a warning).
"""

from __future__ import annotations

import logging
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

log = logging.getLogger(__name__)

try:  # pragma: no cover - depends on the environment
    from sksparse import cholmod as _cholmod
except ImportError:  # pragma: no cover
    _cholmod = None


class NotPositiveDefinite(RuntimeError):
    """The damped Hessian could not be factorised."""


@dataclass(frozen=True)
class HessianPattern:
    """Lower-triangular CSC pattern of the Hessian.

    n_dof : 3N; indptr : (3N+1,), indices : (nnz,) row ids per column;
    elem_select : (q,) flat indices into the (m, 9, 9) element Hessians that are on or
    below the diagonal; elem_pos : (q,) their CSC positions;
    vert_select : (6,) flat indices into a 3x3 block (lower part); vert_pos : (N, 6);
    diag_pos : (3N,) positions of the diagonal.
    """

    n_dof: int
    indptr: np.ndarray
    indices: np.ndarray
    elem_select: np.ndarray
    elem_pos: np.ndarray
    vert_select: np.ndarray
    vert_pos: np.ndarray
    diag_pos: np.ndarray

    @property
    def nnz(self) -> int:
        return len(self.indices)

    def positions(self, rows: np.ndarray, cols: np.ndarray) -> np.ndarray:
        """CSC positions of lower-triangle entries (rows >= cols); raises if absent."""
        key = cols.astype(np.int64) * self.n_dof + rows
        keys = self._keys()
        pos = np.searchsorted(keys, key)
        pos = np.minimum(pos, len(keys) - 1)
        if not np.array_equal(keys[pos], key):
            raise ValueError("Hessian entry outside the precomputed sparsity pattern")
        return pos

    def _keys(self) -> np.ndarray:
        cols = np.repeat(np.arange(self.n_dof, dtype=np.int64), np.diff(self.indptr))
        return cols * self.n_dof + self.indices

    def matrix(self, data: np.ndarray) -> sp.csc_matrix:
        """The lower-triangular CSC matrix with values ``data`` (nnz,)."""
        return sp.csc_matrix((data, self.indices, self.indptr), shape=(self.n_dof, self.n_dof))

    def spring_positions(self, index: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """For springs with vertex ids ``index`` (S, 4): ``(select, pos)`` mapping the flat
        (S, 4, 4, 3) array of ``c_s c_t`` per coordinate to CSC positions (lower only)."""
        s_ = np.broadcast_to(index[:, :, None, None], index.shape + (4, 3))
        t_ = np.broadcast_to(index[:, None, :, None], index.shape[:1] + (4, 4, 3))
        c_ = np.broadcast_to(np.arange(3)[None, None, None, :], s_.shape)
        rows = (3 * s_ + c_).ravel()
        cols = (3 * t_ + c_).ravel()
        sel = np.nonzero(rows >= cols)[0]
        return sel, self.positions(rows[sel], cols[sel])


def build_pattern(n_vertices: int, tri: np.ndarray, spring_index: np.ndarray) -> HessianPattern:
    """tri : (m, 3) global vertex ids of all membrane elements;
    spring_index : (S, 4) vertex ids of the motion-independent springs."""
    n_dof = 3 * n_vertices
    m = len(tri)
    dof = (3 * tri[:, :, None] + np.arange(3)).reshape(m, 9)  # (m, 9)
    rows = np.broadcast_to(dof[:, :, None], (m, 9, 9)).ravel()
    cols = np.broadcast_to(dof[:, None, :], (m, 9, 9)).ravel()
    esel = np.nonzero(rows >= cols)[0]
    v = np.arange(n_vertices)
    vdof = (3 * v[:, None] + np.arange(3))  # (N, 3)
    vr = np.broadcast_to(vdof[:, :, None], (n_vertices, 3, 3)).reshape(n_vertices, 9)
    vc = np.broadcast_to(vdof[:, None, :], (n_vertices, 3, 3)).reshape(n_vertices, 9)
    vsel = np.nonzero(vr[0] - vc[0] >= 0)[0]
    srows, scols = [], []
    if len(spring_index):
        s_ = np.broadcast_to(spring_index[:, :, None], spring_index.shape + (4,)).ravel()
        t_ = np.broadcast_to(spring_index[:, None, :], spring_index.shape[:1] + (4, 4)).ravel()
        for c in range(3):
            srows.append(3 * s_ + c)
            scols.append(3 * t_ + c)
    all_r = np.concatenate([rows[esel], vr[:, vsel].ravel(), *srows])
    all_c = np.concatenate([cols[esel], vc[:, vsel].ravel(), *scols])
    low = all_r >= all_c
    keys = np.unique(all_c[low].astype(np.int64) * n_dof + all_r[low])
    kc = keys // n_dof
    indices = (keys % n_dof).astype(np.int32)
    indptr = np.searchsorted(kc, np.arange(n_dof + 1)).astype(np.int32)

    def lookup(r, c):
        return np.searchsorted(keys, c.astype(np.int64) * n_dof + r)

    epos = lookup(rows[esel], cols[esel])
    vpos = lookup(vr[:, vsel].ravel(), vc[:, vsel].ravel()).reshape(n_vertices, len(vsel))
    dpos = lookup(np.arange(n_dof), np.arange(n_dof))
    return HessianPattern(n_dof=n_dof, indptr=indptr, indices=indices, elem_select=esel,
                          elem_pos=epos, vert_select=vsel, vert_pos=vpos, diag_pos=dpos)


class SparseCholesky:
    """Factorise ``H + beta I`` for a fixed pattern: CHOLMOD if available, else ``splu``.

    mode : "simplicial" (LDL', rank updates in place) or "supernodal" (LL' through BLAS;
    rank updates of up to ``WOODBURY_MAX`` columns in all are applied at solve time by the
    Woodbury identity, more refactorise ``H + C C^T``).
    """

    _warned = False
    WOODBURY_MAX = 48

    def __init__(self, pattern: HessianPattern, use_cholmod: bool = True, mode: str = "simplicial",
                 ordering: str = "nesdis"):
        self.pattern = pattern
        self.backend = "cholmod" if (use_cholmod and _cholmod is not None) else "splu"
        self._factor = None
        self._lu = None
        self._H = self._full = None
        self._C = self._Z = self._S = None  # Woodbury: C (n, a) sparse, Z = A^-1 C, S = cho_factor(I + C^T Z)
        self.mode = mode
        if self.backend == "cholmod":
            data = np.zeros(pattern.nnz)
            data[pattern.diag_pos] = 1.0
            self._factor = _cholmod.analyze(pattern.matrix(data), mode=mode, ordering_method=ordering)
        elif not SparseCholesky._warned:
            log.warning("scikit-sparse (CHOLMOD) not available: falling back to scipy splu "
                        "(install kgarment[solver] for speed)")
            SparseCholesky._warned = True

    def factorize(self, data: np.ndarray, beta: float = 0.0) -> None:
        """data : (nnz,) lower-triangle values.  Raises NotPositiveDefinite."""
        H = self.pattern.matrix(data)
        self._H = H
        self._C = self._Z = self._S = None
        if self.backend == "cholmod":
            try:
                self._factor.cholesky_inplace(H, beta=beta)
            except _cholmod.CholmodNotPositiveDefiniteError as exc:
                raise NotPositiveDefinite(str(exc)) from exc
            # the simplicial LDL' factorisation does not fail on indefinite matrices
            if self.mode == "simplicial" and not np.all(self._factor.D() > 0):
                raise NotPositiveDefinite("LDL' factor has non-positive pivots")
            return
        from scipy.sparse.linalg import splu

        full = (H + H.T - sp.diags(H.diagonal()) + beta * sp.eye(H.shape[0])).tocsc()
        self._full = full
        try:
            self._lu = splu(full)
        except RuntimeError as exc:
            raise NotPositiveDefinite(str(exc)) from exc

    def add_outer(self, cols: sp.csc_matrix) -> None:
        """Turn the current factor of H into that of ``H + C C^T``; ``cols`` is the (3N, a)
        sparse C (simplicial: CHOLMOD rank-a update; supernodal: Woodbury, or a
        refactorisation beyond ``WOODBURY_MAX`` columns; splu refactorises)."""
        if self.backend == "cholmod" and self.mode == "simplicial":
            self._factor.update_inplace(cols)
        elif self.backend == "cholmod":
            C = cols if self._C is None else sp.hstack([self._C, cols]).tocsc()
            if C.shape[1] <= self.WOODBURY_MAX:
                # (A + C C^T)^-1 = A^-1 - Z (I + C^T Z)^-1 Z^T with Z = A^-1 C: a few solves
                # instead of a refactorisation; A + C C^T stays positive definite
                Znew = self._factor(cols.toarray())
                Z = Znew if self._Z is None else np.hstack([self._Z, Znew])
                from scipy.linalg import cho_factor

                self._C, self._Z = C, Z
                self._S = cho_factor(np.eye(C.shape[1]) + C.T @ Z, lower=True)
                return
            self._H = (self._H + sp.tril(C @ C.T)).tocsc()  # later updates add to this one
            self._C = self._Z = self._S = None
            self._factor.cholesky_inplace(self._H)
        else:
            from scipy.sparse.linalg import splu

            self._full = (self._full + cols @ cols.T).tocsc()
            self._lu = splu(self._full)

    def solve(self, rhs: np.ndarray) -> np.ndarray:
        """rhs : (3N,) -> (3N,)."""
        if self.backend == "cholmod":
            y = self._factor(rhs)
            if self._C is not None:
                from scipy.linalg import cho_solve

                y = y - self._Z @ cho_solve(self._S, self._C.T @ y)
            return y
        return self._lu.solve(rhs)
