"""Dense LU with partial pivoting for small Newton matrices.

For matrices of a few dozen unknowns a sparse factorization's set-up costs more than the
whole elimination; up to ``Settings.dense_max`` unknowns the step matrix is scattered into a
dense array and factored here. Row-pivoted
Gaussian elimination (``P A = L U``, the pivot the entry of largest magnitude in its column:
Golub & Van Loan, Matrix Computations, 4th ed., alg. 3.4.1), float64 or complex128.
"""

from ._jit import kernel


@kernel
def csc_to_dense(data, indices, indptr, out):
    """Scatter the CSC matrix ``(data, indices, indptr)`` into the square array ``out``."""
    out[:, :] = 0.0
    for j in range(indptr.shape[0] - 1):
        for p in range(indptr[j], indptr[j + 1]):
            out[indices[p], j] = data[p]


@kernel
def lu_factor(A, piv):
    """Factor ``A`` (n, n) in place into unit-lower ``L`` and upper ``U`` with row
    interchanges ``piv`` (``piv[k]``: the row swapped with row ``k`` at step ``k``).
    Returns the first column whose pivot is exactly zero, or -1."""
    n = A.shape[0]
    for k in range(n):
        p = k
        big = abs(A[k, k])
        for i in range(k + 1, n):
            m = abs(A[i, k])
            if m > big:
                big = m
                p = i
        piv[k] = p
        if big == 0.0:
            return k
        if p != k:
            for j in range(n):
                t = A[k, j]
                A[k, j] = A[p, j]
                A[p, j] = t
        inv = 1.0 / A[k, k]
        for i in range(k + 1, n):
            A[i, k] *= inv
        for i in range(k + 1, n):
            lik = A[i, k]
            if lik != 0.0:
                for j in range(k + 1, n):
                    A[i, j] -= lik * A[k, j]
    return -1


@kernel
def lu_solve(LU, piv, b):
    """Solve ``A x = b`` for ``b`` (n, m) in place with the factors of :func:`lu_factor`."""
    n = LU.shape[0]
    m = b.shape[1]
    for k in range(n):
        p = piv[k]
        if p != k:
            for c in range(m):
                t = b[k, c]
                b[k, c] = b[p, c]
                b[p, c] = t
    for i in range(n):
        for k in range(i):
            lik = LU[i, k]
            if lik != 0.0:
                for c in range(m):
                    b[i, c] -= lik * b[k, c]
    for i in range(n - 1, -1, -1):
        for k in range(i + 1, n):
            uik = LU[i, k]
            if uik != 0.0:
                for c in range(m):
                    b[i, c] -= uik * b[k, c]
        inv = 1.0 / LU[i, i]
        for c in range(m):
            b[i, c] *= inv


@kernel
def lu_solve_transposed(LU, piv, b):
    """Solve ``A^T x = b`` for ``b`` (n, m) in place with the factors of :func:`lu_factor`:
    ``A = P^T L U``, so ``U^T y = b``, ``L^T w = y`` and ``x = P^T w`` (the row interchanges
    undone in reverse order)."""
    n = LU.shape[0]
    m = b.shape[1]
    for i in range(n):
        for k in range(i):
            uki = LU[k, i]
            if uki != 0.0:
                for c in range(m):
                    b[i, c] -= uki * b[k, c]
        inv = 1.0 / LU[i, i]
        for c in range(m):
            b[i, c] *= inv
    for i in range(n - 1, -1, -1):
        for k in range(i + 1, n):
            lki = LU[k, i]
            if lki != 0.0:
                for c in range(m):
                    b[i, c] -= lki * b[k, c]
    for k in range(n - 1, -1, -1):
        p = piv[k]
        if p != k:
            for c in range(m):
                t = b[k, c]
                b[k, c] = b[p, c]
                b[p, c] = t
