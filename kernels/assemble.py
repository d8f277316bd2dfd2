"""Whole-system residual and Newton matrix: one compiled call each.

The system arrays travel as one tuple ``S`` (built once per compiled model by
``morphlab.solver.kernel_arrays``), so a Newton iteration costs one call for the residual and one
for the matrix, whatever the number of bodies, elements and joints. The matrix is written into
the ``data`` array of a CSC matrix whose pattern was fixed at compile time; every contribution
has a precomputed position (``-1``: skipped).

``S`` = (gravity, body_ref, body_scal, body_damp, flex_off, flex_dof, flex_IS, flex_I0S,
flex_I0IS, elem_body, elem_fdof, elem_M, elem_St, elem_K, con_kind, con_dofs, con_u0,
load_dofs, load_u0, torque_dofs, border_off, border_map, elem_map, con_map_row, con_map_col,
con_map_H, load_map)
"""

import numpy as np
from numba import njit

from .ffrf import body_jacobian, body_residual
from .joints import constraint_jacobian, constraint_residual, load_jacobian, load_residual


@njit(cache=True)
def add_residual(S, q, v, a, lam, wm, wl, wf, wcm, wcf, scale, b0, b1, c, cd, cdd, F, T, n_dof, R):
    """Add one state's weighted share of the residual to ``R`` (n_dof + n_con).

    Equation rows: ``wm M a + wl J^T lam + wf (K q + D q' - Q_v - Q_g - Q_ext)``;
    constraint rows: ``scale (wcm J a - wcf F_c)`` (paper eq. 25–26 for one time level).
    """
    body_residual(q, v, a, wm, wf, S[0], S[1], S[2], S[3], S[4], S[5], S[6], S[7], S[8],
                  S[10], S[11], S[12], S[13], R)
    constraint_residual(q, v, a, lam, wl, wcm, wcf, scale, b0, b1, c, cd, cdd,
                        S[14], S[15], S[16], n_dof, R)
    load_residual(q, wf, F, S[17], S[18], T, S[19], R)


@njit(cache=True)
def fill_matrix(S, q, v, a, lam, cm, cl, cf, ccm, ccf, bh2, gh, scale, b0, b1, F, data):
    """Overwrite ``data`` with ``d(residual)/d(a, lambda/scale)`` at the given state.

    ``q = q_pred + bh2 a`` and ``q' = qd_pred + gh a``; ``cm, cl, cf`` weight the inertia,
    multiplier and force terms, ``ccm, ccf`` the constraint rows (paper eq. 30–33, every
    derivative term).
    """
    data[:] = 0.0
    body_jacobian(q, v, a, cm, cf, bh2, gh, S[0], S[1], S[2], S[3], S[4], S[5], S[6], S[7],
                  S[8], S[9], S[10], S[11], S[12], S[13], S[20], S[21], S[22], data)
    constraint_jacobian(q, v, a, lam, cl, ccm, ccf, bh2, gh, scale, b0, b1, S[14], S[15], S[16],
                        S[23], S[24], S[25], data)
    load_jacobian(q, cf, bh2, F, S[17], S[18], S[26], data)


# positions in ``S`` of the floating-point arrays that a design variable can change; a
# sensitivity run stacks them over the design variables (leading axis n_x)
PERTURBED = (0, 2, 3, 6, 7, 8, 11, 12, 13, 16, 18)


@njit(cache=True)
def _perturbed_tuple(S, P, i):
    return (P[0][i], S[1], P[1][i], P[2][i], S[4], S[5], P[3][i], P[4][i], P[5][i], S[9],
            S[10], P[6][i], P[7][i], P[8][i], S[14], S[15], P[9][i], S[17], P[10][i], S[19],
            S[20], S[21], S[22], S[23], S[24], S[25], S[26])


@njit(cache=True)
def pseudo_residuals(S, P, q, v, a, g, lam, dq, dv, da, dg, dlam, pert, pc, has_old, w_old,
                     w_new, z, scale, b0, b1, TA_old, TA_new, n_dof, out):
    """Step residuals of every perturbed design in one call (sensitivity pseudo-loads).

    For design variable ``i``, the state at ``t_n`` is ``s_n + pert[i] ds_n[:, i]`` and the
    system arrays are ``P[k][i]``; the residual of the step is evaluated at the converged
    unknowns ``z`` exactly as :func:`add_residual` does for the primal (same kernels).

    Parameters
    ----------
    S : tuple
        Nominal system arrays (integer tables are shared).
    P : tuple
        The arrays of ``S`` at positions :data:`PERTURBED`, stacked over the n_x designs.
    q, v, a, g, lam : (n_dof,), (n_con,)
        State at ``t_n`` (``g``: algorithmic acceleration).
    dq, dv, da, dg, dlam : (n_dof, n_x), (n_con, n_x)
        Its sensitivities.
    pert : (n_x,)
        Perturbation size: ``1e-30j`` (complex step) or the finite-difference steps.
    pc : (7,)
        ``(h, cqa, cqg, cva, cvg, bh2, gh)`` of the Newmark update (all 0 for the initial
        solve), see ``morphlab.solver.StepCoefficients``.
    has_old : bool
        Whether the residual has an old-level share (the paper's weighting).
    w_old, w_new : (5,) arrays
        Weights ``(wm, wl, wf, wcm, wcf)`` of the old and new time level.
    z : (n,)
        Converged unknowns ``(a_{n+1}, lam_{n+1}/scale)``.
    TA_old, TA_new : tuples ``(C, CD, CDD, F, T)`` with a leading n_x axis
        Time arrays of each perturbed design at ``t_n`` and ``t_{n+1}``.
    out : (n_x, n)
        Residuals (written).
    """
    n_x = out.shape[0]
    n = out.shape[1]
    n_con = n - n_dof
    dt = out.dtype
    h, cqa, cqg, cva, cvg, bh2, gh = pc[0], pc[1], pc[2], pc[3], pc[4], pc[5], pc[6]
    for i in range(n_x):
        Si = _perturbed_tuple(S, P, i)
        e = pert[i]
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
        R = out[i]
        R[:] = 0.0
        if has_old:
            add_residual(Si, qp, vp, ap, lp, w_old[0], w_old[1], w_old[2], w_old[3], w_old[4],
                         scale, b0, b1, TA_old[0][i], TA_old[1][i], TA_old[2][i], TA_old[3][i],
                         TA_old[4][i], n_dof, R)
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
        add_residual(Si, q1, v1, a1, l1, w_new[0], w_new[1], w_new[2], w_new[3], w_new[4],
                     scale, b0, b1, TA_new[0][i], TA_new[1][i], TA_new[2][i], TA_new[3][i],
                     TA_new[4][i], n_dof, R)
