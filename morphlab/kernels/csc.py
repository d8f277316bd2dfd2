"""Products with a sparse matrix in compressed-column form (CSC: ``data``, ``indices``,
``indptr``), plain or transposed, for the right-hand sides and the refinement residuals of the
direct (``A x``) and adjoint (``A^T x``) sensitivities. Entry ``p`` of column ``j`` couples
row ``indices[p]`` and column ``j``. The plain product scatters column ``j`` into the rows; the
transposed one gathers column ``j`` into one sum per right-hand side. For a few right-hand
sides (an adjoint's responses, at most :data:`REGISTER_RHS`) those sums run in registers, one
right-hand side after the other (a sum kept in ``out`` makes every term wait for the store of
the one before); for more, the sums of all right-hand sides advance together in ``out``, which
reads each row of ``x`` once. :func:`subtract_products_transposed` forms the sums of two
matrices of one pattern in one pass.
"""

import numpy as np

from ._jit import inner, kernel

#: Transposed products with at most this many right-hand sides sum in registers (module
#: docstring); measured on matrices of 3.6e3 and 2.6e4 entries (two products): a quarter of
#: the time of the sums in ``out`` for one right-hand side, three quarters for four, more
#: from eight.
REGISTER_RHS = 4


@inner
def subtract_product(data, indices, indptr, n_cols, x, out, transposed):
    """``out -= A[:, :n_cols] x`` (``transposed`` False) or ``out[:n_cols] -= A[:, :n_cols]^T
    x`` (True) for the CSC matrix ``A`` and ``x``, ``out`` (n, m)."""
    m = x.shape[1]
    for j in range(n_cols):
        p0, p1 = indptr[j], indptr[j + 1]
        if not transposed:
            for p in range(p0, p1):
                row = indices[p]
                aij = data[p]
                for i in range(m):
                    out[row, i] -= aij * x[j, i]
        elif m <= REGISTER_RHS:
            for i in range(m):
                acc = out[j, i]
                for p in range(p0, p1):
                    acc -= data[p] * x[indices[p], i]
                out[j, i] = acc
        else:
            for p in range(p0, p1):
                row = indices[p]
                aij = data[p]
                for i in range(m):
                    out[j, i] -= aij * x[row, i]


@inner
def subtract_products_transposed(A1, A2, indices, indptr, n_cols, x, out1, out2):
    """``out1[:n_cols] -= A1[:, :n_cols]^T x`` and ``out2[:n_cols] -= A2[:, :n_cols]^T x`` for
    two CSC matrices of one pattern (``A1``, ``A2`` their values) in one pass; each equals
    :func:`subtract_product`'s, term for term in the same order."""
    m = x.shape[1]
    if m > REGISTER_RHS:
        subtract_product(A1, indices, indptr, n_cols, x, out1, True)
        subtract_product(A2, indices, indptr, n_cols, x, out2, True)
        return
    for j in range(n_cols):
        p0, p1 = indptr[j], indptr[j + 1]
        for i in range(m):
            a1 = out1[j, i]
            a2 = out2[j, i]
            for p in range(p0, p1):
                xr = x[indices[p], i]
                a1 -= A1[p] * xr
                a2 -= A2[p] * xr
            out1[j, i] = a1
            out2[j, i] = a2


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
