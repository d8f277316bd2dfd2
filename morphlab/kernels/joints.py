"""Scalar constraint rows with exact derivatives (the point loads, which share their point
kinematics, are in :mod:`morphlab.kernels.loads`; the slide rows of prismatic joints in
:mod:`morphlab.kernels.slides`).

Every joint is a set of scalar rows ``Phi_i = g_i(q) - c_i(t) = 0`` (:data:`ROWS`), each of
one kind:

* :data:`ROW_X` / :data:`ROW_Y` (0 / 1): the x / y component of ``r_P - r_Q``, with
  ``r = R + A (u0 + w)`` for a material point of a body (``w`` the nodal displacement of a beam
  node, zero for a rigid body point);
* :data:`ROW_ANGLE` (2): the angle ``(theta_P + phi_P) - (theta_Q + phi_Q)`` (``phi`` the nodal
  rotation);
* :data:`ROW_GEAR` (3): the angle ``(theta_P + phi_P) - r (theta_Q + phi_Q)`` with the ratio
  ``r`` in ``u0[1, 2]``: a gear pair or coupler.

A side (P or Q) is described by the global DOFs ``(R_x, R_y, theta, u, v, phi)`` of its point
(``-1`` where absent; all ``-1`` for the ground), its body-frame position ``u0[side, 0:2]``
and a coefficient ``u0[side, 2]`` (the gear ratio of side Q; unused otherwise). Revolute = an
x and a y row; weld = x, y and angle rows; a ground fix any subset; a driving constraint an
angle row with a time-dependent ``c``.

What the other stages need to know of a row kind is in the tables :data:`POINT_HESSIAN`
(the row has the one-side Hessian of a material point: the step-matrix pattern) and
:data:`ANGLE_LIKE` (the row measures an angle: the scaling of the rank checks), and in
:func:`reaction_directions` (the force and moment a unit multiplier applies: the reactions).

The acceleration-level right-hand side with Baumgarte-type stabilization (part of the residual,
so it is differentiated with it) is::

    F_c = -q'^T H q' + c'' - b1 (J q' - c') - b0 (g - c),        H = d²g/dq²

and the rows of the residual are ``s (w_cm J a - w_cf F_c)`` (scaled by ``s``); the multipliers
add ``w_l J^T lambda`` to the equations of motion (paper eq. 25–26 use ``w_l = w_m``).
"""

import numpy as np

from ._jit import inlined, inner, kernel
from .schema import Kind, design, pattern, register, timed, topology
from .types import add_split

#: Kinds of constraint rows (``rows.kind``; module docstring).
ROW_X, ROW_Y, ROW_ANGLE, ROW_GEAR = 0, 1, 2, 3
#: Per row kind: does the row carry the one-side Hessian of a material point (x, y rows)?
POINT_HESSIAN = np.array([True, True, False, False])
#: Per row kind: is the row an angle (radians, not a length)?
ANGLE_LIKE = np.array([False, False, True, True])

ROWS = register(Kind("rows", [
    design("u0", (2, 3), "body-frame point of each side and its coefficient (gear ratio)"),
    topology("kind", (), "ROW_X, ROW_Y, ROW_ANGLE or ROW_GEAR"),
    topology("con", (), "constraint number (multiplier, equation n_dof + con)"),
    topology("dofs", (2, 6), "DOFs R_x, R_y, theta, u, v, phi of each side (-1: absent)"),
    pattern("row", (2, 6), "positions of (constraint row, DOF j of side s)"),
    pattern("col", (2, 6), "positions of (DOF j of side s, multiplier column)"),
    pattern("H", (2, 6, 6), "positions of the Hessian entries of each side's point"),
    timed("c", (), "target value"),
    timed("cd", (), "its first time derivative"),
    timed("cdd", (), "its second time derivative"),
], "a scalar constraint row between two material points",
   timing="drive", module=__name__))

# entries of a side's 6 x 6 Hessian that can be nonzero (theta-theta, theta-w, w-theta)
HESS_ENTRIES = ((2, 2), (2, 3), (3, 2), (2, 4), (4, 2))


