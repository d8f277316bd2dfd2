"""Products with a sparse matrix in compressed-column form (CSC: ``data``, ``indices``,
``indptr``), plain or transposed, for the right-hand sides and the refinement residuals of the
direct (``A x``) and adjoint (``A^T x``) sensitivities. One loop serves both: entry ``p`` of
column ``j`` couples row ``indices[p]`` and column ``j``, and only which of the two is read and
which is written changes. The choice is a branch around the innermost loop: choosing the two
indices per entry instead (a pair of selects) made the adjoint's sweep 8 % slower.
"""

import numpy as np

from ._jit import inner, kernel


@inner
def subtract_product(data, indices, indptr, n_cols, x, out, transposed):
    """``out -= A[:, :n_cols] x`` (``transposed`` False) or ``out[:n_cols] -= A[:, :n_cols]^T
    x`` (True) for the CSC matrix ``A`` and ``x``, ``out`` (n, m)."""
    m = x.shape[1]
    for j in range(n_cols):
        for p in range(indptr[j], indptr[j + 1]):
            row = indices[p]
            aij = data[p]
            if transposed:
                for i in range(m):
                    out[j, i] -= aij * x[row, i]
            else:
                for i in range(m):
                    out[row, i] -= aij * x[j, i]


@kernel
def residual(data, indices, indptr, x, b, r, transposed):
    """``r = b - A x`` (``transposed`` False) or ``r = b - A^T x`` (True) for the square CSC
    matrix ``A`` and ``x``, ``b``, ``r`` (n, m); returns ``(|r|_F, |b|_F)``."""
    n = indptr.shape[0] - 1
    m = x.shape[1]
    for j in range(n):
        for i in range(m):
            r[j, i] = b[j, i]
    subtract_product(data, indices, indptr, n, x, r, transposed)
    rr = 0.0
    bb = 0.0
    for j in range(n):
        for i in range(m):
            rr += r[j, i] * r[j, i]
            bb += b[j, i] * b[j, i]
    return np.sqrt(rr), np.sqrt(bb)
