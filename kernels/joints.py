"""Scalar constraint rows, point loads and torques, with exact derivatives.

Every joint of ``morphlab`` is a set of scalar rows ``Phi_i = g_i(q) - c_i(t) = 0`` of two kinds:

* kind 0 / 1: the x / y component of ``r_P - r_Q``, with ``r = R + A (u0 + w)`` for a material
  point of a body (``w`` the nodal displacement of a beam node, zero for a rigid body point);
* kind 2: the angle ``(theta_P + phi_P) - (theta_Q + phi_Q)`` (``phi`` the nodal rotation).

A side (P or Q) is described by the global DOFs ``(R_x, R_y, theta, u, v, phi)`` of its point
(``-1`` where absent; all ``-1`` for the ground) and its body-frame position ``u0``. Revolute =
two rows of kinds 0 and 1; weld = kinds 0, 1, 2; a ground fix any subset; a driving constraint
a kind-2 row with a time-dependent ``c``.

The acceleration-level right-hand side with Baumgarte-type stabilization (part of the residual,
so it is differentiated with it) is::

    F_c = -q'^T H q' + c'' - b1 (J q' - c') - b0 (g - c),        H = d²g/dq²

and the rows of the residual are ``s (w_cm J a - w_cf F_c)`` (scaled by ``s``); the multipliers
add ``w_l J^T lambda`` to the equations of motion (paper eq. 25–26 use ``w_l = w_m``).
"""

import numpy as np
from numba import njit


@njit(cache=True)
def _side(kind, dofs, u0, q, v, a, grad, Hv, Ha, dvHv):
    """Value, gradient and second-order terms of one side of a row (sign not applied).

    Outputs (6,) arrays on the side's local DOFs; returns ``(g, vHv)``.
    """
    dt = grad.dtype
    zero = dt.type(0.0)
    th = zero
    vth = zero
    ath = zero
    wx = zero
    wy = zero
    vwx = zero
    vwy = zero
    awx = zero
    awy = zero
    Rk = zero
    phi = zero
    for i in range(6):
        grad[i] = 0.0
        Hv[i] = 0.0
        Ha[i] = 0.0
        dvHv[i] = 0.0
    if dofs[2] >= 0:
        th = q[dofs[2]]
        vth = v[dofs[2]]
        ath = a[dofs[2]]
    if dofs[3] >= 0:
        wx = q[dofs[3]]
        vwx = v[dofs[3]]
        awx = a[dofs[3]]
    if dofs[4] >= 0:
        wy = q[dofs[4]]
        vwy = v[dofs[4]]
        awy = a[dofs[4]]
    if dofs[5] >= 0:
        phi = q[dofs[5]]
    if kind == 2:
        grad[2] = 1.0
        grad[5] = 1.0
        return th + phi, zero
    if dofs[kind] >= 0:
        Rk = q[dofs[kind]]
    c = np.cos(th)
    s = np.sin(th)
    ux = u0[0] + wx
    uy = u0[1] + wy
    Au = (c * ux - s * uy, s * ux + c * uy)
    AIu = (-Au[1], Au[0])
    # A = [[c, -s], [s, c]], AĨ = [[-s, -c], [c, -s]]
    if kind == 0:
        A0 = c
        A1 = -s
        AI0 = -s
        AI1 = -c
    else:
        A0 = s
        A1 = c
        AI0 = c
        AI1 = -s
    g = Rk + Au[kind]
    grad[kind] = 1.0
    grad[2] = AIu[kind]
    grad[3] = A0
    grad[4] = A1
    # H: (th, th) = -(A u)_k ; (th, w_j) = (w_j, th) = (AĨ)_kj
    Hv[2] = -Au[kind] * vth + AI0 * vwx + AI1 * vwy
    Hv[3] = AI0 * vth
    Hv[4] = AI1 * vth
    Ha[2] = -Au[kind] * ath + AI0 * awx + AI1 * awy
    Ha[3] = AI0 * ath
    Ha[4] = AI1 * ath
    vHv = -Au[kind] * vth * vth + 2.0 * vth * (AI0 * vwx + AI1 * vwy)
    # d(v^T H v)/dq: th -> -(AĨu)_k vth² - 2 vth (A v_w)_k ; w_j -> -A_kj vth²
    dvHv[2] = -AIu[kind] * vth * vth - 2.0 * vth * (A0 * vwx + A1 * vwy)
    dvHv[3] = -A0 * vth * vth
    dvHv[4] = -A1 * vth * vth
    return g, vHv


@njit(cache=True)
def _side_hessian(kind, dofs, u0, q, H):
    """``H = d²g/dq²`` of one side on its 6 local DOFs (zero for angle rows)."""
    for i in range(6):
        for j in range(6):
            H[i, j] = 0.0
    if kind == 2:
        return
    th = 0.0 * H[0, 0]
    wx = 0.0 * H[0, 0]
    wy = 0.0 * H[0, 0]
    if dofs[2] >= 0:
        th = q[dofs[2]]
    if dofs[3] >= 0:
        wx = q[dofs[3]]
    if dofs[4] >= 0:
        wy = q[dofs[4]]
    c = np.cos(th)
    s = np.sin(th)
    ux = u0[0] + wx
    uy = u0[1] + wy
    if kind == 0:
        Auk = c * ux - s * uy
        AI0 = -s
        AI1 = -c
    else:
        Auk = s * ux + c * uy
        AI0 = c
        AI1 = -s
    H[2, 2] = -Auk
    H[2, 3] = AI0
    H[3, 2] = AI0
    H[2, 4] = AI1
    H[4, 2] = AI1