def hessian_coordinates(dofs: np.ndarray, which) -> tuple[np.ndarray, np.ndarray]:
    """Row and column DOFs of the Hessian entries :data:`HESS_ENTRIES` of points whose six
    DOFs are ``dofs[..., 6]``, where ``which`` (broadcastable to ``dofs[..., 0]``) is True;
    ``-1`` elsewhere (shape ``dofs.shape[:-1] + (6, 6)``)."""
    shape = dofs.shape[:-1] + (6, 6)
    Hr, Hc = -np.ones(shape, dtype=np.int64), -np.ones(shape, dtype=np.int64)
    for (j, k) in HESS_ENTRIES:
        Hr[..., j, k] = np.where(which, dofs[..., j], -1)
        Hc[..., j, k] = np.where(which, dofs[..., k], -1)
    return Hr, Hc


@ROWS.pattern_of
def coordinates(S, n_dof: int) -> dict:
    """(row, column) of every entry of :data:`ROWS`' pattern fields (``-1``: none)."""
    A = S.rows
    crow = (n_dof + A.con)[:, None, None]
    point = POINT_HESSIAN[A.kind][:, None]
    return {"row": (crow, A.dofs), "col": (A.dofs, crow),
            "H": hessian_coordinates(A.dofs, point)}


@ROWS.reactions_of
def reaction_directions(A, items, sides, q) -> np.ndarray:
    """``(n_t, n, 3)``: the force (x, y) and moment a unit multiplier of each row applies to
    its side ``sides`` (0 or 1), with the sign of side 1 (``morphlab.results.reactions``
    applies the held side's): x and y rows push along x and y, angle rows turn, a gear row
    turns side 1 by its ratio."""
    kind = A.kind[items]
    out = np.zeros((q.shape[0], kind.shape[0], 3), dtype=np.result_type(q, A.u0))
    out[:, kind == ROW_X, 0] = 1.0
    out[:, kind == ROW_Y, 1] = 1.0
    out[:, kind == ROW_ANGLE, 2] = 1.0
    for j in np.flatnonzero(kind == ROW_GEAR):
        out[:, j, 2] = A.u0[items[j], 1, 2] if sides[j] == 1 else 1.0
    return out


@inner(forceinline=True)
def _at(w, d, zero):
    """``w[d]``, or ``zero`` where the DOF ``d`` is absent (-1)."""
    return w[d] if d >= 0 else zero


@inlined
def side_terms(kind, dofs, ux0, uy0, q, v, a):
    """Value, gradient and second-order terms of one side of a point or angle row (sign not
    applied).

    ``dofs``: the side's six DOFs (tuple, ``-1`` where absent); ``(ux0, uy0)``: the point in the
    body frame. Returns ``(g, vHv, grad, Hv, Ha, dvHv)``, the last four as 6-tuples on the
    local DOFs: ``grad = dg/dq``, ``Hv = H q'``, ``Ha = H q''`` and ``dvHv = d(q'^T H q')/dq``.
    (Values, not output arrays: scratch arrays passed into a helper add reference counting
    and keep Numba from optimizing the caller's loop.)
    """
    # one scalar type for every returned value: that of the state and the point together
    zero = q[0] * 0.0 + ux0 * 0.0
    one = zero + 1.0
    th = _at(q, dofs[2], zero)
    vth = _at(v, dofs[2], zero)
    ath = _at(a, dofs[2], zero)
    if kind == ROW_ANGLE or kind == ROW_GEAR:
        phi = _at(q, dofs[5], zero)
        z6 = (zero, zero, zero, zero, zero, zero)
        return th + phi + zero, zero, (zero, zero, one, zero, zero, one), z6, z6, z6
    wx = _at(q, dofs[3], zero)
    vwx = _at(v, dofs[3], zero)
    awx = _at(a, dofs[3], zero)
    wy = _at(q, dofs[4], zero)
    vwy = _at(v, dofs[4], zero)
    awy = _at(a, dofs[4], zero)
    Rk = _at(q, dofs[kind], zero)
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


@inner(forceinline=True)
def side_hessian(kind, dofs, ux0, uy0, q):
    """The nonzero entries ``(H_thth, H_th,wx, H_th,wy)`` of ``H = d²g/dq²`` of one side of an
    x (``kind`` 0) or y (1) row (symmetric)."""
    zero = q[0] * 0.0 + ux0 * 0.0  # the scalar type of state and point (see side_terms)
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


