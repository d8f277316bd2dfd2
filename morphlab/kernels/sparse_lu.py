"""Sparse LU refactorization with a fixed pivot sequence (static pivoting).

The step matrices of a run share one CSC pattern and change little from one Newton iteration
or time step to the next. SuperLU chooses a row order (threshold partial pivoting) for one of
them; with that order fixed, the pattern of the factors is fixed too, and every later matrix is
factored numerically into the same ``L`` and ``U`` arrays without any search or allocation.
This is the "refactor" of KLU (Davis & Palamadai Natarajan, ACM TOMS 37(3), 2010), here
without its rank-revealing extras: each pivot is tested against the same threshold rule
SuperLU used to choose it, and a pivot that fails it is reported, so the caller lets SuperLU
choose a new order.

Conventions. ``B`` (n, n) is the matrix in CSC form ``(data, indices, indptr)`` with sorted
row indices. ``perm_r[i]`` is the row of the factored matrix ``C = P_r B`` that holds row ``i``
of ``B`` (SciPy's ``SuperLU.perm_r``). ``C = L U`` with ``L`` unit lower triangular, stored
without its diagonal in CSC ``(Lp, Li, Lx)``, and ``U`` upper triangular, stored as its strict
upper part in CSC ``(Up, Ui, Ux)`` and its diagonal ``Ud``. Row indices are sorted in every
column. The numeric kernels run for float64 and complex128 alike; the caller may scale the
matrix (``D B D``, :func:`refactor`'s ``scale``) and undo the scaling in the solve.

Algorithm: left-looking column LU (Gilbert & Peierls, SIAM J. Sci. Stat. Comput. 9(5), 1988)
on a dense work column. The symbolic pass finds the pattern of column ``j`` of ``L + U`` as the
rows reachable from the pattern of ``C[:, j]`` in the graph of the columns of ``L`` left of
``j`` (depth-first search). With the pattern known, the numeric pass applies the updates of
column ``j`` in increasing row order, which is a valid order for a lower-triangular solve.
"""

import numpy as np

from ._jit import inner, kernel

#: Transposed solves of at most this many right-hand sides sum in registers, two at a time
#: (:func:`solve_transposed`); measured on factors of 7e4 and 4e6 entries, the register sums
#: take a quarter to half the time of the sums in memory for one or two right-hand sides,
#: half to as long for three or four, up to 1.5 times as long for five (a pass over the
#: factors per pair).
REGISTER_RHS = 4


@kernel
def symbolic(n, indices, indptr, perm_r):
    """Patterns of the factors of ``C = P_r B`` for the CSC pattern ``(indices, indptr)`` of
    ``B`` (n, n) and the row order ``perm_r`` (n,). Returns ``(Lp, Li, Up, Ui)``: column
    pointers (n + 1,) and sorted row indices of strict ``L`` and strict ``U``."""
    mark = np.full(n, -1, np.int64)
    stack = np.empty(n, np.int64)
    next_child = np.empty(n, np.int64)
    found = np.empty(n, np.int64)
    Lp = np.zeros(n + 1, np.int64)
    Up = np.zeros(n + 1, np.int64)
    cap = max(2 * indices.size, 16)
    Li = np.empty(cap, np.int64)
    Ui = np.empty(cap, np.int64)
    nl = 0
    nu = 0
    for j in range(n):
        nf = 0
        for p in range(indptr[j], indptr[j + 1]):
            start = perm_r[indices[p]]
            if mark[start] == j:
                continue
            mark[start] = j
            found[nf] = start
            nf += 1
            top = 0
            stack[0] = start
            next_child[0] = Lp[start] if start < j else 0
            while top >= 0:  # depth-first over the columns of L left of j
                k = stack[top]
                if k < j and next_child[top] < Lp[k + 1]:
                    i = Li[next_child[top]]
                    next_child[top] += 1
                    if mark[i] != j:
                        mark[i] = j
                        found[nf] = i
                        nf += 1
                        top += 1
                        stack[top] = i
                        next_child[top] = Lp[i] if i < j else 0
                else:
                    top -= 1
        for t in range(1, nf):  # insertion sort: a column's rows are few
            x = found[t]
            u = t - 1
            while u >= 0 and found[u] > x:
                found[u + 1] = found[u]
                u -= 1
            found[u + 1] = x
        for t in range(nf):
            i = found[t]
            if i < j:
                if nu == Ui.size:
                    Ui = np.concatenate((Ui, np.empty(Ui.size, np.int64)))
                Ui[nu] = i
                nu += 1
            elif i > j:
                if nl == Li.size:
                    Li = np.concatenate((Li, np.empty(Li.size, np.int64)))
                Li[nl] = i
                nl += 1
        Lp[j + 1] = nl
        Up[j + 1] = nu
    return Lp, Li[:nl].copy(), Up, Ui[:nu].copy()


