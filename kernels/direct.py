"""Direct-differentiation kernels: the work of one sensitivity step in three compiled calls.

After the primal has converged a step (``morphlab.sensitivity``):

1. :func:`pseudo_loads` — the right-hand sides ``-D_i R`` of every design variable ``i``: the
   step residual at the converged unknowns ``z``, with the state at ``t_n`` perturbed along its
   sensitivity and the system arrays replaced by variable ``i``'s (complex step or forward
   difference), through the primal's own :func:`~morphlab.kernels.assemble.add_residual`;
2. (SuperLU solve in Python, with the primal's last factorization;
   :func:`csc_residual` for iterative refinement against the exact converged matrix);
3. :func:`update_sensitivities` — the Newmark update of the sensitivity histories.

The step coefficients travel as two small arrays: ``pc = (h, cqa, cqg, cva, cvg, bh2, gh)``
and ``upd = (ga, gan, ggn)`` (``morphlab.integrator.StepCoefficients``), so that::

    q_{n+1} = q_n + h v_n + cqa a_n + cqg g_n + bh2 a_{n+1}
    v_{n+1} = v_n + cva a_n + cvg g_n + gh a_{n+1}
    g_{n+1} = ga a_{n+1} + gan a_n + ggn g_n

the same linear update the primal applies (``morphlab.integrator.newmark_predict`` /
``newmark_update``), here on sensitivity columns.
"""

import numpy as np
from numba import njit

from .assemble import add_residual

# positions in ``S`` of the floating-point arrays that a design variable can change; a
# sensitivity run stacks them over the design variables (leading axis n_x)
PERTURBED = (0, 2, 3, 6, 7, 8, 11, 12, 13, 16, 18)


@njit(cache=True)
def _perturbed_tuple(S, P, i):
    return (P[0][i], S[1], P[1][i], P[2][i], S[4], S[5], P[3][i], P[4][i], P[5][i], S[9],
            S[10], P[6][i], P[7][i], P[8][i], S[14], S[15], P[9][i], S[17], P[10][i], S[19],
            S[20], S[21], S[22], S[23], S[24], S[25], S[26])


@njit(cache=True)
def _step_residual(S, q, v, a, g, lam, dq, dv, da, dg, dlam, i, e, pc, has_old, w_old, w_new,
                   z, scale, b0, b1, ta_old, ta_new, n_dof, R):
    """Overwrite ``R`` with the step residual at the converged unknowns ``z`` when the state at
    ``t_n`` is ``s_n + e ds_n[:, i]`` (``e`` in the dtype of ``R``) and the arrays are ``S``."""
    n_con = R.shape[0] - n_dof
    dt = R.dtype
    h, cqa, cqg, cva, cvg, bh2, gh = pc[0], pc[1], pc[2], pc[3], pc[4], pc[5], pc[6]
    qp = np.empty(n_dof, dtype=dt)
    vp = np.empty(n_dof, dtype=dt)
    ap = np.empty(n_dof, dtype=dt)
    gp = np.empty(n_dof, dtype=dt)
    lp = np.empty(n_con, dtype=dt)
    for k in range(n_dof):
        qp[k] = q[k] + e * dq[k, i]
        vp[k] = v[k] + e * dv[k, i]
        ap[k] = a[k] + e * da[k, i]
        gp[k] = g[k] + e * dg[k, i]
    for k in range(n_con):
        lp[k] = lam[k] + e * dlam[k, i]
    R[:] = 0.0
    if has_old:
        add_residual(S, qp, vp, ap, lp, w_old[0], w_old[1], w_old[2], w_old[3], w_old[4],
                     scale, b0, b1, ta_old[0], ta_old[1], ta_old[2], ta_old[3], ta_old[4],
                     n_dof, R)
    q1 = np.empty(n_dof, dtype=dt)
    v1 = np.empty(n_dof, dtype=dt)
    a1 = np.empty(n_dof, dtype=dt)
    l1 = np.empty(n_con, dtype=dt)
    for k in range(n_dof):
        a1[k] = z[k]
        q1[k] = qp[k] + h * vp[k] + cqa * ap[k] + cqg * gp[k] + bh2 * z[k]
        v1[k] = vp[k] + cva * ap[k] + cvg * gp[k] + gh * z[k]
    for k in range(n_con):
        l1[k] = z[n_dof + k] * scale
    add_residual(S, q1, v1, a1, l1, w_new[0], w_new[1], w_new[2], w_new[3], w_new[4], scale,
                 b0, b1, ta_new[0], ta_new[1], ta_new[2], ta_new[3], ta_new[4], n_dof, R)


