"""Sparse Hessian assembly into a pattern built once, and the sparse Cholesky solve.

The pattern is the lower triangle (CSC, ``row >= col``) of the 3N x 3N Hessian, DOF
``3 * vertex + coordinate``.  It holds every membrane element's 9x9 block, every vertex's
3x3 diagonal block (contact, damping) and the vertex pairs coupled by springs.  Building it
precomputes, for each source of values, where each value lands in the CSC data array, so
an iteration only recomputes values and scatters them with one ``index_add``.

Factorisations (``SolverOptions.factorization``; the lower-triangle CSC pattern is exactly
the upper-triangle CSR matrix PARDISO reads, so no copy is made):

* "pardiso" (Intel MKL PARDISO, ``kgarment.sim.pardiso``; what "auto" picks when the
  ``mkl`` wheel is installed): symbolic analysis (METIS) once per pattern, a numerical
  Cholesky per iteration that stops at the first non-positive pivot.  Rank updates (contact
  anticipation) of up to ``WOODBURY_MAX["pardiso"]`` columns in all are applied at solve
  time by the Woodbury identity (one multi-right-hand-side solve costs ~0.9 ms a column),
  more refactorise ``H + C C^T`` (~18 ms at subdivision 1);
* "simplicial" (CHOLMOD LDL', "auto" without MKL): rank updates in place, but an
  indefinite matrix is only detected from the pivots once the whole factorisation is done;
* "supernodal" (CHOLMOD LL' through BLAS; the Makefile installs Debian's serial OpenBLAS,
  with the reference BLAS it is slower): stops at the first non-positive pivot, Woodbury
  updates up to 48 columns.  CHOLMOD runs OpenMP regions here, which GNU OpenMP does not
  survive across a fork (``kgarment.sim.parallel`` then starts its workers by forkserver);
* "splu" (SciPy's SuperLU on the full matrix with a symmetric ordering and no pivoting,
  so its pivots decide definiteness; the fallback without scikit-sparse, logged once).

Measured (2026-11-23, 2 cores, idle machine; the three-motion shirt at subdivision 1,
20,679 unknowns, 1.5-1.8M nonzeros in the factor, ~300 MFlop): one numerical
factorisation takes 17-20 ms with PARDISO, 62-80 ms with CHOLMOD supernodal, 74-80 ms
with CHOLMOD simplicial (which a BLAS cannot speed up; CHOLMOD supernodal with MKL's BLAS
was no faster either).  A failed one costs 5 ms with PARDISO (it stops early).  Six warm
states after a 1.5% design change in one process, tol 1e-3: 13.5 s with PARDISO against
30.7 s simplicial and 35.2 s supernodal, with identical Newton iterations (174).
"""

from __future__ import annotations

import hashlib
import logging
import os
import threading
from dataclasses import dataclass
from functools import cached_property
from typing import ClassVar

import numpy as np
import scipy.sparse as sp

from kgarment.sim import pardiso

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
    diag_pos : (3N,) positions of the diagonal;
    dense_select, dense_pos : per dense vertex group (a cable clutch's strip,
    ``kgarment.sim.cable``), the flat indices into its (3v, 3v) block that are on or below
    the diagonal and their CSC positions.
    """

    n_dof: int
    indptr: np.ndarray
    indices: np.ndarray
    elem_select: np.ndarray
    elem_pos: np.ndarray
    vert_select: np.ndarray
    vert_pos: np.ndarray
    diag_pos: np.ndarray
    dense_select: tuple = ()
    dense_pos: tuple = ()

    @property
    def nnz(self) -> int:
        return len(self.indices)

    @cached_property
    def fingerprint(self) -> tuple[int, int, bytes]:
        """(n_dof, nnz, digest of the structure): equal for equal patterns, also across
        copies (a worker process gets its own copy of the model with every task)."""
        digest = hashlib.blake2b(self.indptr.tobytes(), digest_size=16)
        digest.update(self.indices.tobytes())
        return self.n_dof, self.nnz, digest.digest()

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


def build_pattern(n_vertices: int, tri: np.ndarray, spring_index: np.ndarray, dense=()) -> HessianPattern:
    """tri : (m, 3) global vertex ids of all membrane elements;
    spring_index : (S, 4) vertex ids of the motion-independent springs;  dense : vertex id
    arrays (v,) whose vertices are all coupled with one another (a cable clutch's strip)."""
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
    blocks = []  # (select, rows, cols) of each dense group's lower entries
    for verts in dense:
        d = (3 * np.asarray(verts, dtype=np.int64)[:, None] + np.arange(3)).ravel()  # (3v,)
        br, bc = np.broadcast_to(d[:, None], (len(d),) * 2).ravel(), np.broadcast_to(d[None, :], (len(d),) * 2).ravel()
        sel = np.nonzero(br >= bc)[0]
        blocks.append((sel, br[sel], bc[sel]))
    all_r = np.concatenate([rows[esel], vr[:, vsel].ravel(), *srows, *(b[1] for b in blocks)])
    all_c = np.concatenate([cols[esel], vc[:, vsel].ravel(), *scols, *(b[2] for b in blocks)])
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
                          elem_pos=epos, vert_select=vsel, vert_pos=vpos, diag_pos=dpos,
                          dense_select=tuple(b[0] for b in blocks),
                          dense_pos=tuple(lookup(b[1], b[2]) for b in blocks))


