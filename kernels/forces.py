"""Spring-damper elements with exact derivatives.

A spring-damper acts between two sides P and Q, each described like a constraint side
(:mod:`morphlab.kernels.joints`: six DOFs ``R_x, R_y, theta, u, v, phi``, ``-1`` where absent,
all ``-1`` for the ground, and a body-frame point). It measures a scalar ``s(q)``:

* :data:`SPRING_LENGTH` (0): the distance ``l = |d|`` of the points, ``d = r_P - r_Q``
  (a translational spring; the ground side's point is its global position);
* :data:`SPRING_ANGLE` (1): the relative rotation ``(theta_P + phi_P) - (theta_Q + phi_Q)``.

Its force ``f = k (s - s0) + c s' + f0`` (``S.spring_par[i] = (k, c, s0, f0)``, ``s' = grad s
. q'``) adds ``wf f grad s`` to the equation rows. The Newton matrix of the step, with
``q = q_hat + bh2 a`` and ``q' = v_hat + gh a``, is
``wf [bh2 (grad s (k grad s + c H q')^T + f H) + gh c grad s grad s^T]``, ``H = d²s/dq²``:
for the length
``H = (D^T (I - e e^T) D) / l + e_x H_x + e_y H_y`` (``D = dd/dq``, ``e = d / l``, ``H_x``,
``H_y`` the point Hessians of the two components), zero for the angle
(``docs/theory.md`` §4.6).
"""

import numpy as np
from numba import njit

from .joints import ROW_X, ROW_Y, _psi, _side_hessian, _side_of

#: Kinds of spring-damper (``spring_kind``): distance of two points, relative rotation.
SPRING_LENGTH, SPRING_ANGLE = 0, 1


@njit(cache=True, inline="always")
def _sdofs(table, i, side):
    return (table[i, side, 0], table[i, side, 1], table[i, side, 2], table[i, side, 3],
            table[i, side, 4], table[i, side, 5])


@njit(cache=True, inline="always")
def _scaled(x, t):
    return (x * t[0], x * t[1], x * t[2], x * t[3], x * t[4], x * t[5])


@njit(cache=True)
def _measure(kind, dP, dQ, uP, uQ, q, v):
    """``(s, s', (grad_P, grad_Q), (Hv_P, Hv_Q), (e_x, e_y, l), (Dx_P, Dy_P, Dx_Q, Dy_Q))`` of a
    spring: its measure, rate, gradient and ``H q'`` per side (6-tuples, signs applied), and
    for a length the direction, the length and the signed gradients of ``d`` (zeros for an
    angle)."""
    zero = q[0] * 0.0 + uP[0] * 0.0 + uQ[0] * 0.0
    one = zero + 1.0
    z6 = (zero, zero, zero, zero, zero, zero)
    if kind == SPRING_ANGLE:
        e = (zero, zero, one, zero, zero, one)
        s = _psi(dP, q, zero) - _psi(dQ, q, zero)
        sd = _psi(dP, v, zero) - _psi(dQ, v, zero)
        return s, sd, (e, _scaled(-1.0, e)), (z6, z6), (zero, zero, one), (z6, z6, z6, z6)
    gxP, _, DxP, HvxP, _, _ = _side_of(ROW_X, dP, uP[0], uP[1], q, v, v)
    gyP, _, DyP, HvyP, _, _ = _side_of(ROW_Y, dP, uP[0], uP[1], q, v, v)
    gxQ, _, DxQ, HvxQ, _, _ = _side_of(ROW_X, dQ, uQ[0], uQ[1], q, v, v)
    gyQ, _, DyQ, HvyQ, _, _ = _side_of(ROW_Y, dQ, uQ[0], uQ[1], q, v, v)
    DxQ, DyQ = _scaled(-1.0, DxQ), _scaled(-1.0, DyQ)
    dx, dy = gxP - gxQ, gyP - gyQ
    ell = np.sqrt(dx * dx + dy * dy)
    ex, ey = dx / ell, dy / ell
    vx, vy = zero, zero  # the relative velocity D q'
    for j in range(6):
        if dP[j] >= 0:
            vx += DxP[j] * v[dP[j]]
            vy += DyP[j] * v[dP[j]]
        if dQ[j] >= 0:
            vx += DxQ[j] * v[dQ[j]]
            vy += DyQ[j] * v[dQ[j]]
    sd = ex * vx + ey * vy
    gP = (ex * DxP[0] + ey * DyP[0], ex * DxP[1] + ey * DyP[1], ex * DxP[2] + ey * DyP[2],
          ex * DxP[3] + ey * DyP[3], ex * DxP[4] + ey * DyP[4], ex * DxP[5] + ey * DyP[5])
    gQ = (ex * DxQ[0] + ey * DyQ[0], ex * DxQ[1] + ey * DyQ[1], ex * DxQ[2] + ey * DyQ[2],
          ex * DxQ[3] + ey * DyQ[3], ex * DxQ[4] + ey * DyQ[4], ex * DxQ[5] + ey * DyQ[5])
    # H q' = D^T (I - e e^T) D q' / l + sum_k e_k H_k q' (H_k q' of each side from _side)
    px, py = (vx - ex * sd) / ell, (vy - ey * sd) / ell
    hP = (DxP[0] * px + DyP[0] * py, DxP[1] * px + DyP[1] * py,
          DxP[2] * px + DyP[2] * py + ex * HvxP[2] + ey * HvyP[2],
          DxP[3] * px + DyP[3] * py + ex * HvxP[3] + ey * HvyP[3],
          DxP[4] * px + DyP[4] * py + ex * HvxP[4] + ey * HvyP[4], zero)
    hQ = (DxQ[0] * px + DyQ[0] * py, DxQ[1] * px + DyQ[1] * py,
          DxQ[2] * px + DyQ[2] * py - ex * HvxQ[2] - ey * HvyQ[2],
          DxQ[3] * px + DyQ[3] * py - ex * HvxQ[3] - ey * HvyQ[3],
          DxQ[4] * px + DyQ[4] * py - ex * HvxQ[4] - ey * HvyQ[4], zero)
    return ell, sd, (gP, gQ), (hP, hQ), (ex, ey, ell), (DxP, DyP, DxQ, DyQ)