@njit(cache=True)
def pseudo_loads(S, P, q, v, a, g, lam, DQ, DV, DA, DG, DLAM, k, pert, pc, has_old, w_old,
                 w_new, z, scale, b0, b1, TA_old, TA_new, ta_old, ta_new, n_dof, work, rhs):
    """Right-hand sides ``rhs[:, i] = -D_i R`` of every design variable in one call.

    ``D_i R = Re[(R_i - R_0) / pert_i]`` with ``R_i`` the step residual for design ``i`` (state
    ``s_n + pert_i ds_n[:, i]``, arrays ``P[.][i]``) and ``R_0`` the nominal one: with a
    complex step ``pert_i = i h`` this is ``Im R_i / h`` (``R_0`` is not needed and not
    evaluated), with real steps the forward difference of the paper's semi-analytical method.

    Parameters
    ----------
    S : tuple
        Nominal system arrays (``morphlab.solver.kernel_arrays``, the dtype of ``work``).
    P : tuple
        The arrays of ``S`` at positions :data:`PERTURBED`, stacked over the n_x designs.
    q, v, a, g, lam : (n_dof,), (n_con,) float64
        State at ``t_n`` (``g``: algorithmic acceleration).
    DQ, DV, DA, DG : (n_t, n_dof, n_x); DLAM : (n_t, n_con, n_x) float64
        Sensitivity histories; entry ``k`` (the step's old level) is read.
    pert : (n_x,)
        ``1e-30j`` (complex step) or the finite-difference steps (dtype of ``work``).
    pc : (7,)
        ``(h, cqa, cqg, cva, cvg, bh2, gh)``; all zero for the initial solve.
    has_old : bool
        Whether the residual has an old-level share (the paper's weighting).
    w_old, w_new : (5,)
        Weights ``(wm, wl, wf, wcm, wcf)`` of the old and new time level.
    z : (n,) float64
        Converged unknowns ``(a_{n+1}, lam_{n+1}/scale)``.
    TA_old, TA_new : tuples ``(C, CD, CDD, F, T)`` with a leading n_x axis
        Time arrays of each design at ``t_n`` and ``t_{n+1}``.
    ta_old, ta_new : tuples ``(C, CD, CDD, F, T)``
        The nominal time arrays (used for ``R_0`` of real steps only).
    work : (n_x + 1, n)
        Scratch rows for the residuals (dtype of ``pert``).
    rhs : (n, n_x) float64
        Written.
    """
    n_x = rhs.shape[1]
    n = rhs.shape[0]
    dq = DQ[k]
    dv = DV[k]
    da = DA[k]
    dg = DG[k]
    dlam = DLAM[k]
    zero = pert[0] * 0.0
    R0 = work[n_x]
    R0[:] = 0.0
    if zero.imag == 0.0 and pert[0].imag == 0.0:
        _step_residual(S, q, v, a, g, lam, dq, dv, da, dg, dlam, 0, zero, pc, has_old, w_old,
                       w_new, z, scale, b0, b1, ta_old, ta_new, n_dof, R0)
    for i in range(n_x):
        Si = _perturbed_tuple(S, P, i)
        tai_old = (TA_old[0][i], TA_old[1][i], TA_old[2][i], TA_old[3][i], TA_old[4][i])
        tai_new = (TA_new[0][i], TA_new[1][i], TA_new[2][i], TA_new[3][i], TA_new[4][i])
        R = work[i]
        _step_residual(Si, q, v, a, g, lam, dq, dv, da, dg, dlam, i, pert[i], pc, has_old,
                       w_old, w_new, z, scale, b0, b1, tai_old, tai_new, n_dof, R)
        for r in range(n):
            rhs[r, i] = -((R[r] - R0[r]) / pert[i]).real


@njit(cache=True)
def update_sensitivities(DQ, DV, DA, DG, DLAM, n, x, scale, n_dof, pc, upd):
    """Store the step's solution ``x = (da, dlam/scale)`` (n, n_x) as entry ``n`` of the
    histories and advance ``dq, dv, dg`` by the Newmark update from entry ``n - 1``
    (``n == 0``: the initial solve, which sets ``da, dg, dlam`` only)."""
    n_x = x.shape[1]
    n_con = DLAM.shape[1]
    if n == 0:
        for r in range(n_dof):
            for i in range(n_x):
                DA[0, r, i] = x[r, i]
                DG[0, r, i] = x[r, i]
        for r in range(n_con):
            for i in range(n_x):
                DLAM[0, r, i] = x[n_dof + r, i] * scale
        return
    h, cqa, cqg, cva, cvg, bh2, gh = pc[0], pc[1], pc[2], pc[3], pc[4], pc[5], pc[6]
    ga, gan, ggn = upd[0], upd[1], upd[2]
    m = n - 1
    for r in range(n_dof):
        for i in range(n_x):
            da = x[r, i]
            a0 = DA[m, r, i]
            g0 = DG[m, r, i]
            DQ[n, r, i] = (DQ[m, r, i] + h * DV[m, r, i] + cqa * a0 + cqg * g0 + bh2 * da)
            DV[n, r, i] = DV[m, r, i] + cva * a0 + cvg * g0 + gh * da
            DG[n, r, i] = ga * da + gan * a0 + ggn * g0
            DA[n, r, i] = da
    for r in range(n_con):
        for i in range(n_x):
            DLAM[n, r, i] = x[n_dof + r, i] * scale


@njit(cache=True)
def csc_residual(data, indices, indptr, x, b, r):
    """``r = b - A x`` for the CSC matrix ``A = (data, indices, indptr)`` and ``x`` (n, n_x);
    returns ``(|r|_F, |b|_F)``."""
    n = indptr.shape[0] - 1
    n_x = x.shape[1]
    for j in range(n):
        for i in range(n_x):
            r[j, i] = b[j, i]
    for j in range(n):
        for p in range(indptr[j], indptr[j + 1]):
            row = indices[p]
            aij = data[p]
            for i in range(n_x):
                r[row, i] -= aij * x[j, i]
    rr = 0.0
    bb = 0.0
    for j in range(n):
        for i in range(n_x):
            rr += r[j, i] * r[j, i]
            bb += b[j, i] * b[j, i]
    return np.sqrt(rr), np.sqrt(bb)
