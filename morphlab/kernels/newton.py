"""The Newton loop of one time step in one compiled call, on either kind of step-matrix factor.

:class:`morphlab.solve.newton.NewtonSolver` iterates from Python (residual, matrix,
factorization, solve, correction); once the factorization of a run has settled
(:class:`morphlab.solve.linalg.StepFactorization`: the dense LU of a small matrix, or the
compiled sparse refactorization with a row order SuperLU chose), the compiled time loop
(:mod:`morphlab.kernels.steps`) solves each step here, with the same kernels in the same order
and the same arithmetic: bitwise the same iterates.

A factor is a :class:`Factors` of one of two kinds:

* dense (``LU`` (n, n), ``piv`` (n,)): :mod:`morphlab.kernels.dense`; the sparse fields are
  None;
* sparse: the values ``Lx, Ux, Ud`` of :func:`morphlab.kernels.sparse_lu.refactor`, with the
  arrays of the row order it reads, ``order = (gather, pair, b_indices, b_indptr, perm_r,
  work)``, and the patterns its solve reads, ``pattern = (Lp, Li, Up, Ui, row_from,
  row_scale, col_to, col_scale)``; ``LU`` and ``piv`` are None.

The kind is told by which fields are None, tests Numba decides when it compiles (a branch
``if x is None`` on an argument ``x`` typed None is dropped, and so is the branch of ``x is
not None``): a model whose step matrices are sparse never compiles the dense LU, and the
other way round. The tests are on arguments (Numba does not decide them on attributes), so
the helpers below take the fields one by one.
"""

from typing import NamedTuple

import numpy as np

from ._jit import inlined, inner
from .assemble import apply_correction, level, matrix, residual
from .dense import csc_to_dense, lu_factor, lu_solve, lu_solve_transposed
from .sparse_lu import refactor
from .sparse_lu import solve as sparse_solve
from .sparse_lu import solve_transposed as sparse_solve_transposed

# Status codes of :func:`newton_loop`
CONVERGED, NONFINITE_RESIDUAL, SINGULAR, NONFINITE_CORRECTION, NOT_CONVERGED, PIVOT_REFUSED = (
    0, 1, 2, 3, 4, 5)


class Factors(NamedTuple):
    """The arrays of one factorization of the step matrix (module docstring)."""

    LU: np.ndarray
    piv: np.ndarray
    Lx: np.ndarray
    Ux: np.ndarray
    Ud: np.ndarray
    order: tuple
    pattern: tuple


class Csc(NamedTuple):
    """The fixed CSC pattern of the step matrix: ``indices`` (nnz,), ``indptr`` (n + 1,)."""

    indices: np.ndarray
    indptr: np.ndarray


class Options(NamedTuple):
    """Newton's options: converged when the position correction ``bh2 |dz_a|_max / length``
    is at most ``tol`` (``linear``: the initial solve, converged after one iteration), at most
    ``max_iter`` iterations, then ``polish`` more; ``tau``: the sparse refactorization's pivot
    threshold."""

    tol: float
    max_iter: int
    length: float
    polish: int
    linear: bool
    tau: float


class Work(NamedTuple):
    """Buffers of :func:`newton_loop`: the residual ``R`` (n,), the step matrix's CSC values
    ``data`` (m, nnz) (row 0 the Newton matrix; rows 1, 2 ``Dq``, ``Dv`` when the step's
    ``C`` asks for them), the bodies' scratch ``W``, the iteration history ``hist``
    (max_iter, 2) of ``(|R|, correction)``."""

    R: np.ndarray
    data: np.ndarray
    W: tuple
    hist: np.ndarray


@inner
def factor_matrix(data, csc, F, tau):
    """Factor the step matrix with CSC values ``data`` over ``csc``: densely into ``F.LU,
    F.piv`` if ``F.order`` is None, else by the sparse refactorization into ``F.Lx, F.Ux,
    F.Ud`` (pivots tested against the threshold ``tau``). Returns -1, or the first column
    whose pivot is exactly zero (dense) or fails the threshold (sparse: the row order no
    longer serves)."""
    return _factor(data, csc, F.LU, F.piv, F.Lx, F.Ux, F.Ud, F.order, F.pattern, tau)


@inner
def _factor(data, csc, LU, piv, Lx, Ux, Ud, order, pattern, tau):
    if order is None:  # dense: the other branch dropped
        if LU is not None:  # dropped in a sparse run (LU None), where this branch stays
            csc_to_dense(data, csc.indices, csc.indptr, LU)
            return lu_factor(LU, piv)
        return -1
    else:
        gather, pair, b_indices, b_indptr, perm_r, work = order
        Lp, Li, Up, Ui = pattern[0], pattern[1], pattern[2], pattern[3]
        return refactor(data, gather, pair, b_indices, b_indptr, perm_r, Lp, Li, Up, Ui, Lx,
                        Ux, Ud, work, tau)


@inner
def solve_factored(b, work, F):
    """Solve in place for ``b`` (n, m) with the factors ``F`` (``work``: (n, m) scratch, read
    by the sparse solve only)."""
    _solve(b, work, F.LU, F.piv, F.Lx, F.Ux, F.Ud, F.pattern, None)


@inner
def solve_factored_transposed(b, work, F):
    """:func:`solve_factored` for the transposed matrix (the adjoint sweep)."""
    _solve(b, work, F.LU, F.piv, F.Lx, F.Ux, F.Ud, F.pattern, np.bool_(True))


