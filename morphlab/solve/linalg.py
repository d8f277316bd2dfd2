"""Factorization of the step matrix: one fixed CSC pattern, many value sets.

:class:`StepFactorization` is what :class:`morphlab.solver.Stepper` factors each Newton matrix
with, and what the sensitivity solves reuse. Small matrices (at most :data:`DENSE_MAX`
unknowns) go to a dense LU with partial pivoting (:mod:`morphlab.kernels.dense`); larger ones
to a compiled sparse refactorization (:mod:`morphlab.kernels.sparse_lu`) that reuses the
fill-reducing order and the row pivots SuperLU chose (:data:`SPLU_OPTIONS`). Every
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

from ..kernels.dense import csc_to_dense, lu_factor
from ..kernels.dense import lu_solve as dense_lu_solve
from ..kernels.sparse_lu import refactor, symbolic
from ..kernels.sparse_lu import solve as sparse_solve

# Step matrices of at most this many unknowns are factored dense (kernels.dense). Against
# SuperLU (~20 us of set-up per factorization) the boundary was 60 unknowns; against the
# compiled refactorization it is lower. Whole runs with the compiled Newton loop on either
# kind (1000 steps, medians of 9 interleaved rounds, 2026-11-22), sparse / dense: 8 unknowns
# 1.01, 11: 1.09, 17: 1.04-1.06 (a flexible pendulum and a rigid four-bar), 29: 0.90, 35: 1.00,
# 53: 0.69 (direct sensitivities 0.71).
DENSE_MAX = 24

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

    Sparse path (more than :data:`DENSE_MAX` unknowns), each matrix factored once:

    * the first matrix by SuperLU with a fill-reducing order ``q`` (minimum degree on
      A^T + A, :data:`SPLU_OPTIONS`). The pattern is fixed, so every later matrix is permuted
      symmetrically, ``B = A[q][:, q]``, by a precomputed gather of its CSC values;
    * the next ``B`` by SuperLU in that column order (``permc_spec="NATURAL"``), whose
      threshold pivoting chooses a row order (:class:`_Pivots`);
    * every later ``B`` by the compiled refactorization with that row order
      (:func:`morphlab.kernels.sparse_lu.refactor`; the patterns of the factors are found once,
      when the order is first reused). A pivot that fails SuperLU's own threshold test (below
      0.1 of the largest entry under it) sends that matrix back to SuperLU, which chooses a
      new row order.

    Measured on the morphing model (123 unknowns, 1587 nonzeros, 544 step matrices of a run):
    14 us per refactorization (6215 multiply-adds, called from Python with its factors
    allocated) against 44 us per SuperLU factorization in the same column order (its set-up
    and supernode bookkeeping dominate at this size; 68 us with its own ordering), solves with
    5 right-hand sides 6.7 against 16 us; the solutions agreed with dense LAPACK solves to
    3e-12 relative. (A first measurement gave 6 us per refactorization; re-measured twice
    since, 13-14 us.) The row order SuperLU chose on the second matrix served the whole run;
    with a 60-element skin it was renewed 3 times, with 300 elements 5 times. The first
    matrix of a run (the initial solve, mass and constraint blocks only) is a poor source of
    row pivots for the step matrices: on a 3000-element skin its order fills L + U with 7.9 M
    nonzeros against 0.16 M for the order of a step matrix, hence the order is taken from the
    second matrix.
    """

    def __init__(self, indices: np.ndarray, indptr: np.ndarray, n: int, dtype):
        self.indices = indices
        self.indptr = indptr
        self.n = n
        self.dtype = np.dtype(dtype)
        self._order = None  # (q, gather, B indices, B indptr)
        self._superlu = None  # SuperLU in the column order q (_NaturalFactor)
        self._pivots = None  # the kept row order
        self.n_orders = 0  # row orders chosen by SuperLU in this run

    @property
    def dense(self) -> bool:
        """Are the matrices factored by the dense LU (at most :data:`DENSE_MAX` unknowns)?"""
        return self.n <= DENSE_MAX

    @property
    def settled(self) -> bool:
        """Is the next matrix factored by a compiled kernel alone: the dense LU, or the sparse
        refactorization once SuperLU has chosen a row order (:attr:`pivots`)?"""
        return self.dense or self._pivots is not None

    @property
    def pivots(self) -> _Pivots | None:
        """The row order later sparse matrices are refactored with (its patterns found), or
        None while SuperLU has chosen none."""
        return None if self._pivots is None else self._pivots.ready()

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
        if self._order is None:
            lu, self._order = self._first(data)
            return lu
        q, gather, b_indices, b_indptr, b_cols = self._order
        if self._pivots is not None:
            lu = self._pivots.factor(data, SPLU_OPTIONS["diag_pivot_thresh"])
            if lu is not None:
                return lu
        b_data = data[gather]
        if self._superlu is None:
            self._superlu = _NaturalFactor(b_indices, b_indptr)
        d = column_scaling(b_data, b_indptr)
        pair = d[b_indices] * d[b_cols]
        lu = self._superlu(b_data * pair)
        self._pivots = _Pivots(lu.perm_r, d, pair, gather, b_indices, b_indptr, q,
                               self.dtype)
        self.n_orders += 1
        return _PermutedLU(lu, q, d)

    def _first(self, data):
        """SuperLU's factorization of the first matrix, and ``(q, gather, indices, indptr,
        cols)``: its column order ``q`` and the CSC pattern of ``B = A[q][:, q]`` (with the
        column of each entry), whose values are ``data[gather]``."""
        d = column_scaling(data, self.indptr)
        A = sp.csc_matrix((data * d[self.indices] * np.repeat(d, np.diff(self.indptr)),
                           self.indices, self.indptr), shape=(self.n, self.n))
        lu = splu(A, **SPLU_OPTIONS)
        q = np.argsort(lu.perm_c)  # position j of the factored matrix holds column q[j]
        tag = sp.csc_matrix((np.arange(1, data.size + 1, dtype=np.float64), self.indices,
                             self.indptr), shape=(self.n, self.n))
        B = tag[q][:, q].tocsc()
        B.sort_indices()
        gather = (B.data - 1).astype(np.int64)
        cols = np.repeat(np.arange(self.n, dtype=np.int64), np.diff(B.indptr))
        return _PermutedLU(lu, None, d), (q, gather, B.indices.astype(np.int64),
                                          B.indptr.astype(np.int64), cols)