@njit(cache=True, inline="always")
def _spring_of(S, i, q, v):
    """:func:`_measure` of spring ``i`` of ``S`` and its DOFs (pair of 6-tuples)."""
    dofs = (_sdofs(S.spring_dofs, i, 0), _sdofs(S.spring_dofs, i, 1))
    u = S.spring_u0
    return dofs, _measure(S.spring_kind[i], dofs[0], dofs[1], (u[i, 0, 0], u[i, 0, 1]),
                          (u[i, 1, 0], u[i, 1, 1]), q, v)


@njit(cache=True)
def spring_residual(S, q, v, wf, springs, R):
    """Add ``wf f grad s`` of the spring-dampers ``springs`` (int64 indices) to the equation
    rows of ``R``."""
    par = S.spring_par
    for i in springs:
        dofs, m = _spring_of(S, i, q, v)
        s, sd, g = m[0], m[1], m[2]
        f = par[i, 0] * (s - par[i, 2]) + par[i, 1] * sd + par[i, 3]
        for side in range(2):
            for j in range(6):
                d = dofs[side][j]
                if d >= 0:
                    R[d] += wf * f * g[side][j]


@njit(cache=True)
def spring_jacobian(S, q, v, cf, bh2, gh, data):
    """Add ``d(wf f grad s)/da`` of every spring-damper to ``data`` (positions
    ``S.spring_map[i, r, c, j, k]``: row DOF ``j`` of side ``r``, column DOF ``k`` of side
    ``c``), weighted ``cf`` (module docstring)."""
    par, smap = S.spring_par, S.spring_map
    for i in range(S.spring_kind.shape[0]):
        dofs, m = _spring_of(S, i, q, v)
        s, sd, g, hv, geo, D = m
        k, c = par[i, 0], par[i, 1]
        f = k * (s - par[i, 2]) + c * sd + par[i, 3]
        length = S.spring_kind[i] == SPRING_LENGTH
        ex, ey, ell = geo
        z = ex * 0.0
        sh = ((z, z, z), (z, z, z))  # (H_22, H_23, H_24) of e_x H_x + e_y H_y per side
        if length:
            u = S.spring_u0
            hx, hy = (_side_hessian(ROW_X, dofs[0], u[i, 0, 0], u[i, 0, 1], q),
                      _side_hessian(ROW_Y, dofs[0], u[i, 0, 0], u[i, 0, 1], q))
            hxq, hyq = (_side_hessian(ROW_X, dofs[1], u[i, 1, 0], u[i, 1, 1], q),
                        _side_hessian(ROW_Y, dofs[1], u[i, 1, 0], u[i, 1, 1], q))
            sh = ((ex * hx[0] + ey * hy[0], ex * hx[1] + ey * hy[1], ex * hx[2] + ey * hy[2]),
                  (-ex * hxq[0] - ey * hyq[0], -ex * hxq[1] - ey * hyq[1],
                   -ex * hxq[2] - ey * hyq[2]))
        for r in range(2):
            Dx, Dy = D[2 * r], D[2 * r + 1]
            for j in range(6):
                if dofs[r][j] < 0:
                    continue
                for cs in range(2):
                    Ex, Ey = D[2 * cs], D[2 * cs + 1]
                    for kk in range(6):
                        p = smap[i, r, cs, j, kk]
                        if p < 0:
                            continue
                        gg = g[r][j] * g[cs][kk]
                        val = bh2 * (k * gg + c * g[r][j] * hv[cs][kk]) + gh * c * gg
                        if length:
                            H = (Dx[j] * Ex[kk] + Dy[j] * Ey[kk] - gg) / ell
                            if r == cs and (j == 2 or kk == 2):
                                o = j + kk - 2  # 2: (th, th); 3: (th, wx); 4: (th, wy)
                                if o >= 2 and o <= 4:
                                    H += sh[r][o - 2]
                            val += bh2 * f * H
                        data[p] += cf * val


@njit(cache=True)
def spring_measures(S, Q, V, out):
    """The measure ``s`` and its rate ``s'`` of every spring-damper at every stored time:
    ``Q, V`` (n_t, n_dof), ``out`` (n_t, n_spring, 2)."""
    for t in range(Q.shape[0]):
        for i in range(S.spring_kind.shape[0]):
            _, m = _spring_of(S, i, Q[t], V[t])
            out[t, i, 0] = m[0]
            out[t, i, 1] = m[1]
