"""Scalar constraint rows with exact derivatives (the point loads, which share their point
kinematics, are in :mod:`morphlab.kernels.loads`).

Every joint of ``morphlab`` is a set of scalar rows ``Phi_i = g_i(q) - c_i(t) = 0`` of two kinds:

* :data:`ROW_X` / :data:`ROW_Y` (0 / 1): the x / y component of ``r_P - r_Q``, with
  ``r = R + A (u0 + w)`` for a material point of a body (``w`` the nodal displacement of a beam
  node, zero for a rigid body point);
* :data:`ROW_ANGLE` (2): the angle ``(theta_P + phi_P) - (theta_Q + phi_Q)`` (``phi`` the nodal
  rotation);
* :data:`ROW_SLIDE` (3): the distance of P from a line through Q fixed in Q's body,
  ``n(psi) . (r_P - r_Q)`` with ``n = (cos psi, sin psi)`` and ``psi = theta_Q + phi_Q + beta``
  (``beta`` the normal's angle in Q's frame): the row of a prismatic joint that keeps P on the
  guide. Unlike the other kinds it couples both sides (its Hessian has P-Q blocks). Its code
  is compiled only for models with extra items: the kernels take the switch
  ``S.extra_items`` (``True``, or ``None``) as the argument ``extra``, and Numba drops a
  branch ``if extra is not None`` for an argument typed ``None`` (``kernels.system``).

A side (P or Q) is described by the global DOFs ``(R_x, R_y, theta, u, v, phi)`` of its point
(``-1`` where absent; all ``-1`` for the ground), its body-frame position ``u0[0:2]`` and an
angle ``u0[2]`` in the body frame (``beta`` of a slide row's Q; unused otherwise). Revolute =
an x and a y row; weld = x, y and angle rows; a ground fix any subset; a driving constraint
a kind-2 row with a time-dependent ``c``; prismatic = a slide row and an angle row.

The acceleration-level right-hand side with Baumgarte-type stabilization (part of the residual,
so it is differentiated with it) is::

    F_c = -q'^T H q' + c'' - b1 (J q' - c') - b0 (g - c),        H = d²g/dq²

and the rows of the residual are ``s (w_cm J a - w_cf F_c)`` (scaled by ``s``); the multipliers
add ``w_l J^T lambda`` to the equations of motion (paper eq. 25–26 use ``w_l = w_m``).
"""

import numpy as np
from numba import njit

#: Kinds of constraint rows (``con_kind``): the x and y components of ``r_P - r_Q``, the
#: angle ``(theta_P + phi_P) - (theta_Q + phi_Q)`` and the slide row (module docstring).
ROW_X, ROW_Y, ROW_ANGLE, ROW_SLIDE = 0, 1, 2, 3


@njit(cache=True, inline="always")
def _dofs(table, i, side):
    """The six DOFs of side ``side`` of row ``i`` as a tuple (``-1`` where absent)."""
    return (table[i, side, 0], table[i, side, 1], table[i, side, 2], table[i, side, 3],
            table[i, side, 4], table[i, side, 5])


