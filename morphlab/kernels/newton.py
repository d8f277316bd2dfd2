"""The Newton loop of one time step in one compiled call, on either kind of step-matrix factor.

:func:`morphlab.solve.newton.newton` iterates from Python with five calls per iteration
(residual, matrix, factorization, solve, correction) until the factorization of a run has
settled (:class:`morphlab.solve.linalg.StepFactorization`: the dense LU of a small matrix, or
the compiled sparse refactorization with a row order SuperLU chose); from then on the same
kernels, in the same order and with the same arithmetic, run here in one call: bitwise the
same iterates.

A factor is one of two kinds:

* dense (``LU`` (n, n), ``piv`` (n,)): :mod:`morphlab.kernels.dense`; ``order`` and
  ``pattern`` are None;
* sparse: the values ``Lx, Ux, Ud`` of :func:`morphlab.kernels.sparse_lu.refactor`, with the
  arrays of the row order it reads, ``order = (gather, pair, b_indices, b_indptr, perm_r,
  work)``, and the patterns its solve reads, ``pattern = (Lp, Li, Up, Ui, row_from,
  row_scale, col_to, col_scale)``; ``LU`` and ``piv`` are empty.

The kind is told by ``order is None`` / ``pattern is None``, a test Numba decides when it
compiles: a model whose step matrices are sparse never compiles the dense LU, and the other
way round. The sensitivity recursion (:mod:`morphlab.kernels.direct`) solves with
:func:`solve_factored` as well.
"""

import numpy as np
from numba import njit

from .assemble import apply_correction, step_matrix, step_residual
from .dense import csc_to_dense, lu_factor, lu_solve, lu_solve_transposed
from .sparse_lu import refactor
from .sparse_lu import solve as sparse_solve
from .sparse_lu import solve_transposed as sparse_solve_transposed

# Status codes of :func:`newton_loop`
CONVERGED, NONFINITE_RESIDUAL, SINGULAR, NONFINITE_CORRECTION, NOT_CONVERGED, PIVOT_REFUSED = (
    0, 1, 2, 3, 4, 5)


@njit(cache=True)
def factor_matrix(data, indices, indptr, LU, piv, Lx, Ux, Ud, order, pattern, tau):
    """Factor the step matrix with CSC values ``data`` over ``(indices, indptr)``: densely into
    ``LU, piv`` if ``order`` is None, else by the sparse refactorization into ``Lx, Ux, Ud``
    (pivots tested against the threshold ``tau``). Returns -1, or the first column whose pivot
    is exactly zero (dense) or fails the threshold (sparse: the row order no longer serves)."""
    if order is None:
        csc_to_dense(data, indices, indptr, LU)
        return lu_factor(LU, piv)
    gather, pair, b_indices, b_indptr, perm_r, work = order
    Lp, Li, Up, Ui = pattern[0], pattern[1], pattern[2], pattern[3]
    return refactor(data, gather, pair, b_indices, b_indptr, perm_r, Lp, Li, Up, Ui, Lx, Ux, Ud,
                    work, tau)


@njit(cache=True)
def solve_factored(b, work, LU, piv, Lx, Ux, Ud, pattern):
    """Solve in place for ``b`` (n, m) with the factors of :func:`factor_matrix` (``work``: (n, m)
    scratch, read by the sparse solve only; ``pattern`` None: the dense factor)."""
    if pattern is None:
        lu_solve(LU, piv, b)
    else:
        Lp, Li, Up, Ui, row_from, row_scale, col_to, col_scale = pattern
        sparse_solve(Lp, Li, Lx, Up, Ui, Ux, Ud, row_from, row_scale, col_to, col_scale, b, b,
                     work)


@njit(cache=True)
def solve_factored_transposed(b, work, LU, piv, Lx, Ux, Ud, pattern):
    """:func:`solve_factored` for the transposed matrix (the adjoint sweep)."""
    if pattern is None:
        lu_solve_transposed(LU, piv, b)
    else:
        Lp, Li, Up, Ui, row_from, row_scale, col_to, col_scale = pattern
        sparse_solve_transposed(Lp, Li, Lx, Up, Ui, Ux, Ud, row_from, row_scale, col_to,
                                col_scale, b, b, work)