@kernel
def refactor(data, gather, scale, indices, indptr, perm_r, Lp, Li, Up, Ui, Lx, Ux, Ud, work,
             tau):
    """Numeric LU of ``C = P_r B`` into ``Lx``, ``Ux`` (the sizes of ``Li``, ``Ui``) and ``Ud``
    (n,) with the patterns of :func:`symbolic`; the values of ``B`` are
    ``data[gather] * scale`` (nnz,): read from the caller's matrix in its own order, scaled as
    the caller chose, without a copy. ``work`` (n,) must be zero on entry and
    is zero on return. A pivot is accepted if it is nonzero and at least ``tau`` times the largest
    entry below it in its column (SuperLU's threshold rule; ``tau = 0`` accepts any nonzero
    pivot). Returns -1, or the first column whose pivot fails (the factors are then
    incomplete)."""
    n = Lp.shape[0] - 1
    for j in range(n):
        for p in range(indptr[j], indptr[j + 1]):
            work[perm_r[indices[p]]] = data[gather[p]] * scale[p]
        for p in range(Up[j], Up[j + 1]):  # increasing k: x[k] is final when it is reached
            k = Ui[p]
            xk = work[k]
            work[k] = 0.0
            Ux[p] = xk
            if xk != 0.0:
                for t in range(Lp[k], Lp[k + 1]):
                    work[Li[t]] -= Lx[t] * xk
        pivot = work[j]
        work[j] = 0.0
        big = 0.0
        for p in range(Lp[j], Lp[j + 1]):
            a = abs(work[Li[p]])
            if a > big:
                big = a
        if pivot == 0.0 or abs(pivot) < tau * big:
            for p in range(Lp[j], Lp[j + 1]):
                work[Li[p]] = 0.0
            return j
        Ud[j] = pivot
        inv = 1.0 / pivot
        for p in range(Lp[j], Lp[j + 1]):
            i = Li[p]
            Lx[p] = work[i] * inv
            work[i] = 0.0
    return -1


@kernel
def solve(Lp, Li, Lx, Up, Ui, Ux, Ud, row_from, row_scale, col_to, col_scale, b, x, work):
    """Solve with the factors of :func:`refactor` for ``b`` (n, m) into ``x`` (n, m), through
    the scratch ``work`` (n, m): ``work[k] = row_scale[k] b[row_from[k]]``, ``L U y = work``,
    ``x[col_to[k]] = col_scale[k] y[k]`` (the row and column orders and scalings of the
    factored matrix)."""
    n = Lp.shape[0] - 1
    m = b.shape[1]
    for k in range(n):
        for s in range(m):
            work[k, s] = b[row_from[k], s] * row_scale[k]
    for j in range(n):
        for p in range(Lp[j], Lp[j + 1]):
            i = Li[p]
            lij = Lx[p]
            for s in range(m):
                work[i, s] -= lij * work[j, s]
    for j in range(n - 1, -1, -1):
        inv = 1.0 / Ud[j]
        for s in range(m):
            work[j, s] *= inv
        for p in range(Up[j], Up[j + 1]):
            i = Ui[p]
            uij = Ux[p]
            for s in range(m):
                work[i, s] -= uij * work[j, s]
    for k in range(n):
        for s in range(m):
            x[col_to[k], s] = work[k, s] * col_scale[k]