@njit(cache=True, inline="always")
def _side(kind, dofs, ux0, uy0, q, v, a):
    """Value, gradient and second-order terms of one side of a row (sign not applied).

    ``dofs``: the side's six DOFs (tuple, ``-1`` where absent); ``(ux0, uy0)``: the point in the
    body frame. Returns ``(g, vHv, grad, Hv, Ha, dvHv)``, the last four as 6-tuples on the
    local DOFs: ``grad = dg/dq``, ``Hv = H q'``, ``Ha = H q''`` and ``dvHv = d(q'^T H q')/dq``.
    (Values, not output arrays: scratch arrays passed into a helper add reference counting
    and keep Numba from optimizing the caller's loop, which dominates the residual's cost.)
    """
    # one scalar type for every returned value: that of the state and the point together (a
    # sensitivity pseudo-load evaluates complex points at a real state)
    zero = q[0] * 0.0 + ux0 * 0.0
    one = zero + 1.0
    th = q[dofs[2]] if dofs[2] >= 0 else zero
    vth = v[dofs[2]] if dofs[2] >= 0 else zero
    ath = a[dofs[2]] if dofs[2] >= 0 else zero
    if kind == ROW_ANGLE:
        phi = q[dofs[5]] if dofs[5] >= 0 else zero
        z6 = (zero, zero, zero, zero, zero, zero)
        return th + phi + zero, zero, (zero, zero, one, zero, zero, one), z6, z6, z6
    wx = q[dofs[3]] if dofs[3] >= 0 else zero
    vwx = v[dofs[3]] if dofs[3] >= 0 else zero
    awx = a[dofs[3]] if dofs[3] >= 0 else zero
    wy = q[dofs[4]] if dofs[4] >= 0 else zero
    vwy = v[dofs[4]] if dofs[4] >= 0 else zero
    awy = a[dofs[4]] if dofs[4] >= 0 else zero
    Rk = q[dofs[kind]] if dofs[kind] >= 0 else zero
    c = np.cos(th) + zero
    s = np.sin(th) + zero
    ux = ux0 + wx
    uy = uy0 + wy
    # A = [[c, -s], [s, c]], AĨ = [[-s, -c], [c, -s]]; row kind of A u, AĨ u, A and AĨ
    if kind == ROW_X:
        Auk = c * ux - s * uy
        AIuk = -(s * ux + c * uy)
        A0 = c
        A1 = -s
        AI0 = -s
        AI1 = -c
        grad = (one, zero, AIuk, A0, A1, zero)
    else:
        Auk = s * ux + c * uy
        AIuk = c * ux - s * uy
        A0 = s
        A1 = c
        AI0 = c
        AI1 = -s
        grad = (zero, one, AIuk, A0, A1, zero)
    g = Rk + Auk
    # H: (th, th) = -(A u)_k ; (th, w_j) = (w_j, th) = (AĨ)_kj
    Hv = (zero, zero, -Auk * vth + AI0 * vwx + AI1 * vwy, AI0 * vth, AI1 * vth, zero)
    Ha = (zero, zero, -Auk * ath + AI0 * awx + AI1 * awy, AI0 * ath, AI1 * ath, zero)
    vHv = -Auk * vth * vth + 2.0 * vth * (AI0 * vwx + AI1 * vwy)
    # d(v^T H v)/dq: th -> -(AĨu)_k vth² - 2 vth (A v_w)_k ; w_j -> -A_kj vth²
    dvHv = (zero, zero, -AIuk * vth * vth - 2.0 * vth * (A0 * vwx + A1 * vwy),
            -A0 * vth * vth, -A1 * vth * vth, zero)
    return g, vHv, grad, Hv, Ha, dvHv


@njit(cache=True, inline="always")
def _side_hessian(kind, dofs, ux0, uy0, q):
    """The nonzero entries ``(H_thth, H_th,wx, H_th,wy)`` of ``H = d²g/dq²`` of one side
    (symmetric; all zero for angle rows)."""
    zero = q[0] * 0.0 + ux0 * 0.0  # the scalar type of state and point (see _side)
    if kind == ROW_ANGLE:
        return zero, zero, zero
    th = q[dofs[2]] if dofs[2] >= 0 else zero
    wx = q[dofs[3]] if dofs[3] >= 0 else zero
    wy = q[dofs[4]] if dofs[4] >= 0 else zero
    c = np.cos(th) + zero
    s = np.sin(th) + zero
    ux = ux0 + wx
    uy = uy0 + wy
    if kind == ROW_X:
        return -(c * ux - s * uy), -s, -c
    return -(s * ux + c * uy), c, -s


@njit(cache=True, inline="always")
def _add_hessian(kind, dofs, ux0, uy0, q, coef, hmap, i, side, data):
    """Add ``coef H`` of one side to ``data`` at the positions ``hmap[i, side, side, j, k]``."""
    h22, h23, h24 = _side_hessian(kind, dofs, ux0, uy0, q)
    for (j, k, h) in ((2, 2, h22), (2, 3, h23), (3, 2, h23), (2, 4, h24), (4, 2, h24)):
        p = hmap[i, side, side, j, k]
        if p >= 0:
            data[p] += coef * h


@njit(cache=True, inline="always")
def _lin(x, p, y, r):
    """The 6-tuple ``x p + y r`` (``p``, ``r`` 6-tuples)."""
    return (x * p[0] + y * r[0], x * p[1] + y * r[1], x * p[2] + y * r[2], x * p[3] + y * r[3],
            x * p[4] + y * r[4], x * p[5] + y * r[5])