@inlined
def point_side(kind, dofs, ux0, uy0, q, v, a):
    """:func:`side_terms`, or zeros for the ground (no DOFs; its point sits in ``c``)."""
    if dofs[0] < 0 and dofs[2] < 0:
        zero = q[0] * 0.0 + ux0 * 0.0
        z6 = (zero, zero, zero, zero, zero, zero)
        return zero, zero, z6, z6, z6, z6
    return side_terms(kind, dofs, ux0, uy0, q, v, a)


#: :func:`side_terms` as a call of its own, which LLVM inlines (``forceinline``), for the item
#: kinds that evaluate points at several places (forces, slides, point and line loads): there
#: each call site of the Numba-level inlined one is typed again, about a CPU-second each. The
#: rows' :func:`_side` keeps the Numba-level one, with which their loop runs faster.
point_terms = inner(forceinline=True)(getattr(side_terms, "py_func", side_terms))


@inlined
def point_dofs(dofs):
    """The DOFs ``(R_x, R_y, theta, u, v, phi)`` of a point as a 6-tuple, from its row
    ``dofs`` (6,) (-1: absent)."""
    return (dofs[0], dofs[1], dofs[2], dofs[3], dofs[4], dofs[5])


@inner
def point_angle(dofs, w, zero):
    """``w[theta] + w[phi]`` at a point of the DOFs ``dofs`` (6-tuple; a term is zero where
    its DOF is absent): the point's rotation, or its rate, for ``w`` = q, q'."""
    out = zero
    if dofs[2] >= 0:
        out += w[dofs[2]]
    if dofs[5] >= 0:
        out += w[dofs[5]]
    return out


@inner(forceinline=True)
def _side(A, i, side, q, v, a):
    """``(sign, g, vHv, grad, Hv, Ha, dvHv, dofs)`` of side ``side`` of row ``i``
    (:func:`point_side`, the last five 6-tuples on the side's DOFs ``dofs``); ``sign`` the
    side's coefficient in the row: 1 for side 0, minus one for side 1 (minus the ratio for a
    gear row)."""
    kind = A.kind[i]
    d = point_dofs(A.dofs[i, side])
    sign = 1.0 + 0.0 * A.u0[i, 1, 2]
    if side == 1:
        sign = -A.u0[i, 1, 2] if kind == ROW_GEAR else -sign
    g, vHv, grad, Hv, Ha, dvHv = point_side(kind, d, A.u0[i, side, 0], A.u0[i, side, 1], q, v,
                                            a)
    return sign, g, vHv, grad, Hv, Ha, dvHv, d


@inner(forceinline=True)
def add_row_entries(w, C, gr, hv, ha, dvhv, p_row, p_col, out):
    """The entries of one DOF of a constraint row (weights ``w``,
    :class:`~morphlab.kernels.types.Weights`) in the outputs ``out`` (m, nnz) of the
    coefficients ``C`` (m, 3): at ``p_row`` (the row's column of the DOF) the derivative of
    ``scale (wcm J a - wcf F_c)``, at ``p_col`` (the DOF's entry in the multiplier's column)
    ``wl scale J`` (-1: absent). ``gr``, ``hv``, ``ha``, ``dvhv``: the DOF's entries of the
    row's ``J``, ``H q'``, ``H q''`` and ``d(q'^T H q')/dq``."""
    dFc_dq = -dvhv - w.b1 * hv - w.b0 * gr
    dFc_dv = -2.0 * hv - w.b1 * gr
    x0 = w.scale * w.wcm * gr
    xq = w.scale * (w.wcm * ha - w.wcf * dFc_dq)
    xv = -w.scale * w.wcf * dFc_dv
    if p_row >= 0:
        add_split(out, C, p_row, x0, xq, xv)
    if p_col >= 0:  # along the multiplier: D0 alone
        out[0, p_col] += C[0, 0] * w.wl * w.scale * gr


