"""The slide row of a prismatic joint, with exact derivatives (:data:`SLIDES`).

A slide row keeps a point P on a line through Q fixed in Q's body: ``g = n(psi) . (r_P -
r_Q)`` with ``n = (cos psi, sin psi)`` and ``psi = theta_Q + phi_Q + beta`` (``beta`` the
normal's angle in Q's frame, ``u0[1, 2]``). Unlike the rows of :mod:`morphlab.kernels.joints`
it couples both sides (its Hessian has P-Q blocks). Sides are described as there; the rows
share the constraint numbering (``con``) and the residual and matrix conventions of
:mod:`morphlab.kernels.joints`. An optional kind: models without prismatic joints do not
compile it.
"""

import numpy as np

from ._jit import inner, kernel
from .joints import add_hessian as _add_side_hessian
from .joints import add_row_entries, point_angle, point_dofs, point_terms, side_hessian
from .schema import Kind, design, pattern, register, timed, topology

SLIDES = register(Kind("slides", [
    design("u0", (2, 3), "body-frame point of P and Q; u0[1, 2] the normal's angle beta"),
    topology("con", (), "constraint number"),
    topology("dofs", (2, 6), "DOFs of each side"),
    pattern("row", (2, 6), "positions of (constraint row, DOF j of side s)"),
    pattern("col", (2, 6), "positions of (DOF j of side s, multiplier column)"),
    pattern("H", (2, 2, 6, 6), "positions of the Hessian entries (row side, column side)"),
    timed("c", (), "target value"),
    timed("cd", (), "its first time derivative"),
    timed("cdd", (), "its second time derivative"),
], "the slide row of a prismatic joint",
   optional=True, timing="drive", module=__name__))


@SLIDES.pattern_of
def coordinates(S, n_dof: int) -> dict:
    """(row, column) of every entry of :data:`SLIDES`' pattern fields: the rows and columns
    of the constraint, and every pair of the two sides' DOFs in the Hessian (it couples the
    guide's rotation with both points)."""
    A = S.slides
    n = A.con.shape[0]
    crow = (n_dof + A.con)[:, None, None]
    Hr = -np.ones((n, 2, 2, 6, 6), dtype=np.int64)
    Hc = -np.ones_like(Hr)
    for r in range(2):
        for c in range(2):
            rows = np.broadcast_to(A.dofs[:, r, :, None], (n, 6, 6))
            cols = np.broadcast_to(A.dofs[:, c, None, :], (n, 6, 6))
            ok = (rows >= 0) & (cols >= 0)
            Hr[:, r, c] = np.where(ok, rows, -1)
            Hc[:, r, c] = np.where(ok, cols, -1)
    return {"row": (crow, A.dofs), "col": (A.dofs, crow), "H": (Hr, Hc)}


@SLIDES.reactions_of
def reaction_directions(A, items, sides, q) -> np.ndarray:
    """``(n_t, n, 3)``: the force of a unit multiplier along the guide's normal at the states
    ``q`` (n_t, n_dof), ``psi = theta_Q + phi_Q + beta`` (no moment: it acts at the slider's
    point), on either side."""
    psi = A.u0[items, 1, 2][None, :] + 0.0 * q[:, :1]
    for j, i in enumerate(items):
        for d in A.dofs[i, 1, [2, 5]]:
            if d >= 0:
                psi[:, j] = psi[:, j] + q[:, d]
    out = np.zeros(psi.shape + (3,), dtype=psi.dtype)
    out[..., 0], out[..., 1] = np.cos(psi), np.sin(psi)
    return out


@inner
def _lin(x, p, y, r):
    """The 6-tuple ``x p + y r`` (``p``, ``r`` 6-tuples)."""
    return (x * p[0] + y * r[0], x * p[1] + y * r[1], x * p[2] + y * r[2], x * p[3] + y * r[3],
            x * p[4] + y * r[4], x * p[5] + y * r[5])


@inner
def _dot(grad, dofs, w, zero):
    out = zero
    for j in range(6):
        if dofs[j] >= 0:
            out += grad[j] * w[dofs[j]]
    return out


@inner
def _point(dofs, ux0, uy0, q, v, a):
    """The x and the y component of one material point (:func:`~morphlab.kernels.joints.
    side_terms` of each; a ground side's point is its global position)."""
    return (point_terms(np.int64(0), dofs, ux0, uy0, q, v, a),
            point_terms(np.int64(1), dofs, ux0, uy0, q, v, a))


@inner
def _slide(A, i, q, v, a):
    """``(g, vHv, grad, Hv, Ha, dvHv)`` of slide row ``i``, each of the last four a pair
    (P side, Q side) of 6-tuples, signs included.

    With ``t = dn/dpsi`` and ``D = dd/dq``: ``grad = n^T D + (t.d) e_psi``;
    ``H = n.H_d + e_psi (t^T D) + (t^T D)^T e_psi^T - (n.d) e_psi e_psi^T``;
    ``v^T H v = n.(v^T H_d v) + 2 psi' t.(D v) - psi'^2 n.d``.
    """
    dP, dQ = point_dofs(A.dofs[i, 0]), point_dofs(A.dofs[i, 1])
    uP, uQ = A.u0[i, 0], A.u0[i, 1]
    zero = q[0] * 0.0 + uP[0] * 0.0
    (gxP, vxP, grxP, HvxP, HaxP, dvxP), (gyP, vyP, gryP, HvyP, HayP, dvyP) = _point(
        dP, uP[0], uP[1], q, v, a)
    (gxQ, vxQ, grxQ, HvxQ, HaxQ, dvxQ), (gyQ, vyQ, gryQ, HvyQ, HayQ, dvyQ) = _point(
        dQ, uQ[0], uQ[1], q, v, a)
    psi = point_angle(dQ, q, zero) + uQ[2]
    pv = point_angle(dQ, v, zero)
    pa = point_angle(dQ, a, zero)
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