class SparseCholesky:
    """Factorise ``H + beta I`` for a fixed pattern (module doc).

    mode : "auto" (PARDISO if MKL is installed, else CHOLMOD simplicial), "pardiso",
    "simplicial" (CHOLMOD LDL', rank updates in place), "supernodal" (CHOLMOD LL' through
    BLAS) or "splu" (SciPy, no extra package; slow).  For "pardiso" and "supernodal", rank
    updates of up to ``WOODBURY_MAX[mode]`` columns in all are applied at solve time by the
    Woodbury identity; more refactorise ``H + C C^T``.  ``use_cholmod=False`` forces "splu".
    """

    _warned = False
    WOODBURY_MAX: ClassVar[dict[str, int]] = {"supernodal": 48, "pardiso": 12}
    openmp_used = False  # this process has run a CHOLMOD supernodal (OpenMP) factorisation

    _shared = threading.local()
    SHARED_MAX = 2  # factorisations kept per thread (one per model pattern in use)

    @classmethod
    def shared(cls, pattern: HessianPattern, use_cholmod: bool = True, mode: str = "auto") -> SparseCholesky:
        """A factorisation of ``pattern`` kept for later solves in this thread and process,
        so that the symbolic analysis (METIS ordering, ~50 ms at subdivision 1, as long as
        a few Newton iterations) runs once per model rather than once per state and design
        iteration.  Every ``factorize`` starts afresh, so reuse changes no result.  Per
        thread, because a factorisation holds the state of the solve using it; per process,
        because a forked worker must not share its parent's."""
        key = (os.getpid(), cls.choose_mode(mode, use_cholmod), pattern.fingerprint)
        cache = cls._shared.__dict__.setdefault("cache", {})
        chol = cache.pop(key, None)
        if chol is None:
            chol = cls(pattern, use_cholmod, mode)
        cache[key] = chol  # most recently used last
        while len(cache) > cls.SHARED_MAX:
            cache.pop(next(iter(cache)))
        return chol

    @staticmethod
    def choose_mode(mode: str, use_cholmod: bool = True) -> str:
        """The factorisation ``mode`` stands for in this environment (module doc).  Raises
        ValueError for "pardiso" without MKL."""
        if not use_cholmod or mode == "splu":
            return "splu"
        if mode == "auto":
            mode = "pardiso" if pardiso.available() else "simplicial"
        if mode == "pardiso" and not pardiso.available():
            raise ValueError("factorization 'pardiso' needs Intel MKL (pip install mkl); "
                             "or use 'auto', 'simplicial', 'supernodal' or 'splu'")
        if mode in ("simplicial", "supernodal") and _cholmod is None:
            if not SparseCholesky._warned:
                log.warning("scikit-sparse (CHOLMOD) not available: falling back to scipy splu "
                            "(install kgarment[solver] for speed)")
                SparseCholesky._warned = True
            return "splu"
        return mode

    def __init__(self, pattern: HessianPattern, use_cholmod: bool = True, mode: str = "auto",
                 ordering: str = "nesdis"):
        self.pattern = pattern
        self.mode = self.choose_mode(mode, use_cholmod)
        self.backend = {"pardiso": "pardiso", "splu": "splu"}.get(self.mode, "cholmod")
        self._factor = self._lu = self._pd = None
        self._data = self._full = None
        self._C = self._Z = self._S = None  # Woodbury: C (n, a) sparse, Z = A^-1 C, S = cho_factor(I + C^T Z)
        if self.backend == "pardiso":
            self._pd = pardiso.PardisoSolver(pattern.indptr, pattern.indices)
        elif self.backend == "cholmod":
            if self.mode == "supernodal":
                SparseCholesky.openmp_used = True
            data = np.zeros(pattern.nnz)
            data[pattern.diag_pos] = 1.0
            self._factor = _cholmod.analyze(pattern.matrix(data), mode=self.mode, ordering_method=ordering)

    def factorize(self, data: np.ndarray, beta: float = 0.0) -> None:
        """data : (nnz,) lower-triangle values.  Raises NotPositiveDefinite."""
        if beta:
            data = data.copy()
            data[self.pattern.diag_pos] += beta
        self._data = data
        self._C = self._Z = self._S = None
        self._numeric(data)

    def _numeric(self, data: np.ndarray) -> None:
        if self.backend == "pardiso":
            if not self._pd.factorize(data):
                raise NotPositiveDefinite("PARDISO: non-positive pivot")
            return
        H = self.pattern.matrix(data)
        if self.backend == "cholmod":
            try:
                self._factor.cholesky_inplace(H)
            except _cholmod.CholmodNotPositiveDefiniteError as exc:
                raise NotPositiveDefinite(str(exc)) from exc
            # the simplicial LDL' factorisation does not fail on indefinite matrices
            if self.mode == "simplicial" and not np.all(self._factor.D() > 0):
                raise NotPositiveDefinite("LDL' factor has non-positive pivots")
            return
        from scipy.sparse.linalg import splu

        self._full = (H + H.T - sp.diags(H.diagonal())).tocsc()
        try:  # symmetric ordering, no pivoting: U = D L^T, so U's diagonal holds the pivots
            self._lu = splu(self._full, permc_spec="MMD_AT_PLUS_A", diag_pivot_thresh=0.0,
                            options={"SymmetricMode": True})
        except RuntimeError as exc:
            raise NotPositiveDefinite(str(exc)) from exc
        if not (np.array_equal(self._lu.perm_r, self._lu.perm_c) and np.all(self._lu.U.diagonal() > 0)):
            raise NotPositiveDefinite("LU pivots of the symmetric matrix are not all positive")

    def add_outer(self, cols: sp.csc_matrix) -> None:
        """Turn the current factor of H into that of ``H + C C^T``; ``cols`` is the (3N, a)
        sparse C whose outer products lie in the pattern (CHOLMOD simplicial: a rank-a
        update in place; PARDISO and supernodal: Woodbury up to ``WOODBURY_MAX`` columns
        in all, else a refactorisation; splu refactorises)."""
        if self.mode == "simplicial":
            self._factor.update_inplace(cols)
            return
        C = cols if self._C is None else sp.hstack([self._C, cols]).tocsc()
        if self.mode in self.WOODBURY_MAX and C.shape[1] <= self.WOODBURY_MAX[self.mode]:
            # (A + C C^T)^-1 = A^-1 - Z (I + C^T Z)^-1 Z^T with Z = A^-1 C: a few solves
            # instead of a refactorisation; A + C C^T stays positive definite
            from scipy.linalg import cho_factor

            Znew = self._base_solve(cols.toarray())
            self._Z = Znew if self._Z is None else np.hstack([self._Z, Znew])
            self._C = C
            self._S = cho_factor(np.eye(C.shape[1]) + C.T @ self._Z, lower=True)
            return
        outer = sp.tril(C @ C.T).tocoo()  # later updates add to this one
        self._data = self._data + np.bincount(self.pattern.positions(outer.row, outer.col), weights=outer.data,
                                              minlength=self.pattern.nnz)
        self._C = self._Z = self._S = None
        self._numeric(self._data)

    def _base_solve(self, rhs: np.ndarray) -> np.ndarray:
        if self.backend == "pardiso":
            return self._pd.solve(rhs)
        if self.backend == "cholmod":
            return self._factor(rhs)
        return self._lu.solve(rhs)

    def solve(self, rhs: np.ndarray) -> np.ndarray:
        """rhs : (3N,) -> (3N,)."""
        y = self._base_solve(rhs)
        if self._C is not None:
            from scipy.linalg import cho_solve

            y = y - self._Z @ cho_solve(self._S, self._C.T @ y)
        return y