@njit(cache=True, inline="always")
def _psi(dofs, w, zero):
    """``w[theta] + w[phi]`` of a side (zero where absent)."""
    out = zero
    if dofs[2] >= 0:
        out += w[dofs[2]]
    if dofs[5] >= 0:
        out += w[dofs[5]]
    return out


@njit(cache=True, inline="always")
def _dot(grad, dofs, w, zero):
    out = zero
    for j in range(6):
        if dofs[j] >= 0:
            out += grad[j] * w[dofs[j]]
    return out


@njit(cache=True)
def _point_of(dofs, ux0, uy0, q, v, a):
    """:func:`_side` of the x and the y component of one material point, as a called
    function: the slide row's helpers need both components of both sides, and inlining every
    call (or calling with the kind as a compile-time constant, which Numba specializes on)
    multiplied the constraint kernels' compile time."""
    return (_side(ROW_X, dofs, ux0, uy0, q, v, a), _side(ROW_Y, dofs, ux0, uy0, q, v, a))


@njit(cache=True)
def _add_point_hessian(dofs, ux0, uy0, q, cx, cy, hmap, i, side, data):
    """Add ``cx H_x + cy H_y`` of one material point (:func:`_add_hessian` of both
    components) at ``hmap[i, side, side, j, k]``; ``side`` a run-time value (see
    :func:`_point_of`)."""
    _add_hessian(ROW_X, dofs, ux0, uy0, q, cx, hmap, i, side, data)
    _add_hessian(ROW_Y, dofs, ux0, uy0, q, cy, hmap, i, side, data)


@njit(cache=True)
def _slide(dP, dQ, uP, uQ, q, v, a):
    """A slide row ``g = n(psi) . d``, ``d = r_P - r_Q``, ``psi = theta_Q + phi_Q + beta``:
    ``(g, vHv, grad, Hv, Ha, dvHv)`` as :func:`_side` gives them, but each of the last four a
    pair (P side, Q side) of 6-tuples, signs included. ``uP = (x, y, -)``, ``uQ = (x, y, beta)``.

    With ``t = dn/dpsi`` and ``D = dd/dq``: ``grad = n^T D + (t.d) e_psi``;
    ``H = n.H_d + e_psi (t^T D) + (t^T D)^T e_psi^T - (n.d) e_psi e_psi^T``;
    ``v^T H v = n.(v^T H_d v) + 2 psi' t.(D v) - psi'^2 n.d``.
    """
    zero = q[0] * 0.0 + uP[0] * 0.0 + uQ[0] * 0.0
    (gxP, vxP, grxP, HvxP, HaxP, dvxP), (gyP, vyP, gryP, HvyP, HayP, dvyP) = _point_of(
        dP, uP[0], uP[1], q, v, a)
    (gxQ, vxQ, grxQ, HvxQ, HaxQ, dvxQ), (gyQ, vyQ, gryQ, HvyQ, HayQ, dvyQ) = _point_of(
        dQ, uQ[0], uQ[1], q, v, a)
    psi = _psi(dQ, q, zero) + uQ[2]
    pv = _psi(dQ, v, zero)
    pa = _psi(dQ, a, zero)
    nx, ny = np.cos(psi) + zero, np.sin(psi) + zero
    tx, ty = -ny, nx
    dx, dy = gxP - gxQ, gyP - gyQ
    # D v, D a and v^T H_d v of d (components x, y)
    dvx = _dot(grxP, dP, v, zero) - _dot(grxQ, dQ, v, zero)
    dvy = _dot(gryP, dP, v, zero) - _dot(gryQ, dQ, v, zero)
    dax = _dot(grxP, dP, a, zero) - _dot(grxQ, dQ, a, zero)
    day = _dot(gryP, dP, a, zero) - _dot(gryQ, dQ, a, zero)
    hx, hy = vxP - vxQ, vyP - vyQ
    nd, td = nx * dx + ny * dy, tx * dx + ty * dy
    g = nd
    vHv = nx * hx + ny * hy + 2.0 * pv * (tx * dvx + ty * dvy) - pv * pv * nd
    e = (zero, zero, zero + 1.0, zero, zero, zero + 1.0)  # d psi / dq of the Q side
    nP, nQ = _lin(nx, grxP, ny, gryP), _lin(nx, grxQ, ny, gryQ)
    tP, tQ = _lin(tx, grxP, ty, gryP), _lin(tx, grxQ, ty, gryQ)
    gP = nP
    gQ = _lin(-1.0, nQ, td, e)
    HvP = _lin(1.0, _lin(nx, HvxP, ny, HvyP), pv, tP)
    HaP = _lin(1.0, _lin(nx, HaxP, ny, HayP), pa, tP)
    HvQ = _lin(-1.0, _lin(nx, HvxQ, ny, HvyQ), -pv, tQ)
    HvQ = _lin(1.0, HvQ, tx * dvx + ty * dvy - nd * pv, e)
    HaQ = _lin(-1.0, _lin(nx, HaxQ, ny, HayQ), -pa, tQ)
    HaQ = _lin(1.0, HaQ, tx * dax + ty * day - nd * pa, e)
    dvP = _lin(1.0, _lin(nx, dvxP, ny, dvyP), 2.0 * pv, _lin(tx, HvxP, ty, HvyP))
    dvP = _lin(1.0, dvP, -pv * pv, nP)
    dvQ = _lin(-1.0, _lin(nx, dvxQ, ny, dvyQ), -2.0 * pv, _lin(tx, HvxQ, ty, HvyQ))
    dvQ = _lin(1.0, dvQ, pv * pv, nQ)
    dvQ = _lin(1.0, dvQ, tx * hx + ty * hy - 2.0 * pv * (nx * dvx + ny * dvy) - pv * pv * td, e)
    return g, vHv, (gP, gQ), (HvP, HvQ), (HaP, HaQ), (dvP, dvQ)