@inner
def _add_point_hessian(d, u, q, cx, cy, hmap, data):
    """Add ``cx H_x + cy H_y`` of one material point at ``hmap[j, k]`` (6, 6)."""
    h22, h23, h24 = side_hessian(np.int64(0), d, u[0], u[1], q)
    _add_side_hessian(hmap, h22, h23, h24, cx, data)
    h22, h23, h24 = side_hessian(np.int64(1), d, u[0], u[1], q)
    _add_side_hessian(hmap, h22, h23, h24, cy, data)


@inner
def _add_hessian(A, i, q, coef, data):
    """Add ``coef H`` of slide row ``i`` to ``data`` at ``A.H[i, r, c, j, k]`` (``r``, ``c``:
    the sides of row and column; 0 = P, 1 = Q)."""
    dP, dQ = point_dofs(A.dofs[i, 0]), point_dofs(A.dofs[i, 1])
    uP, uQ = A.u0[i, 0], A.u0[i, 1]
    hmap = A.H[i]
    zero = q[0] * 0.0 + uP[0] * 0.0
    psi = point_angle(dQ, q, zero) + uQ[2]
    nx, ny = np.cos(psi) + zero, np.sin(psi) + zero
    (gxP, _, grxP, _, _, _), (gyP, _, gryP, _, _, _) = _point(dP, uP[0], uP[1], q, q, q)
    (gxQ, _, grxQ, _, _, _), (gyQ, _, gryQ, _, _, _) = _point(dQ, uQ[0], uQ[1], q, q, q)
    nd = nx * (gxP - gxQ) + ny * (gyP - gyQ)
    if dP[0] >= 0 or dP[2] >= 0:
        _add_point_hessian(dP, uP, q, coef * nx, coef * ny, hmap[0, 0], data)
    if dQ[0] >= 0 or dQ[2] >= 0:
        _add_point_hessian(dQ, uQ, q, -coef * nx, -coef * ny, hmap[1, 1], data)
    tP = _lin(-ny, grxP, nx, gryP)
    tQ = _lin(-ny, grxQ, nx, gryQ)
    for j in (2, 5):
        for m in range(6):
            for (r, c, jj, mm, h) in ((0, 1, m, j, tP[m]), (1, 0, j, m, tP[m]),
                                      (1, 1, j, m, -tQ[m]), (1, 1, m, j, -tQ[m])):
                p = hmap[r, c, jj, mm]
                if p >= 0:
                    data[p] += coef * h
        for k in (2, 5):
            p = hmap[1, 1, j, k]
            if p >= 0:
                data[p] -= coef * nd


@inner
def _rate(A, i, grad, w, zero):
    """``J w`` of slide ``i`` for its two sides' gradients ``grad`` (``w`` = q', q'')."""
    return (_dot(grad[0], point_dofs(A.dofs[i, 0]), w, zero)
            + _dot(grad[1], point_dofs(A.dofs[i, 1]), w, zero))


@inner
def residual(A, x, w, T, t, k, rows, n_dof, R):
    """As :func:`morphlab.kernels.joints.residual`, for the slide rows ``rows``."""
    if A is None:  # the model has none of this kind
        return
    q, v, a, lam = x.q, x.v, x.a, x.lam
    zero = R[0] * 0.0
    for i in rows:
        g, vHv, grad, _, _, _ = _slide(A, i, q, v, a)
        con = A.con[i]
        Ja = _rate(A, i, grad, a, zero)
        Jv = _rate(A, i, grad, v, zero)
        for side in range(2):
            for j in range(6):
                d = A.dofs[i, side, j]
                if d >= 0:
                    R[d] += w.wl * grad[side][j] * lam[con]
        Fc = (-vHv + T.cdd[t, k, i] - w.b1 * (Jv - T.cd[t, k, i])
              - w.b0 * (g - T.c[t, k, i]))
        R[n_dof + con] += w.scale * (w.wcm * Ja - w.wcf * Fc)


@inner
def matrix(A, x, w, C, out):
    """As :func:`morphlab.kernels.joints.matrix`, for the slide rows."""
    if A is None:  # the model has none of this kind
        return
    q, v, a, lam = x.q, x.v, x.a, x.lam
    cl = w.wl
    for i in range(A.con.shape[0]):
        _, _, grad, Hv, Ha, dvHv = _slide(A, i, q, v, a)
        for side in range(2):
            for j in range(6):
                if A.dofs[i, side, j] >= 0:
                    add_row_entries(w, C, grad[side][j], Hv[side][j], Ha[side][j],
                                    dvHv[side][j], A.row[i, side, j], A.col[i, side, j], out)
        for r in range(C.shape[0]):
            if C[r, 1] == 0.0:
                continue
            _add_hessian(A, i, q, cl * C[r, 1] * lam[A.con[i]], out[r])


@kernel
def values(A, q, v, T, k, phi, phid):
    """As :func:`morphlab.kernels.joints.values`, for the slide rows."""
    if A is None:  # the model has none of this kind
        return
    zero = q[0] * 0.0
    for i in range(A.con.shape[0]):
        g, _, grad, _, _, _ = _slide(A, i, q, v, v)
        phi[A.con[i]] = g - T.c[0, k, i]
        phid[A.con[i]] = _rate(A, i, grad, v, zero) - T.cd[0, k, i]
