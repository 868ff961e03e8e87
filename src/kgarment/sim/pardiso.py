"""Intel MKL PARDISO for a symmetric matrix with a fixed sparsity pattern (ctypes).

Why PARDISO: on the Hessians of the shirt at subdivision 1 (20,679 unknowns, 1.5-1.7M
nonzeros in the factor, ~300 MFlop) its numerical Cholesky takes 19-20 ms on one core
against 62-80 ms for CHOLMOD's supernodal and 75-80 ms for its simplicial factorisation
(scikit-sparse 0.4.16 on Debian 12's SuiteSparse 5.12 and OpenBLAS; the BLAS is not the
difference: CHOLMOD supernodal with MKL's BLAS is no faster).  It is a sparse direct
solver made for exactly this (symmetric FEM matrices), shipped on PyPI as the ``mkl``
wheel.  We bind the documented C entry point ``pardiso`` of ``libmkl_rt`` ourselves rather
than through ``pypardiso``, whose interface re-runs the symbolic analysis for every new
matrix and hides the "not positive definite" status that the Newton shift strategy
depends on.

The pattern is given as a lower-triangular CSC matrix, which is the upper-triangular CSR
matrix PARDISO reads for symmetric types (``indptr``, ``indices`` unchanged, zero-based).
``mtype=2`` (real symmetric positive definite, Cholesky): the numerical factorisation
fails with error -4 at a non-positive pivot, which :class:`PardisoSolver` reports as
``ok=False``; nothing else is perturbed or pivoted, so a successful factorisation is an
exact one of a positive definite matrix.

MKL runs sequentially here (``MKL_Set_Threading_Layer(SEQUENTIAL)`` before any other MKL
call): states are solved in parallel by worker processes instead (``parallel``), and an
MKL without OpenMP threads is safe to fork.
"""

from __future__ import annotations

import ctypes
import glob
import logging
import os
import sys
import weakref

import numpy as np

log = logging.getLogger(__name__)

_MKL_THREADING_SEQUENTIAL = 1
_MKL_INTERFACE_LP64 = 0
_LIB = None
_TRIED = False


def _candidates() -> list[str]:
    """Where the ``mkl`` wheel (or a system MKL) puts ``libmkl_rt``."""
    names = []
    for root in dict.fromkeys([sys.prefix, sys.base_prefix, os.environ.get("CONDA_PREFIX") or ""]):
        if root:
            names += sorted(glob.glob(os.path.join(root, "lib", "libmkl_rt.so*")), reverse=True)
    import ctypes.util

    found = ctypes.util.find_library("mkl_rt")
    if found:
        names.append(found)
    return names


def load_mkl():
    """The MKL runtime library (ctypes.CDLL) set to sequential threading, or None when MKL is
    not installed (``pip install mkl``) or cannot be loaded."""
    global _LIB, _TRIED
    if _TRIED:
        return _LIB
    _TRIED = True
    for path in _candidates():
        try:
            lib = ctypes.CDLL(path)
            lib.pardiso  # noqa: B018 - raises AttributeError if absent
        except (OSError, AttributeError):
            continue
        lib.MKL_Set_Interface_Layer.argtypes = [ctypes.c_int]
        lib.MKL_Set_Threading_Layer.argtypes = [ctypes.c_int]
        lib.MKL_Set_Interface_Layer(_MKL_INTERFACE_LP64)
        lib.MKL_Set_Threading_Layer(_MKL_THREADING_SEQUENTIAL)
        i32p = ctypes.POINTER(ctypes.c_int32)
        lib.pardiso.restype = None
        lib.pardiso.argtypes = [ctypes.c_void_p, i32p, i32p, i32p, i32p, i32p, ctypes.c_void_p, i32p, i32p, i32p,
                                i32p, i32p, i32p, ctypes.c_void_p, ctypes.c_void_p, i32p]
        log.debug("MKL PARDISO from %s", path)
        _LIB = lib
        break
    return _LIB


def available() -> bool:
    """Whether MKL PARDISO can be used in this environment."""
    return load_mkl() is not None


class PardisoError(RuntimeError):
    """PARDISO returned an error other than a non-positive pivot."""


_ERRORS = {-1: "input inconsistent", -2: "not enough memory", -3: "reordering problem",
           -4: "zero or negative pivot", -5: "unclassified internal error", -6: "reordering failed",
           -7: "diagonal matrix is singular", -8: "32-bit integer overflow", -9: "not enough memory for OOC",
           -10: "error opening OOC files", -11: "read/write error with OOC files"}