@njit(cache=True)
def _add_slide_hessian(dP, dQ, uP, uQ, q, coef, hmap, i, data):
    """Add ``coef H`` of a slide row (:func:`_slide`) to ``data`` at ``hmap[i, r, c, j, k]``
    (``r``, ``c``: the sides of row and column; 0 = P, 1 = Q)."""
    zero = q[0] * 0.0 + uP[0] * 0.0 + uQ[0] * 0.0
    psi = _psi(dQ, q, zero) + uQ[2]
    nx, ny = np.cos(psi) + zero, np.sin(psi) + zero
    (gxP, _, grxP, _, _, _), (gyP, _, gryP, _, _, _) = _point_of(dP, uP[0], uP[1], q, q, q)
    (gxQ, _, grxQ, _, _, _), (gyQ, _, gryQ, _, _, _) = _point_of(dQ, uQ[0], uQ[1], q, q, q)
    nd = nx * (gxP - gxQ) + ny * (gyP - gyQ)
    for side in range(2):
        sg = 1.0 if side == 0 else -1.0
        d, u = (dP, uP) if side == 0 else (dQ, uQ)
        _add_point_hessian(d, u[0], u[1], q, sg * coef * nx, sg * coef * ny, hmap, i, side,
                           data)
    tP = _lin(-ny, grxP, nx, gryP)
    tQ = _lin(-ny, grxQ, nx, gryQ)
    for j in (2, 5):
        for m in range(6):
            for (r, c, jj, mm, h) in ((0, 1, m, j, tP[m]), (1, 0, j, m, tP[m]),
                                      (1, 1, j, m, -tQ[m]), (1, 1, m, j, -tQ[m])):
                p = hmap[i, r, c, jj, mm]
                if p >= 0:
                    data[p] += coef * h
        for k in (2, 5):
            p = hmap[i, 1, 1, j, k]
            if p >= 0:
                data[p] -= coef * nd


@njit(cache=True, inline="always")
def _neg(t):
    return (-t[0], -t[1], -t[2], -t[3], -t[4], -t[5])


@njit(cache=True, inline="always")
def _point_side(kind, dofs, u, q, v, a):
    """:func:`_side`, or zeros for the ground (no DOFs; its point sits in ``c``)."""
    if dofs[0] < 0 and dofs[2] < 0:
        zero = q[0] * 0.0 + u[0] * 0.0
        z6 = (zero, zero, zero, zero, zero, zero)
        return zero, zero, z6, z6, z6, z6
    return _side(kind, dofs, u[0], u[1], q, v, a)