@njit(cache=True, nogil=True)
def newton_loop(S, z, qh, vh, bh2, gh, scale, w, b0, b1, c, cd, cdd, F, T, n_dof, R_hist,
                indices, indptr, linear, length, tol, max_iter, polish, R, data, LU, piv, Lx,
                Ux, Ud, order, pattern, tau, hist):
    """Full Newton–Raphson on a step, in one call: iterations of the residual
    (:func:`morphlab.kernels.assemble.step_residual`) into ``R``, the matrix
    (:func:`~morphlab.kernels.assemble.step_matrix`) into ``data`` (the CSC values), its
    factorization (:func:`factor_matrix`), ``dz = -J^{-1} R`` and
    :func:`~morphlab.kernels.assemble.apply_correction` until the position correction
    ``bh2 |dz_a|_max / length`` is at most ``tol`` (``linear``: the initial solve, converged
    after one iteration), then ``polish`` more (complex-step reference runs). The kernels, in
    the order, of the step-by-step loop of ``morphlab.solve.newton.newton`` (which raises
    the errors): the same arithmetic, bitwise the same iterates.

    Returns ``(z, iterations, status, bad)``: ``iterations`` up to convergence (the polish ones
    not counted), ``hist[k] = (|R|, correction)`` of iteration ``k + 1``; the factor arrays hold
    the last factorization (at the iterate before the last correction). Status: 0 converged; 1
    non-finite residual (``R`` holds it, ``z`` the iterate; no matrix formed); 2 a dense
    matrix is exactly singular (``R`` the residual, ``bad`` the column without a nonzero pivot;
    no solve); 3 non-finite correction (``z`` the corrected iterate); 4 no convergence in
    ``max_iter`` iterations; 5 a sparse pivot failed the threshold (``bad`` its column, ``z``
    the iterate whose matrix it was: the caller lets SuperLU choose a new row order and goes on
    from there; with ``polish`` this can happen after convergence, so the caller takes the
    sparse kind here only without it). ``max_iter = 1`` with ``tol = inf`` is one iteration.

    (One function, not a loop around an iteration kernel: each compiled caller re-optimizes the
    residual and matrix kernels it links, which lengthens every cold start.)"""
    n = R.shape[0]
    dz1 = np.empty(n, dtype=R.dtype)  # contiguous: apply_correction as called from Python
    dz = dz1.reshape((n, 1))
    work = np.empty_like(dz)
    done = 0  # the iteration that met the tolerance
    it = 0
    while True:
        it += 1
        k = it if done == 0 else done
        ssq = step_residual(S, z, qh, vh, bh2, gh, scale, w, b0, b1, c, cd, cdd, F, T, n_dof,
                            R_hist, R)
        if done == 0:
            hist[it - 1, 0] = np.sqrt(ssq)
        if not np.isfinite(ssq):
            return z, k, NONFINITE_RESIDUAL, -1
        step_matrix(S, z, qh, vh, bh2, gh, scale, w, b0, b1, F, data)
        bad = factor_matrix(data, indices, indptr, LU, piv, Lx, Ux, Ud, order, pattern, tau)
        if bad >= 0:
            return z, k, SINGULAR if order is None else PIVOT_REFUSED, bad
        for r in range(n):
            dz[r, 0] = -R[r]
        solve_factored(dz, work, LU, piv, Lx, Ux, Ud, pattern)
        z1, dz_max, finite = apply_correction(z, dz1, n_dof)
        if not finite:
            return z1, k, NONFINITE_CORRECTION, -1
        z = z1
        if done == 0:
            err = 0.0 if linear else bh2 * dz_max / length
            hist[it - 1, 1] = err
            if err <= tol:
                done = it
            elif it == max_iter:
                return z, it, NOT_CONVERGED, -1
        if done > 0 and it - done >= polish:
            return z, done, CONVERGED, -1