def column_scaling(data: np.ndarray, indptr: np.ndarray) -> np.ndarray:
    """``d`` (n,) with ``d_j = 1/sqrt(max_i |A_ij|)`` (1 for an empty column): the symmetric
    scaling ``D A D`` makes the threshold pivot test independent of the units of the unknowns.
    Without it the initial-acceleration matrix of a 3000-element skin (mass and constraint
    blocks; beam-node rotations with diagonal masses ~1e-11 against couplings ~1e-7) failed
    the test on most diagonal pivots, and SuperLU's row interchanges filled L + U with 7.9 M
    nonzeros in 0.69 s; scaled, 0.18 M in 0.06 s."""
    n = indptr.size - 1
    a = np.abs(data)
    counts = np.diff(indptr)
    cmax = np.zeros(n)
    full = counts > 0
    cmax[full] = np.maximum.reduceat(a, indptr[:-1][full])
    d = np.ones(n)
    good = cmax > 0
    d[good] = 1.0 / np.sqrt(cmax[good])
    return d


def no_sparse_arrays(dtype) -> tuple:
    """``(order, pattern)`` of :mod:`morphlab.kernels.newton` with no entries, typed as those of
    a sparse factor of ``dtype`` (``_Pivots.order_arrays``, ``_Pivots.solve_arrays``):
    what the compiled kernels take beside a dense factor."""
    idx = np.zeros(0, dtype=np.int64)
    real = np.zeros(0)
    return ((idx, real, idx, idx, idx, np.zeros(0, dtype=dtype)),
            (idx, idx, idx, idx, idx, real, idx, real))


class DenseLU:
    """Dense ``P A = L U`` of a small step matrix (:mod:`morphlab.kernels.dense`)."""

    __slots__ = ("LU", "piv")

    def __init__(self, LU, piv):
        self.LU = LU
        self.piv = piv

    @property
    def nbytes(self) -> int:
        """Memory of the factors."""
        return self.LU.nbytes + self.piv.nbytes

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

    def __init__(self, indices: np.ndarray, indptr: np.ndarray):
        self.n = indptr.size - 1
        self.indices = np.ascontiguousarray(indices, dtype=np.intc)
        self.indptr = np.ascontiguousarray(indptr, dtype=np.intc)
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


