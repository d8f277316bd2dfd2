"""Factorization of the step matrix: one fixed CSC pattern, many value sets.

:class:`StepFactorization` is what :class:`morphlab.solver.Stepper` factors each Newton matrix
with, and what the sensitivity solves reuse. Small matrices (at most :data:`DENSE_MAX`
unknowns) go to a dense LU with partial pivoting (:mod:`morphlab.kernels.dense`); larger ones
to SuperLU with a fill-reducing order computed once (:data:`SPLU_OPTIONS`). Every
factorization is returned as an object with ``solve(b)`` for ``b`` (n,) or (n, m); an exactly
singular matrix raises ``RuntimeError`` (the solver turns it into a SingularMatrixError).
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
from scipy.sparse.linalg import splu

try:  # SciPy's SuperLU wrapper, what splu calls after its input checks (see _NaturalFactor)
    from scipy.sparse.linalg._dsolve._superlu import gstrf as _gstrf
except ImportError:  # pragma: no cover - other SciPy layouts: splu is used
    _gstrf = None

from .kernels.dense import csc_to_dense, lu_factor
from .kernels.dense import lu_solve as dense_lu_solve

# Step matrices of at most this many unknowns are factored dense (kernels.dense): SuperLU's
# set-up costs ~20 us per factorization, more than the elimination itself for a few dozen
# unknowns. Measured per factorization plus one solve (SuperLU / dense): 17 unknowns 24 / 4.5
# us, 29: 30 / 9, 53: 48 / 32, 65: 58 / 57, 123 (the morphing model): 59 / 78.
DENSE_MAX = 60

# SuperLU settings for the saddle-point matrix. The matrix is structurally nearly symmetric
# (mass/stiffness blocks plus J and J^T), so a minimum-degree ordering of A^T + A in
# SymmetricMode with threshold pivoting (prefer the diagonal unless it is < 0.1 of the column
# maximum) keeps the sparsity; the default COLAMD with partial pivoting filled the LU almost
# densely on long skins. Measured on the morphing model (n = 123 / 333 / 933 unknowns):
# 0.20 / 0.36 / 1.3 ms per factorization against 0.23 / 1.2 / 9.2 ms with COLAMD (also with
# its column order computed once and reused); L+U nonzeros 18k against 410k at n = 933.
# The order is computed once per run and reused (StepFactorization).
SPLU_OPTIONS = dict(permc_spec="MMD_AT_PLUS_A", diag_pivot_thresh=0.1,
                    options=dict(SymmetricMode=True))


class StepFactorization:
    """Factor matrices that share the CSC pattern ``(indices, indptr)`` of size ``n``.

    SuperLU path: the first factorization computes the fill-reducing order ``q`` (minimum
    degree on A^T + A). The pattern is fixed, so later matrices are permuted symmetrically,
    ``B = A[q][:, q]``, by a precomputed gather of the CSC data and factored with
    ``permc_spec="NATURAL"``: same fill, without recomputing the ordering (measured 9.3 ms
    against 61 ms per factorization at 9033 unknowns, 0.9 against 1.9 ms at 933).
    """

    def __init__(self, indices: np.ndarray, indptr: np.ndarray, n: int, dtype):
        self.indices = indices
        self.indptr = indptr
        self.n = n
        self.dtype = np.dtype(dtype)
        self._perm = None
        self._B = None
        self._natural = None

    @property
    def dense(self) -> bool:
        """Are the matrices factored by the dense LU (at most :data:`DENSE_MAX` unknowns)?"""
        return self.n <= DENSE_MAX

    def __call__(self, data: np.ndarray):
        """Factor the matrix with CSC values ``data`` (nnz,)."""
        if self.dense:
            A = np.empty((self.n, self.n), dtype=self.dtype)
            piv = np.empty(self.n, dtype=np.int64)
            csc_to_dense(data, self.indices, self.indptr, A)
            bad = lu_factor(A, piv)
            if bad >= 0:
                raise RuntimeError(f"Factor is exactly singular (pivot {bad})")
            return DenseLU(A, piv)
        if self._perm is None:
            A = sp.csc_matrix((data, self.indices, self.indptr), shape=(self.n, self.n))
            lu = splu(A, **SPLU_OPTIONS)
            q = np.argsort(lu.perm_c)  # position j of the factored matrix holds column q[j]
            tag = sp.csc_matrix((np.arange(1, data.size + 1, dtype=np.float64), self.indices,
                                 self.indptr), shape=(self.n, self.n))
            B = tag[q][:, q].tocsc()
            B.sort_indices()
            gather = (B.data - 1).astype(np.int64)
            self._perm = (q, gather)
            self._B = sp.csc_matrix((data[gather], B.indices, B.indptr),
                                    shape=(self.n, self.n))
            return _PermutedLU(lu, None)
        q, gather = self._perm
        np.take(data, gather, out=self._B.data)
        if self._natural is None:
            self._natural = _NaturalFactor(self._B)
        return _PermutedLU(self._natural(self._B.data), q)


class DenseLU:
    """Dense ``P A = L U`` of a small step matrix (:mod:`morphlab.kernels.dense`)."""

    __slots__ = ("LU", "piv")

    def __init__(self, LU, piv):
        self.LU = LU
        self.piv = piv

    def solve(self, b):
        dt = np.result_type(self.LU.dtype, b.dtype)
        x = np.array(b, dtype=dt, order="C").reshape(b.shape[0], -1)
        dense_lu_solve(self.LU, self.piv, x)
        return x.reshape(b.shape)


class _NaturalFactor:
    """SuperLU factorizations of matrices with one fixed CSC pattern, no column reordering
    (:data:`SPLU_OPTIONS` with ``permc_spec="NATURAL"``).

    ``splu`` checks its input and converts the int64 index arrays to C ints on every call
    before it calls SciPy's SuperLU wrapper ``_superlu.gstrf``; here the conversion is done once
    and ``gstrf`` is called directly: ~12 us less per factorization, a third of one at 30
    unknowns (measured on the Exudyn comparison's pendulum, 1979 factorizations). The entry
    point is private to SciPy, so the first call that it refuses (missing, or a changed
    signature: ``TypeError``) switches this object to ``splu`` for good.
    """

    def __init__(self, B: sp.csc_matrix):
        self.n = B.shape[0]
        self.indices = np.ascontiguousarray(B.indices, dtype=np.intc)
        self.indptr = np.ascontiguousarray(B.indptr, dtype=np.intc)
        self.options = dict(DiagPivotThresh=SPLU_OPTIONS["diag_pivot_thresh"],
                            ColPerm="NATURAL", PanelSize=None, Relax=None,
                            **SPLU_OPTIONS["options"])
        self.direct = _gstrf is not None

    def __call__(self, data: np.ndarray):
        if self.direct:
            try:
                return _gstrf(self.n, data.size, data, self.indices, self.indptr,
                              csc_construct_func=sp.csc_array, ilu=False,
                              options=self.options)
            except TypeError:
                self.direct = False
        B = sp.csc_matrix((data, self.indices, self.indptr), shape=(self.n, self.n))
        return splu(B, permc_spec="NATURAL", diag_pivot_thresh=SPLU_OPTIONS["diag_pivot_thresh"],
                    options=SPLU_OPTIONS["options"])


class _PermutedLU:
    """The LU of ``B = A[q][:, q]`` solving ``A x = b`` (``q is None``: the LU of ``A``)."""

    __slots__ = ("lu", "q")

    def __init__(self, lu, q):
        self.lu = lu
        self.q = q

    def solve(self, b):
        if self.q is None:
            return self.lu.solve(b)
        y = self.lu.solve(b[self.q])
        x = np.empty_like(y)
        x[self.q] = y
        return x
