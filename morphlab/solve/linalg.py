"""Factorizations of the step matrix: one fixed CSC pattern, many value sets, one interface.

Every factorization is a :class:`Factor`: ``solve(b)``, ``solve_transposed(b)`` (the adjoint
sweep), ``nbytes``, and for the compiled kernels ``compiled`` and ``arrays()`` (the
:class:`~morphlab.kernels.newton.Factors` they solve with). Three kinds exist, private to this
module:

* a dense LU with partial pivoting of small matrices (at most ``dense_max`` unknowns,
  :mod:`morphlab.kernels.dense`), where a sparse factorization's set-up costs more than the
  elimination;
* a compiled sparse refactorization (:mod:`morphlab.kernels.sparse_lu`) that reuses the
  fill-reducing column order and the row pivots SuperLU chose for an earlier matrix of the
  same pattern;
* SuperLU's own factorization (:mod:`morphlab.solve.superlu`), for the matrices on which a
  row order is chosen.

:class:`StepFactorization` decides which kind factors the next matrix; the Newton loop and the
sensitivity strategies see :class:`Factor` objects only, and the compiled loops the arrays
:meth:`StepFactorization.loop_arrays` gives them.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from ..kernels.dense import csc_to_dense, lu_factor, lu_solve, lu_solve_transposed
from ..kernels.newton import Factors
from ..kernels.sparse_lu import refactor, symbolic
from ..kernels.sparse_lu import solve as sparse_solve
from ..kernels.sparse_lu import solve_transposed as sparse_solve_transposed
from .superlu import PIVOT_THRESHOLD, NaturalOrderLU, column_scaling, first_factor

#: Bytes of one chunk of sparse factor values (:meth:`_RowOrder.empty_factors`).
CHUNK_BYTES = 8 * 2**20

#: Default of ``Settings.dense_max``: step matrices of at most this many unknowns are factored
#: dense (the boundary measured against the compiled sparse refactorization: BENCHMARKS.md).
DENSE_MAX = 24


class SingularFactor(RuntimeError):
    """A dense LU found no nonzero pivot for column ``column`` of the matrix."""

    def __init__(self, column: int):
        super().__init__(f"Factor is exactly singular (pivot {column})")
        self.column = column


class Factor:
    """A factorization of one step matrix ``A`` (n, n).

    ``solve(b)`` returns ``A^-1 b`` and ``solve_transposed(b)`` ``A^-T b`` for ``b`` (n,) or
    (n, m), real or complex; ``nbytes`` is the memory the factorization keeps. A ``compiled``
    factor's arrays (:meth:`arrays`) are what the compiled kernels solve with
    (:func:`morphlab.kernels.newton.solve_factored`).
    """

    __slots__ = ()
    compiled = False

    def solve(self, b):  # pragma: no cover - interface
        raise NotImplementedError

    def solve_transposed(self, b):  # pragma: no cover - interface
        raise NotImplementedError

    @property
    def nbytes(self) -> int:  # pragma: no cover - interface
        raise NotImplementedError

    def arrays(self) -> Factors:  # pragma: no cover - interface
        """The :class:`~morphlab.kernels.newton.Factors` of a compiled factor (the other
        kind's arrays empty; ``order``, ``pattern`` None for a dense factor)."""
        raise NotImplementedError


def _columns(b, dtype):
    """``(x, shape, xk)``: ``b`` as a C-ordered (n, m) copy ``x`` in the result type of
    ``b`` and the factor's ``dtype``, the shape to return, and what the factor's kernels solve
    in place: ``x`` itself, or for a complex ``b`` and a real factor the real view of ``x``
    (n, 2m), whose columns alternate real and imaginary parts. A real matrix solves the two
    parts apart, so the real kernels serve and no kernel of mixed types is compiled."""
    dt = np.result_type(dtype, b.dtype)
    x = np.array(b, dtype=dt, order="C").reshape(b.shape[0], -1)
    return x, b.shape, (x if dt == dtype else x.view(dtype))


class _DenseLU(Factor):
    """Dense ``P A = L U`` (:mod:`morphlab.kernels.dense`)."""

    __slots__ = ("LU", "piv")
    compiled = True

    def __init__(self, LU, piv):
        self.LU = LU
        self.piv = piv

    @property
    def nbytes(self) -> int:
        return self.LU.nbytes + self.piv.nbytes

    def solve(self, b):
        x, shape, xk = _columns(b, self.LU.dtype)
        lu_solve(self.LU, self.piv, xk)
        return x.reshape(shape)

    def solve_transposed(self, b):
        x, shape, xk = _columns(b, self.LU.dtype)
        lu_solve_transposed(self.LU, self.piv, xk)
        return x.reshape(shape)

    def arrays(self) -> Factors:
        return Factors(self.LU, self.piv, None, None, None, None, None)


class _RowOrder:
    """A row order SuperLU chose for the scaled ``D B D`` (``B = A[q][:, q]``; ``perm_r``,
    ``d`` (n,), ``pair`` (nnz,) the scale of each entry), kept to refactor later matrices
    with (:func:`morphlab.kernels.sparse_lu.refactor`). The patterns of its factors are found
    when it is first reused."""

    def __init__(self, perm_r, d, pair, gather, b_indices, b_indptr, q, dtype):
        self.perm_r = np.ascontiguousarray(perm_r, dtype=np.int64)
        first = np.argsort(self.perm_r)  # row k of C = P_r B is row first[k] of B
        self.work = np.zeros(q.size, dtype=dtype)
        # what the refactorization reads besides the matrix and the patterns
        self.order_arrays = (gather, pair, b_indices, b_indptr, self.perm_r, self.work)
        self._solve_maps = (q[first], d[first], q, d)  # row_from, row_scale, col_to, col_scale
        self.patterns = None  # (Lp, Li, Up, Ui)
        self.solve_arrays = None  # ``pattern`` of morphlab.kernels.newton
        self._chunk = None  # (Lx, Ux, Ud) rows for the next factors (empty_factors)
        self._next = 0
        self.last_row = -1

    def ready(self) -> _RowOrder:
        """Find the patterns of the factors (once) and return self."""
        if self.patterns is None:
            _, _, b_indices, b_indptr, perm_r, work = self.order_arrays
            self.patterns = symbolic(work.size, b_indices, b_indptr, perm_r)
            self.solve_arrays = (*self.patterns, *self._solve_maps)
        return self

    def empty_factors(self) -> tuple:
        """Fresh ``(Lx, Ux, Ud)`` for one factorization: the next rows of a chunk of
        :data:`CHUNK_BYTES` (a chunk is freed with the last factor in it). ``last_row``: the
        row of the factors returned."""
        if self._chunk is None or self._next == self._chunk[0].shape[0]:
            _, Li, _, Ui = self.ready().patterns
            dt = self.work.dtype
            sizes = (Li.size, Ui.size, self.work.size)
            slots = max(1, CHUNK_BYTES // max(1, sum(sizes) * dt.itemsize))
            self._chunk = tuple(np.empty((slots, k), dt) for k in sizes)
            self._next = 0
        i = self.last_row = self._next
        self._next += 1
        return tuple(c[i] for c in self._chunk)

    def factor(self, data, tau):
        """The factor of the matrix with CSC values ``data``, or None if a pivot fails the
        threshold ``tau`` (SuperLU must choose a new row order)."""
        Lx, Ux, Ud = self.empty_factors()
        gather, pair, b_indices, b_indptr, perm_r, work = self.order_arrays
        Lp, Li, Up, Ui = self.patterns
        bad = refactor(data, gather, pair, b_indices, b_indptr, perm_r, Lp, Li, Up, Ui, Lx, Ux,
                       Ud, work, tau)
        return None if bad >= 0 else _SparseLU(self, Lx, Ux, Ud, self.last_row)


class _SparseLU(Factor):
    """``P_r D A[q][:, q] D = L U`` by the compiled refactorization with a kept row order;
    ``Lx, Ux, Ud`` are row ``row`` of a chunk (:meth:`_RowOrder.empty_factors`)."""

    __slots__ = ("order", "Lx", "Ux", "Ud", "row")
    compiled = True

    def __init__(self, order: _RowOrder, Lx, Ux, Ud, row: int):
        self.order = order
        self.Lx = Lx
        self.Ux = Ux
        self.Ud = Ud
        self.row = row

    @property
    def nbytes(self) -> int:
        """Memory of the values (the patterns are shared by all factors of a row order)."""
        return self.Lx.nbytes + self.Ux.nbytes + self.Ud.nbytes

    def _apply(self, kernel, b):
        b2, shape, bk = _columns(b, self.Lx.dtype)
        x = np.empty_like(bk)
        Lp, Li, Up, Ui, *maps = self.order.solve_arrays
        kernel(Lp, Li, self.Lx, Up, Ui, self.Ux, self.Ud, *maps, bk, x, np.empty_like(x))
        return x.view(b2.dtype).reshape(shape)

    def solve(self, b):
        return self._apply(sparse_solve, b)

    def solve_transposed(self, b):
        return self._apply(sparse_solve_transposed, b)

    def arrays(self) -> Factors:
        return Factors(None, None, self.Lx, self.Ux, self.Ud,
                       self.order.order_arrays, self.order.solve_arrays)


class _SuperLUFactor(Factor):
    """SuperLU's LU of ``D B D`` with ``B = A[q][:, q]`` (``q is None``: ``B = A``) solving
    ``A x = b``: ``x[q] = D (D B D)^-1 D b[q]``, and ``A^T x = b`` with the transposed
    factors. No compiled kernel reads it."""

    __slots__ = ("lu", "q", "d")

    def __init__(self, lu, q, d):
        self.lu = lu
        self.q = q
        self.d = d

    @property
    def nbytes(self) -> int:
        """Estimated memory: ``24 nnz(L+U) + 40 kB`` (fitted to the resident memory of kept
        SuperLU factors of beams of 30 to 300 elements)."""
        return 24 * int(self.lu.nnz) + 40_000

    def solve(self, b):
        return self._apply(b, "N")

    def solve_transposed(self, b):
        return self._apply(b, "T")

    def _apply(self, b, trans):
        d = self.d.reshape((-1,) + (1,) * (b.ndim - 1))
        if self.q is None:
            return d * self._solve(d * b, trans)
        y = d * self._solve(d * b[self.q], trans)
        x = np.empty_like(y)
        x[self.q] = y
        return x

    def _solve(self, b, trans):
        try:
            return self.lu.solve(b, trans=trans)
        except TypeError:  # SuperLU solves in its own dtype: a real LU, a complex b
            if not np.iscomplexobj(b):
                raise
            return (self.lu.solve(np.ascontiguousarray(b.real), trans=trans)
                    + 1j * self.lu.solve(np.ascontiguousarray(b.imag), trans=trans))


class StepFactorization:
    """Factor matrices that share the CSC pattern ``(indices, indptr)`` of size ``n``.

    At most ``dense_max`` unknowns: every matrix by the dense LU. Otherwise each matrix is
    factored once, by the cheapest kind that serves it:

    * the first matrix by SuperLU with a fill-reducing order ``q`` (minimum degree on
      ``A^T + A``); the pattern is fixed, so later matrices are permuted symmetrically,
      ``B = A[q][:, q]``, by a precomputed gather of their CSC values;
    * the next ``B`` by SuperLU in that column order, whose threshold pivoting chooses a row
      order (the first matrix of a run, the initial solve's mass and constraint blocks, is a
      poor source of row pivots for the step matrices);
    * every later ``B`` by the compiled refactorization with that row order. A pivot below
      SuperLU's own threshold (:data:`~morphlab.solve.superlu.PIVOT_THRESHOLD` of the largest
      entry under it) sends that matrix back to SuperLU, which chooses a new row order, and
      the matrix is then refactored with it (a compiled factor, as the sensitivity runs
      need; SuperLU's own if even that fails).

    Matrices are scaled symmetrically (``D A D``, :func:`column_scaling`) before pivoting.
    A matrix without a usable pivot raises ``RuntimeError`` (the caller names the unknown).
    """

    def __init__(self, indices: np.ndarray, indptr: np.ndarray, n: int, dtype,
                 dense_max: int = DENSE_MAX):
        self.indices = indices
        self.indptr = indptr
        self.n = n
        self.dtype = np.dtype(dtype)
        self.dense = n <= dense_max
        self._order = None  # (q, gather, B indices, B indptr, B columns)
        self._natural = None  # SuperLU in the column order q
        self._rows = None  # the kept row order (_RowOrder)
        self.n_orders = 0  # row orders chosen by SuperLU in this run

    @property
    def settled(self) -> bool:
        """Is the next matrix factored by a compiled kernel alone (the dense LU, or the sparse
        refactorization once SuperLU has chosen a row order)?"""
        return self.dense or self._rows is not None

    def __call__(self, data: np.ndarray) -> Factor:
        """Factor the matrix with CSC values ``data`` (nnz,)."""
        if self.dense:
            A = np.empty((self.n, self.n), dtype=self.dtype)
            piv = np.empty(self.n, dtype=np.int64)
            csc_to_dense(data, self.indices, self.indptr, A)
            bad = lu_factor(A, piv)
            if bad >= 0:
                raise SingularFactor(bad)
            return _DenseLU(A, piv)
        if self._order is None:
            lu, d, self._order = first_factor(data, self.indices, self.indptr, self.n)
            return _SuperLUFactor(lu, None, d)
        if self._rows is not None:
            lu = self._rows.ready().factor(data, PIVOT_THRESHOLD)
            if lu is not None:
                return lu
        return self._new_row_order(data)

    def _new_row_order(self, data) -> Factor:
        """SuperLU's factorization in the column order ``q``; its row order is kept."""
        q, gather, b_indices, b_indptr, b_cols = self._order
        b_data = data[gather]
        if self._natural is None:
            self._natural = NaturalOrderLU(b_indices, b_indptr)
        d = column_scaling(b_data, b_indptr)
        pair = d[b_indices] * d[b_cols]
        lu = self._natural(b_data * pair)
        first = self._rows is None
        self._rows = _RowOrder(lu.perm_r, d, pair, gather, b_indices, b_indptr, q, self.dtype)
        self.n_orders += 1
        if not first:  # a compiled factor of this matrix with the new order, where it serves
            again = self._rows.ready().factor(data, PIVOT_THRESHOLD)
            if again is not None:
                return again
        return _SuperLUFactor(lu, q, d)

    # ---- the compiled Newton loop (morphlab.kernels.newton.newton_loop)
    def loop_arrays(self) -> Factors:
        """Fresh factor arrays for a compiled Newton solve once :attr:`settled` (dense:
        ``order``, ``pattern`` None and ``Lx, Ux, Ud`` empty; sparse: ``LU``, ``piv``
        empty)."""
        dt = self.dtype
        if self.dense:
            return Factors(np.empty((self.n, self.n), dtype=dt),
                           np.empty(self.n, dtype=np.int64), None, None, None, None, None)
        rows = self._rows.ready()
        return Factors(None, None, *rows.empty_factors(), rows.order_arrays, rows.solve_arrays)

    def factor_of(self, arrays: Factors) -> Factor:
        """The :class:`Factor` the compiled loop left in ``arrays`` (:meth:`loop_arrays`)."""
        if self.dense:
            return _DenseLU(arrays.LU, arrays.piv)
        return _SparseLU(self._rows, arrays.Lx, arrays.Ux, arrays.Ud, self._rows.last_row)

    @property
    def row_order(self) -> _RowOrder | None:
        """The kept sparse row order (None while SuperLU has chosen none or for dense
        factors)."""
        return None if self._rows is None else self._rows.ready()


def csc_matrix(data, indices, indptr, n: int) -> sp.csc_matrix:
    """A SciPy CSC matrix over the step pattern sharing ``data``."""
    return sp.csc_matrix((data, indices, indptr), shape=(n, n))