def _release(lib, pt, n, iparm) -> None:
    """Free PARDISO's internal memory of handle ``pt`` (phase -1)."""
    err = ctypes.c_int32(0)
    one = ctypes.c_int32(1)
    dummy = np.zeros(1)
    idx = np.zeros(2, np.int32)
    i32p = ctypes.POINTER(ctypes.c_int32)
    lib.pardiso(pt.ctypes.data, ctypes.byref(one), ctypes.byref(one), ctypes.byref(ctypes.c_int32(2)),
                ctypes.byref(ctypes.c_int32(-1)), ctypes.byref(ctypes.c_int32(n)), dummy.ctypes.data,
                idx.ctypes.data_as(i32p), idx.ctypes.data_as(i32p), None, ctypes.byref(one),
                iparm.ctypes.data_as(i32p), ctypes.byref(ctypes.c_int32(0)), None, None, ctypes.byref(err))


class PardisoSolver:
    """Cholesky factorisation of symmetric positive definite matrices with one pattern.

    indptr : (n+1,) and indices : (nnz,) the lower-triangular CSC pattern (rows sorted in
    each column, the diagonal present); the symbolic analysis (METIS nested dissection)
    runs once here.  ``factorize(data)`` then refactorises numerically, ``solve(b)`` solves.
    """

    def __init__(self, indptr: np.ndarray, indices: np.ndarray):
        lib = load_mkl()
        if lib is None:
            raise PardisoError("MKL PARDISO is not available (pip install mkl)")
        self._lib = lib
        self.n = len(indptr) - 1
        self._ia = np.ascontiguousarray(indptr, dtype=np.int32)
        self._ja = np.ascontiguousarray(indices, dtype=np.int32)
        self._pt = np.zeros(64, dtype=np.int64)  # PARDISO's internal handle (64 pointers)
        iparm = np.zeros(64, dtype=np.int32)
        iparm[0] = 1  # these settings, not the defaults
        iparm[1] = 2  # METIS nested dissection ordering
        iparm[7] = 0  # no iterative refinement (exact Cholesky: no perturbed pivots)
        iparm[9] = 13  # pivot perturbation threshold 1e-13 (unused for mtype 2)
        iparm[17] = -1  # report nnz(L)
        iparm[18] = -1  # report the factorisation's MFlop
        iparm[23] = 1  # two-level factorisation (faster on one core too: measured 19 vs 20 ms)
        iparm[34] = 1  # zero-based indices
        self._iparm = iparm
        self._data = None
        self.factorized = False
        self._finalizer = weakref.finalize(self, _release, lib, self._pt, self.n, iparm)
        self._call(11, np.zeros(len(self._ja)))  # symbolic analysis on the pattern only
        self.nnz_factor = int(iparm[17])
        self.mflop = int(iparm[18])

    def _call(self, phase: int, data: np.ndarray, b: np.ndarray | None = None) -> np.ndarray | None:
        i32p = ctypes.POINTER(ctypes.c_int32)
        one = ctypes.c_int32(1)
        nrhs = 1 if b is None or b.ndim == 1 else b.shape[1]
        x = None if b is None else np.zeros_like(b)
        bx = (None, None) if b is None else (b.ctypes.data, x.ctypes.data)
        err = ctypes.c_int32(0)
        self._lib.pardiso(self._pt.ctypes.data, ctypes.byref(one), ctypes.byref(one), ctypes.byref(ctypes.c_int32(2)),
                          ctypes.byref(ctypes.c_int32(phase)), ctypes.byref(ctypes.c_int32(self.n)), data.ctypes.data,
                          self._ia.ctypes.data_as(i32p), self._ja.ctypes.data_as(i32p), None, ctypes.byref(ctypes.c_int32(nrhs)),
                          self._iparm.ctypes.data_as(i32p), ctypes.byref(ctypes.c_int32(0)), bx[0], bx[1], ctypes.byref(err))
        if err.value == -4:
            raise _NotPD()
        if err.value != 0:
            raise PardisoError(f"PARDISO phase {phase}: error {err.value} ({_ERRORS.get(err.value, 'unknown')})")
        return x

    def factorize(self, data: np.ndarray) -> bool:
        """data : (nnz,) values on the pattern.  Returns False if the matrix is not
        positive definite (a non-positive pivot), True once factorised."""
        self._data = np.ascontiguousarray(data, dtype=np.float64)
        self.factorized = False
        try:
            self._call(22, self._data)
        except _NotPD:
            return False
        self.factorized = True
        return True

    def solve(self, b: np.ndarray) -> np.ndarray:
        """b : (n,) or (n, k) -> the solution of the same shape."""
        if not self.factorized:
            raise PardisoError("solve before a successful factorisation")
        bb = np.asfortranarray(b, dtype=np.float64)  # several right-hand sides: column after column
        return self._call(33, self._data, bb)


class _NotPD(Exception):
    pass