class _Pivots:
    """A row order SuperLU chose for the scaled ``D B D`` (``perm_r``; ``d`` (n,), ``pair``
    (nnz,) the scale of each entry), reused for later matrices: the patterns of the factors
    (:func:`morphlab.kernels.sparse_lu.symbolic`) are found when it is first reused."""

    def __init__(self, perm_r, d, pair, gather, b_indices, b_indptr, q, dtype):
        self.perm_r = np.ascontiguousarray(perm_r, dtype=np.int64)
        self.pair = pair
        self.gather = gather  # entry p of B is entry gather[p] of A
        self.indices = b_indices
        self.indptr = b_indptr
        first = np.argsort(self.perm_r)  # row k of C = P_r B is row first[k] of B
        self.row_from = q[first]
        self.row_scale = d[first]
        self.col_to = q  # x[q] = D y
        self.col_scale = d
        self.work = np.zeros(q.size, dtype=dtype)
        # what the refactorization reads besides the matrix and the patterns (``order`` of
        # morphlab.kernels.newton)
        self.order_arrays = (self.gather, self.pair, self.indices, self.indptr, self.perm_r,
                             self.work)
        self.patterns = None  # (Lp, Li, Up, Ui), by ready()
        self.solve_arrays = None  # ``pattern`` of morphlab.kernels.newton, by ready()

    def ready(self) -> _Pivots:
        """Find the patterns of the factors and the arrays a solve reads besides the values,
        ``solve_arrays = (Lp, Li, Up, Ui, row_from, row_scale, col_to, col_scale)`` (once), and
        return self."""
        if self.patterns is None:
            self.patterns = symbolic(self.work.size, self.indices, self.indptr, self.perm_r)
            self.solve_arrays = (*self.patterns, self.row_from, self.row_scale, self.col_to,
                                 self.col_scale)
        return self

    def empty_factors(self) -> tuple:
        """Fresh ``(Lx, Ux, Ud)`` for one factorization."""
        Lp, Li, Up, Ui = self.ready().patterns
        dt = self.work.dtype
        return (np.empty(Li.size, dtype=dt), np.empty(Ui.size, dtype=dt),
                np.empty(self.work.size, dtype=dt))

    def factor(self, data, tau):
        """The :class:`SparseLU` of ``B = A[q][:, q]`` for the CSC values ``data`` of ``A``, or
        None if a pivot fails the threshold ``tau`` (:func:`morphlab.kernels.sparse_lu.refactor`,
        which reads ``data`` through the gather)."""
        Lx, Ux, Ud = self.empty_factors()
        Lp, Li, Up, Ui = self.patterns
        bad = refactor(data, self.gather, self.pair, self.indices, self.indptr, self.perm_r, Lp,
                       Li, Up, Ui, Lx, Ux, Ud, self.work, tau)
        return None if bad >= 0 else SparseLU(self, Lx, Ux, Ud)


class SparseLU:
    """``P_r D A[q][:, q] D = L U`` of a step matrix (:mod:`morphlab.kernels.sparse_lu`)."""

    __slots__ = ("pivots", "Lx", "Ux", "Ud")

    def __init__(self, pivots: _Pivots, Lx, Ux, Ud):
        self.pivots = pivots
        self.Lx = Lx
        self.Ux = Ux
        self.Ud = Ud

    @property
    def nbytes(self) -> int:
        """Memory of the values (the patterns are shared by all factors of a row order)."""
        return self.Lx.nbytes + self.Ux.nbytes + self.Ud.nbytes

    def solve(self, b):
        dt = np.result_type(self.Lx.dtype, b.dtype)
        b2 = np.asarray(b, dtype=dt).reshape(b.shape[0], -1)
        x = np.empty(b2.shape, dtype=dt)
        p = self.pivots
        Lp, Li, Up, Ui = p.patterns
        sparse_solve(Lp, Li, self.Lx, Up, Ui, self.Ux, self.Ud, p.row_from, p.row_scale,
                     p.col_to, p.col_scale, b2, x, np.empty_like(x))
        return x.reshape(b.shape)


class _PermutedLU:
    """SuperLU's LU of ``D B D`` with ``B = A[q][:, q]`` (``q is None``: ``B = A``) solving
    ``A x = b``: ``x[q] = D (D B D)^-1 D b[q]``."""

    __slots__ = ("lu", "q", "d")

    def __init__(self, lu, q, d):
        self.lu = lu
        self.q = q
        self.d = d

    @property
    def nbytes(self) -> int:
        """Estimated memory: ``24 nnz(L+U) + 40 kB``, fitted to the resident memory of 301 kept
        SuperLU factorizations of the morphing skin (0.083 MiB each at 30 elements, 0.41 MiB
        at 300)."""
        return 24 * int(self.lu.nnz) + 40_000

    def solve(self, b):
        d = self.d.reshape((-1,) + (1,) * (b.ndim - 1))
        if self.q is None:
            return d * self._solve(d * b)
        y = d * self._solve(d * b[self.q])
        x = np.empty_like(y)
        x[self.q] = y
        return x

    def _solve(self, b):
        try:
            return self.lu.solve(b)
        except TypeError:  # SuperLU solves in its own dtype: a real LU, a complex b
            if not np.iscomplexobj(b):
                raise
            return self.lu.solve(np.ascontiguousarray(b.real)) + 1j * self.lu.solve(
                np.ascontiguousarray(b.imag))