@inner
def residual(A, x, w, T, t, k, rows, n_dof, R):
    """Add ``wl J^T lam`` to the equation rows and ``scale (wcm J a - wcf F_c)`` to the
    constraint rows ``R[n_dof + con]`` of the rows ``rows`` (int64 indices).

    ``A``: the arrays of :data:`ROWS`; ``x``: a :class:`~morphlab.kernels.types.Level`;
    ``w``: its :class:`~morphlab.kernels.types.Weights`; ``T``: the rows' time values
    (``T.c[t, k, i]``: table ``t`` at time index ``k``).
    """
    if A is None:  # the model has none of this kind
        return
    q, v, a, lam = x.q, x.v, x.a, x.lam
    zero = R[0] * 0.0
    for i in rows:
        con = A.con[i]
        g = zero
        vHv = zero
        Ja = zero
        Jv = zero
        for side in range(2):
            sign, gs, vHvs, grad, _, _, _, d = _side(A, i, side, q, v, a)
            g += sign * gs
            vHv += sign * vHvs
            for j in range(6):
                if d[j] >= 0:
                    gj = sign * grad[j]
                    Ja += gj * a[d[j]]
                    Jv += gj * v[d[j]]
                    R[d[j]] += w.wl * gj * lam[con]
        Fc = (-vHv + T.cdd[t, k, i] - w.b1 * (Jv - T.cd[t, k, i])
              - w.b0 * (g - T.c[t, k, i]))
        R[n_dof + con] += w.scale * (w.wcm * Ja - w.wcf * Fc)


@inner
def matrix(A, x, w, C, out):
    """Add the terms of the rows to the step matrix's CSC data arrays ``out`` (m, nnz), output
    ``r`` receiving ``C[r, 0] D0 + C[r, 1] Dq + C[r, 2] Dv`` (:mod:`morphlab.kernels.types`;
    positions ``A.row``, ``A.col``, ``A.H``, ``-1`` absent)."""
    if A is None:  # the model has none of this kind
        return
    q, v, a, lam = x.q, x.v, x.a, x.lam
    cl = w.wl
    for i in range(A.kind.shape[0]):
        kind = A.kind[i]
        lam_i = lam[A.con[i]]
        for side in range(2):
            sign, _, _, grad, Hv, Ha, dvHv, d = _side(A, i, side, q, v, a)
            for j in range(6):
                if d[j] >= 0:
                    add_row_entries(w, C, sign * grad[j], sign * Hv[j], sign * Ha[j],
                                    sign * dvHv[j], A.row[i, side, j], A.col[i, side, j], out)
            if kind != ROW_X and kind != ROW_Y:
                continue
            # the Hessian terms bh2 cl lam H belong to Dq alone
            if d[0] < 0 and d[2] < 0:
                continue
            h22, h23, h24 = side_hessian(kind, d, A.u0[i, side, 0], A.u0[i, side, 1], q)
            sg = 1.0 if side == 0 else -1.0
            for r in range(C.shape[0]):
                if C[r, 1] == 0.0:
                    continue
                coef = sg * cl * C[r, 1] * lam_i
                add_hessian(A.H[i, side], h22, h23, h24, coef, out[r])


@inner(forceinline=True)
def add_hessian(hmap, h22, h23, h24, coef, data):
    """Add ``coef H`` of one side to ``data`` at the positions ``hmap[j, k]`` (6, 6)."""
    for (j, k, h) in ((2, 2, h22), (2, 3, h23), (3, 2, h23), (2, 4, h24), (4, 2, h24)):
        p = hmap[j, k]
        if p >= 0:
            data[p] += coef * h


@kernel
def values(A, q, v, T, k, phi, phid):
    """Position- and velocity-level violation of every row: ``phi[con] = g - c``,
    ``phid[con] = J q' - c'`` with the targets of the time values ``T`` at time index ``k``
    (table 0)."""
    if A is None:  # the model has none of this kind
        return
    zero = q[0] * 0.0
    for i in range(A.kind.shape[0]):
        g = zero
        Jv = zero
        for side in range(2):
            sign, gs, _, grad, _, _, _, d = _side(A, i, side, q, v, v)
            g += sign * gs
            for j in range(6):
                if d[j] >= 0:
                    Jv += sign * grad[j] * v[d[j]]
        phi[A.con[i]] = g - T.c[0, k, i]
        phid[A.con[i]] = Jv - T.cd[0, k, i]