@inner
def _solve(b, work, LU, piv, Lx, Ux, Ud, pattern, transposed):
    # ``transposed`` None: the plain solve only is compiled (a primal run never compiles the
    # transposed one; the adjoint, which passes True, compiles both)
    if pattern is None:
        if LU is not None:
            if transposed is None:
                lu_solve(LU, piv, b)
            else:
                lu_solve_transposed(LU, piv, b)
    else:
        Lp, Li, Up, Ui, row_from, row_scale, col_to, col_scale = pattern
        if transposed is None:
            sparse_solve(Lp, Li, Lx, Up, Ui, Ux, Ud, row_from, row_scale, col_to, col_scale,
                         b, b, work)
        else:
            sparse_solve_transposed(Lp, Li, Lx, Up, Ui, Ux, Ud, row_from, row_scale, col_to,
                                    col_scale, b, b, work)


@inlined
def newton_loop(M, T, P, s, z, csc, F, opt, ws, full_from):
    """Full Newton–Raphson on the step ``s`` (:class:`~morphlab.kernels.assemble.Step`) from
    ``z``, in one call: iterations of the residual ``R_hist + E(z)``
    (:func:`~morphlab.kernels.assemble.residual`, parts ``P``: all of them) into ``ws.R``, the
    matrix (:func:`~morphlab.kernels.assemble.matrix`, the combinations ``s.C``) into
    ``ws.data``,
    its factorization (:func:`factor_matrix`) into ``F``, ``dz = -J^{-1} R`` and
    :func:`~morphlab.kernels.assemble.apply_correction` until the position correction is at
    most ``opt.tol`` of ``opt.length``, then ``opt.polish`` more. The kernels, in the order,
    of the step-by-step loop of ``morphlab.solve.newton`` (which raises the errors): the same
    arithmetic, bitwise the same iterates.

    Returns ``(z, iterations, status, bad)``: ``iterations`` up to convergence (the polish ones
    not counted), ``ws.hist[k] = (|R|, correction)`` of iteration ``k + 1``; ``F`` and
    ``ws.data`` hold the last factorization and matrix (at the iterate before the last
    correction). ``full_from``: the first iteration whose fill forms every row of ``s.C``; the
    ones before form the Newton matrix alone (``Dq``, ``Dv`` are read from the last fill only,
    and the caller guesses which iteration that is). A step that converges before
    ``full_from`` fills every row once more at its last matrix's iterate: the same matrix
    and the same ``Dq``, ``Dv`` as a fill of every row at every iteration. Status: 0
    converged; 1 non-finite residual (``ws.R`` holds it, ``z`` the
    iterate; no matrix formed); 2 a dense matrix is exactly singular (``bad`` the column
    without a nonzero pivot); 3 non-finite correction (``z`` the corrected iterate); 4 no
    convergence in ``max_iter`` iterations; 5 a sparse pivot failed the threshold (``bad`` its
    column, ``z`` the iterate whose matrix it was: the caller lets SuperLU choose a new row
    order and goes on from there).

    Inlined into :func:`~morphlab.kernels.steps.run_steps`, its one caller: compiled as a
    kernel of its own, its closure (every item kind's residual and matrix) was emitted once
    more (``_jit``'s docstring)."""
    n = ws.R.shape[0]
    n_dof = s.qh.shape[0]
    dz1 = np.empty(n, dtype=ws.R.dtype)  # contiguous: apply_correction as called from Python
    dz = dz1.reshape((n, 1))
    work = np.empty_like(dz)
    data = ws.data
    C1, data1 = s.C[:1], data[:1]  # the fill of the Newton matrix alone
    done = 0  # the iteration that met the tolerance
    it = 0
    while True:
        it += 1
        k = it if done == 0 else done
        x = level(z, s)
        R = ws.R
        for i in range(n):
            R[i] = s.R_hist[i]
        residual(M, x, s.w, T, s.t, s.k, P, n_dof, R, ws.W)
        ssq = 0.0
        for i in range(n):
            ssq += R[i].real * R[i].real + R[i].imag * R[i].imag
        if done == 0:
            ws.hist[it - 1, 0] = np.sqrt(ssq)
        if not np.isfinite(ssq):
            return z, k, NONFINITE_RESIDUAL, -1
        full = it >= full_from  # this fill forms every row of C
        matrix(M, x, s.w, T, s.t, s.k, s.C if full else C1, data if full else data1, ws.W)
        bad = factor_matrix(data[0], csc, F, opt.tau)
        if bad >= 0:
            return z, k, SINGULAR if F.order is None else PIVOT_REFUSED, bad
        for r in range(n):
            dz[r, 0] = -ws.R[r]
        solve_factored(dz, work, F)
        z1, dz_max, finite = apply_correction(z, dz1, n_dof)
        if not finite:
            return z1, k, NONFINITE_CORRECTION, -1
        z = z1
        if done == 0:
            err = 0.0 if opt.linear else s.bh2 * dz_max / opt.length
            ws.hist[it - 1, 1] = err
            if err <= opt.tol:
                done = it
            elif it == opt.max_iter:
                return z, it, NOT_CONVERGED, -1
        if done > 0 and it - done >= opt.polish:
            if not full and data.shape[0] > 1:  # Dq, Dv of the last matrix's iterate
                matrix(M, x, s.w, T, s.t, s.k, s.C, data, ws.W)
            return z, done, CONVERGED, -1