@kernel
def solve_transposed(Lp, Li, Lx, Up, Ui, Ux, Ud, row_from, row_scale, col_to, col_scale, b, x,
                     work):
    """Solve the transposed system ``A^T x = b`` with the factors of :func:`refactor`, ``b``
    (n, m) into ``x`` (n, m) through the scratch ``work`` (n, m). :func:`solve` applies
    ``A^-1 = C (L U)^-1 R`` (``R``: rows picked by ``row_from`` and scaled, ``C``: scaled and
    scattered to ``col_to``), so ``A^-T = R^T U^-T L^-T C^T``.

    A column of ``U`` (``L``) is a row of ``U^T`` (``L^T``): the transposed solves gather an
    inner product per unknown, where :func:`solve` scatters. Summed in ``work`` itself, each
    term waits for the store of the one before, unless several right-hand sides interleave
    their sums: up to :data:`REGISTER_RHS` right-hand sides (an adjoint's responses) are solved
    two at a time with the sums in registers (:func:`_solve_pair`), more in one pass over the
    factors with the sums in ``work``. Either way each sum adds its terms in the same order."""
    n = Lp.shape[0] - 1
    m = b.shape[1]
    for k in range(n):
        for s in range(m):
            work[k, s] = b[col_to[k], s] * col_scale[k]
    if m <= REGISTER_RHS:
        for s in range(0, m, 2):
            _solve_pair(Lp, Li, Lx, Up, Ui, Ux, Ud, work, s, s + 1 < m)
    else:
        for j in range(n):  # U^T y = work: forward, column j of U is row j of U^T
            for p in range(Up[j], Up[j + 1]):
                i = Ui[p]
                uij = Ux[p]
                for s in range(m):
                    work[j, s] -= uij * work[i, s]
            inv = 1.0 / Ud[j]
            for s in range(m):
                work[j, s] *= inv
        for j in range(n - 1, -1, -1):  # L^T z = y: backward, unit diagonal
            for p in range(Lp[j], Lp[j + 1]):
                i = Li[p]
                lij = Lx[p]
                for s in range(m):
                    work[j, s] -= lij * work[i, s]
    for k in range(n):
        for s in range(m):
            x[row_from[k], s] = work[k, s] * row_scale[k]


@inner
def _solve_pair(Lp, Li, Lx, Up, Ui, Ux, Ud, work, s0, two):
    """``U^T y = work``, then ``L^T z = y`` in place for the columns ``s0`` and (``two``)
    ``s0 + 1`` of ``work``: each unknown's two sums in registers, in the order of the stored
    entries (:func:`solve_transposed` says why). Without ``two`` the second sum repeats the
    first's column and is not stored."""
    n = Lp.shape[0] - 1
    s1 = s0 + 1 if two else s0
    for j in range(n):  # U^T y = work: forward, column j of U is row j of U^T
        a0 = work[j, s0]
        a1 = work[j, s1]
        for p in range(Up[j], Up[j + 1]):
            i = Ui[p]
            u = Ux[p]
            a0 -= u * work[i, s0]
            a1 -= u * work[i, s1]
        inv = 1.0 / Ud[j]
        work[j, s0] = a0 * inv
        if two:
            work[j, s1] = a1 * inv
    for j in range(n - 1, -1, -1):  # L^T z = y: backward, unit diagonal
        a0 = work[j, s0]
        a1 = work[j, s1]
        for p in range(Lp[j], Lp[j + 1]):
            i = Li[p]
            lij = Lx[p]
            a0 -= lij * work[i, s0]
            a1 -= lij * work[i, s1]
        work[j, s0] = a0
        if two:
            work[j, s1] = a1