@njit(cache=True)
def _row_of(kind, extra, dofs0, dofs1, u0, u1, q, v, a):
    """``(g, vHv, grad, Hv, Ha, dvHv)`` of one row of any kind, signs applied, the last four as
    pairs (side 0, side 1) of 6-tuples (:func:`_side`, :func:`_slide`). ``extra``: the
    switch ``S.extra_items`` (module docstring), an argument of every compiled caller.

    A called function, not inlined, for every kernel that reads rows (residual, Newton matrix,
    violation diagnostics): Numba types an inlined row anew in each kernel, which was the
    largest share of a cold start. The residual, which needs only ``g``, ``vHv`` and ``grad``,
    pays for computing the whole row: about 2 µs of a 28 µs residual of the morphing model,
    against 6 s less compilation (``BENCHMARKS.md``)."""
    if extra is not None:
        if kind == ROW_SLIDE:
            return _slide(dofs0, dofs1, u0, u1, q, v, a)
    g0, vHv0, gr0, Hv0, Ha0, dv0 = _point_side(kind, dofs0, u0, q, v, a)
    g1, vHv1, gr1, Hv1, Ha1, dv1 = _point_side(kind, dofs1, u1, q, v, a)
    return (g0 - g1, vHv0 - vHv1, (gr0, _neg(gr1)), (Hv0, _neg(Hv1)), (Ha0, _neg(Ha1)),
            (dv0, _neg(dv1)))


@njit(cache=True, inline="always")
def _u(con_u0, i, side):
    return (con_u0[i, side, 0], con_u0[i, side, 1], con_u0[i, side, 2])


@njit(cache=True)
def constraint_residual(extra, S, q, v, a, lam, wl, wcm, wcf, scale, b0, b1, c, cd, cdd, rows,
                        n_dof, R):
    """Add ``wl J^T lam`` to the equation rows and ``scale (wcm J a - wcf F_c)`` to the
    constraint rows ``R[n_dof + i]``.

    Parameters
    ----------
    extra : True or None
        ``S.extra_items`` (module docstring).
    lam : (n_con,)
        Physical Lagrange multipliers.
    c, cd, cdd : (n_con,)
        Target value of each row and its first and second time derivatives at this time.
    S : SystemArrays
        The rows are described by ``S.con_kind``, ``S.con_dofs``, ``S.con_u0`` (module
        docstring).
    rows : int64 array
        The rows evaluated (all of them, or those a design variable changes; see
        ``ffrf.body_residual``).
    """
    con_kind, con_dofs, con_u0 = S.con_kind, S.con_dofs, S.con_u0
    zero = R[0] * 0.0
    for i in rows:
        dofs = (_dofs(con_dofs, i, 0), _dofs(con_dofs, i, 1))
        g, vHv, grad, _, _, _ = _row_of(con_kind[i], extra, dofs[0], dofs[1], _u(con_u0, i, 0),
                                        _u(con_u0, i, 1), q, v, a)
        Ja = zero
        Jv = zero
        for side in range(2):
            for j in range(6):
                d = dofs[side][j]
                if d >= 0:
                    Ja += grad[side][j] * a[d]
                    Jv += grad[side][j] * v[d]
                    R[d] += wl * grad[side][j] * lam[i]
        Fc = -vHv + cdd[i] - b1 * (Jv - cd[i]) - b0 * (g - c[i])
        R[n_dof + i] += scale * (wcm * Ja - wcf * Fc)