@njit(cache=True)
def constraint_residual(
    q, v, a, lam, wl, wcm, wcf, scale, b0, b1, c, cd, cdd, con_kind, con_dofs, con_u0, n_dof, R
):
    """Add ``wl J^T lam`` to the equation rows and ``scale (wcm J a - wcf F_c)`` to the
    constraint rows ``R[n_dof + i]``.

    Parameters
    ----------
    lam : (n_con,)
        Physical Lagrange multipliers.
    c, cd, cdd : (n_con,)
        Target value of each row and its first and second time derivatives at this time.
    con_kind : (n_con,) int64; con_dofs : (n_con, 2, 6) int64; con_u0 : (n_con, 2, 2)
        Row description (module docstring).
    """
    dt = R.dtype
    grad = np.zeros(6, dtype=dt)
    Hv = np.zeros(6, dtype=dt)
    Ha = np.zeros(6, dtype=dt)
    dvHv = np.zeros(6, dtype=dt)
    for i in range(con_kind.shape[0]):
        kind = con_kind[i]
        g = dt.type(0.0)
        Ja = dt.type(0.0)
        Jv = dt.type(0.0)
        vHv = dt.type(0.0)
        for side in range(2):
            dofs = con_dofs[i, side]
            sg = 1.0 if side == 0 else -1.0
            if dofs[0] < 0 and dofs[2] < 0:
                continue
            gs, vHvs = _side(kind, dofs, con_u0[i, side], q, v, a, grad, Hv, Ha, dvHv)
            g += sg * gs
            vHv += sg * vHvs
            for j in range(6):
                d = dofs[j]
                if d >= 0:
                    Ja += sg * grad[j] * a[d]
                    Jv += sg * grad[j] * v[d]
                    R[d] += wl * sg * grad[j] * lam[i]
        Fc = -vHv + cdd[i] - b1 * (Jv - cd[i]) - b0 * (g - c[i])
        R[n_dof + i] += scale * (wcm * Ja - wcf * Fc)


@njit(cache=True)
def constraint_jacobian(
    q, v, a, lam, cl, ccm, ccf, bh2, gh, scale, b0, b1, con_kind, con_dofs, con_u0,
    map_row, map_col, map_H, data,
):
    """Add the constraint terms of ``d(residual)/d(a, lambda_scaled)`` to the CSC ``data``.

    ``map_row[i, side, j]``: position of (constraint row i, DOF j); ``map_col[i, side, j]``:
    position of (DOF j, multiplier column i); ``map_H[i, side, j, k]``: position of
    (DOF j, DOF k) of the same side. ``-1`` marks an absent entry.
    """
    dt = data.dtype
    grad = np.zeros(6, dtype=dt)
    Hv = np.zeros(6, dtype=dt)
    Ha = np.zeros(6, dtype=dt)
    dvHv = np.zeros(6, dtype=dt)
    H = np.zeros((6, 6), dtype=dt)
    for i in range(con_kind.shape[0]):
        kind = con_kind[i]
        for side in range(2):
            dofs = con_dofs[i, side]
            sg = 1.0 if side == 0 else -1.0
            if dofs[0] < 0 and dofs[2] < 0:
                continue
            _side(kind, dofs, con_u0[i, side], q, v, a, grad, Hv, Ha, dvHv)
            for j in range(6):
                if dofs[j] < 0:
                    continue
                # constraint row: d/da of wcm J a - wcf F_c
                dFc_dq = -sg * dvHv[j] - b1 * sg * Hv[j] - b0 * sg * grad[j]
                dFc_dv = -2.0 * sg * Hv[j] - b1 * sg * grad[j]
                val = ccm * (sg * grad[j] + bh2 * sg * Ha[j]) - ccf * (bh2 * dFc_dq + gh * dFc_dv)
                p = map_row[i, side, j]
                if p >= 0:
                    data[p] += scale * val
                p = map_col[i, side, j]
                if p >= 0:
                    data[p] += cl * scale * sg * grad[j]
            if kind != 2:
                _side_hessian(kind, dofs, con_u0[i, side], q, H)
                for j in range(6):
                    for k in range(6):
                        p = map_H[i, side, j, k]
                        if p >= 0:
                            data[p] += cl * bh2 * sg * lam[i] * H[j, k]


