"""SuperLU's factorization of step matrices, for :mod:`morphlab.solve.linalg`.

The saddle-point matrix is structurally nearly symmetric (mass and stiffness blocks plus
``J`` and ``J^T``), so SuperLU orders it by minimum degree on ``A^T + A`` in its symmetric mode
with threshold pivoting (:data:`SPLU_OPTIONS`): the diagonal is kept unless it is below
:data:`PIVOT_THRESHOLD` of the column's largest entry (the default COLAMD with partial
pivoting fills the factors of long beams almost densely; BENCHMARKS.md).
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
from scipy.sparse.linalg import splu

try:  # SciPy's SuperLU wrapper, what splu calls after its input checks (see NaturalOrderLU)
    from scipy.sparse.linalg._dsolve._superlu import gstrf as _gstrf
except ImportError:  # pragma: no cover - other SciPy layouts: splu is used
    _gstrf = None

#: SuperLU's threshold of partial pivoting, also the acceptance test of the compiled
#: refactorization's pivots.
PIVOT_THRESHOLD = 0.1
SPLU_OPTIONS = dict(permc_spec="MMD_AT_PLUS_A", diag_pivot_thresh=PIVOT_THRESHOLD,
                    options=dict(SymmetricMode=True))


def column_scaling(data: np.ndarray, indptr: np.ndarray) -> np.ndarray:
    """``d`` (n,) with ``d_j = 1/sqrt(max_i |A_ij|)`` (1 for an empty column): the symmetric
    scaling ``D A D`` makes the threshold pivot test independent of the units of the unknowns
    (beam-node rotations with masses ~1e-11 beside couplings ~1e-7 in mm, t, s otherwise fail
    it on most diagonal pivots and SuperLU's row interchanges fill the factors)."""
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


def first_factor(data, indices, indptr, n):
    """SuperLU's factorization ``lu`` of the scaled first matrix of a run ``D A D``, the
    scaling ``d`` (n,), and ``(q, gather, indices, indptr, cols)``: its column order ``q`` and
    the CSC pattern of ``B = A[q][:, q]`` (with the column of each entry), whose values are
    ``data[gather]``."""
    d = column_scaling(data, indptr)
    A = sp.csc_matrix((data * d[indices] * np.repeat(d, np.diff(indptr)), indices, indptr),
                      shape=(n, n))
    lu = splu(A, **SPLU_OPTIONS)
    q = np.argsort(lu.perm_c)  # position j of the factored matrix holds column q[j]
    tag = sp.csc_matrix((np.arange(1, data.size + 1, dtype=np.float64), indices, indptr),
                        shape=(n, n))
    B = tag[q][:, q].tocsc()
    B.sort_indices()
    gather = (B.data - 1).astype(np.int64)
    cols = np.repeat(np.arange(n, dtype=np.int64), np.diff(B.indptr))
    return lu, d, (q, gather, B.indices.astype(np.int64), B.indptr.astype(np.int64), cols)


class NaturalOrderLU:
    """SuperLU factorizations of matrices with one fixed CSC pattern and no column reordering.

    ``splu`` checks its input and converts the int64 index arrays to C ints on every call
    before it calls SciPy's SuperLU wrapper; here the conversion is done once and the wrapper
    is called directly. The entry point is private to SciPy, so the first call that it refuses
    (missing, or a changed signature: ``TypeError``) switches this object to ``splu``.
    """

    def __init__(self, indices: np.ndarray, indptr: np.ndarray):
        self.n = indptr.size - 1
        self.indices = np.ascontiguousarray(indices, dtype=np.intc)
        self.indptr = np.ascontiguousarray(indptr, dtype=np.intc)
        self.options = dict(DiagPivotThresh=PIVOT_THRESHOLD, ColPerm="NATURAL", PanelSize=None,
                            Relax=None, **SPLU_OPTIONS["options"])
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
        return splu(B, permc_spec="NATURAL", diag_pivot_thresh=PIVOT_THRESHOLD,
                    options=SPLU_OPTIONS["options"])