@njit(cache=True)
def constraint_jacobian(extra, S, q, v, a, lam, cl, ccm, ccf, C, scale, b0, b1, out):
    """Add the constraint terms of ``d(residual)/d(a, lambda_scaled)`` to the CSC data arrays
    ``out`` (m, nnz) (``extra``: ``S.extra_items``, module docstring): the terms are
    ``D0 + bh2 Dq + gh Dv``, output ``r`` receives ``C[r][0] D0 + C[r][1] Dq + C[r][2] Dv``
    (``C``: m triples; ``kernels.ffrf.body_jacobian``).

    ``S.con_map_row[i, side, j]``: position of (constraint row i, DOF j);
    ``S.con_map_col[i, side, j]``: position of (DOF j, multiplier column i);
    ``S.con_map_H[i, r, c, j, k]``: position of (DOF j of side r, DOF k of side c) (only
    ``r == c`` for the rows of one side's points). ``-1`` marks an absent entry.
    """
    con_kind, con_dofs, con_u0 = S.con_kind, S.con_dofs, S.con_u0
    map_row, map_col, map_H = S.con_map_row, S.con_map_col, S.con_map_H
    for i in range(con_kind.shape[0]):
        kind = con_kind[i]
        dofs = (_dofs(con_dofs, i, 0), _dofs(con_dofs, i, 1))
        u = (_u(con_u0, i, 0), _u(con_u0, i, 1))
        _, _, grad, Hv, Ha, dvHv = _row_of(kind, extra, dofs[0], dofs[1], u[0], u[1], q, v, a)
        for side in range(2):
            for j in range(6):
                if dofs[side][j] < 0:
                    continue
                gr = grad[side][j]
                # constraint row: d/da of wcm J a - wcf F_c
                dFc_dq = -dvHv[side][j] - b1 * Hv[side][j] - b0 * gr
                dFc_dv = -2.0 * Hv[side][j] - b1 * gr
                x0 = scale * ccm * gr
                xq = scale * (ccm * Ha[side][j] - ccf * dFc_dq)
                xv = -scale * ccf * dFc_dv
                p = map_row[i, side, j]
                if p >= 0:
                    for r in range(len(C)):
                        out[r, p] += C[r][0] * x0 + C[r][1] * xq + C[r][2] * xv
                p = map_col[i, side, j]
                if p >= 0:
                    for r in range(len(C)):
                        out[r, p] += C[r][0] * cl * scale * gr
        # the Hessian terms bh2 cl lam H belong to Dq alone
        for r in range(len(C)):
            coef = cl * C[r][1] * lam[i]
            if C[r][1] == 0.0:
                continue
            if extra is not None:
                if kind == ROW_SLIDE:
                    _add_slide_hessian(dofs[0], dofs[1], u[0], u[1], q, coef, map_H, i, out[r])
                    continue
            if kind != ROW_ANGLE:
                for side in range(2):
                    if dofs[side][0] >= 0 or dofs[side][2] >= 0:
                        sg = 1.0 if side == 0 else -1.0
                        _add_hessian(kind, dofs[side], u[side][0], u[side][1], q, sg * coef,
                                     map_H, i, side, out[r])


@njit(cache=True)
def constraint_values(extra, q, v, c, cd, con_kind, con_dofs, con_u0, phi, phid):
    """Position- and velocity-level violation of every row: ``phi = g - c``,
    ``phid = J q' - c'`` (each (n_con,), out; ``extra``: ``S.extra_items``, which must be True if
    ``con_kind`` has slide rows)."""
    zero = q[0] * 0.0
    for i in range(con_kind.shape[0]):
        dofs = (_dofs(con_dofs, i, 0), _dofs(con_dofs, i, 1))
        g, _, grad, _, _, _ = _row_of(con_kind[i], extra, dofs[0], dofs[1], _u(con_u0, i, 0),
                                      _u(con_u0, i, 1), q, v, v)
        Jv = zero
        for side in range(2):
            for j in range(6):
                if dofs[side][j] >= 0:
                    Jv += grad[side][j] * v[dofs[side][j]]
        phi[i] = g - c[i]
        phid[i] = Jv - cd[i]


@njit(cache=True)
def constraint_violation_history(extra, Q, V, C, CD, con_kind, con_dofs, con_u0, viol, vviol):
    """``max |Phi|`` and ``max |Phi'|`` at every stored time in one call (``extra``: as for
    :func:`constraint_values`).

    ``Q, V`` (n_t, n_dof); ``C, CD`` (n_t, n_con) constraint targets; ``viol, vviol`` (n_t,),
    out (magnitudes of the real parts: a diagnostic, not differentiated)."""
    n_con = con_kind.shape[0]
    phi = np.zeros(n_con, dtype=Q.dtype)
    phid = np.zeros(n_con, dtype=Q.dtype)
    for k in range(Q.shape[0]):
        constraint_values(extra, Q[k], V[k], C[k], CD[k], con_kind, con_dofs, con_u0, phi, phid)
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