@njit(cache=True)
def constraint_values(q, v, c, cd, con_kind, con_dofs, con_u0, phi, phid):
    """Position- and velocity-level violation of every row: ``phi = g - c``,
    ``phid = J q' - c'`` (each (n_con,), out)."""
    dt = q.dtype
    grad = np.zeros(6, dtype=dt)
    Hv = np.zeros(6, dtype=dt)
    Ha = np.zeros(6, dtype=dt)
    dvHv = np.zeros(6, dtype=dt)
    for i in range(con_kind.shape[0]):
        g = dt.type(0.0)
        Jv = dt.type(0.0)
        for side in range(2):
            dofs = con_dofs[i, side]
            sg = 1.0 if side == 0 else -1.0
            if dofs[0] < 0 and dofs[2] < 0:
                continue
            gs, _ = _side(con_kind[i], dofs, con_u0[i, side], q, v, v, grad, Hv, Ha, dvHv)
            g += sg * gs
            for j in range(6):
                if dofs[j] >= 0:
                    Jv += sg * grad[j] * v[dofs[j]]
        phi[i] = g - c[i]
        phid[i] = Jv - cd[i]


@njit(cache=True)
def constraint_jacobian_matrix(q, con_kind, con_dofs, con_u0, n_dof, Jc):
    """Dense constraint Jacobian ``Jc`` (n_con, n_dof), out; for checks and rank tests."""
    dt = Jc.dtype
    grad = np.zeros(6, dtype=dt)
    Hv = np.zeros(6, dtype=dt)
    Ha = np.zeros(6, dtype=dt)
    dvHv = np.zeros(6, dtype=dt)
    Jc[:, :] = 0.0
    for i in range(con_kind.shape[0]):
        for side in range(2):
            dofs = con_dofs[i, side]
            sg = 1.0 if side == 0 else -1.0
            if dofs[0] < 0 and dofs[2] < 0:
                continue
            _side(con_kind[i], dofs, con_u0[i, side], q, q, q, grad, Hv, Ha, dvHv)
            for j in range(6):
                if dofs[j] >= 0:
                    Jc[i, dofs[j]] += sg * grad[j]


@njit(cache=True)
def load_residual(q, wf, F, load_dofs, load_u0, T, torque_dofs, R):
    """Subtract ``wf Q_ext`` of point forces and torques from the equation rows of ``R``.

    Parameters
    ----------
    F : (n_load, 2)
        Global force vector of each point load at this time [force].
    load_dofs : (n_load, 6) int64; load_u0 : (n_load, 2)
        Point of application (same description as a constraint side).
    T : (n_torque,)
        Torque values at this time [force·length].
    torque_dofs : (n_torque, 2) int64
        DOF of the body angle and of the nodal rotation (``-1`` if absent) the torque acts on.
    """
    dt = R.dtype
    grad = np.zeros(6, dtype=dt)
    Hv = np.zeros(6, dtype=dt)
    Ha = np.zeros(6, dtype=dt)
    dvHv = np.zeros(6, dtype=dt)
    for i in range(load_dofs.shape[0]):
        dofs = load_dofs[i]
        for k in range(2):
            _side(k, dofs, load_u0[i], q, q, q, grad, Hv, Ha, dvHv)
            for j in range(6):
                if dofs[j] >= 0:
                    R[dofs[j]] -= wf * grad[j] * F[i, k]
    for i in range(torque_dofs.shape[0]):
        for j in range(2):
            d = torque_dofs[i, j]
            if d >= 0:
                R[d] -= wf * T[i]


@njit(cache=True)
def load_jacobian(q, cf, bh2, F, load_dofs, load_u0, load_map, data):
    """Add ``-cf bh2 d(Q_ext)/dq`` of point forces to ``data`` (``load_map`` (n_load, 6, 6))."""
    H = np.zeros((6, 6), dtype=data.dtype)
    for i in range(load_dofs.shape[0]):
        dofs = load_dofs[i]
        for k in range(2):
            _side_hessian(k, dofs, load_u0[i], q, H)
            for j in range(6):
                for m in range(6):
                    p = load_map[i, j, m]
                    if p >= 0:
                        data[p] -= cf * bh2 * F[i, k] * H[j, m]


@njit(cache=True)
def constraint_violation_history(Q, V, C, CD, con_kind, con_dofs, con_u0, viol, vviol):
    """``max |Phi|`` and ``max |Phi'|`` at every stored time in one call.

    ``Q, V`` (n_t, n_dof); ``C, CD`` (n_t, n_con) constraint targets; ``viol, vviol`` (n_t,),
    out (magnitudes of the real parts: a diagnostic, not differentiated)."""
    n_con = con_kind.shape[0]
    phi = np.zeros(n_con, dtype=Q.dtype)
    phid = np.zeros(n_con, dtype=Q.dtype)
    for k in range(Q.shape[0]):
        constraint_values(Q[k], V[k], C[k], CD[k], con_kind, con_dofs, con_u0, phi, phid)
        m0 = 0.0
        m1 = 0.0
        for i in range(n_con):
            a = phi[i].real
            b = phid[i].real
            if a < 0:
                a = -a
            if b < 0:
                b = -b
            if a > m0:
                m0 = a
            if b > m1:
                m1 = b
        viol[k] = m0
        vviol[k] = m1
