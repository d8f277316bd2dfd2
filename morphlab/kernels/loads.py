"""External loads: point forces, line loads on beam elements and torques, with the exact
derivatives of the forces.

A point force of fixed global direction at a material point ``P`` adds ``-wf L_P^T F`` to the
equation rows (``docs/theory.md`` §4.5); its dependence on the body angle and the nodal
displacement gives the load terms of the Newton matrix. The point's position, gradient and
second derivatives are those of a constraint side (:func:`morphlab.kernels.joints._side`).

A line load ``q`` (force per undeformed length, global direction) is a load of the same table:
its row of ``F`` holds ``q`` at this time, it has no point (``load_dofs`` all ``-1``) and acts
on the element entries ``line_off[i] .. line_off[i + 1]``. On an element of a frame
``(R, theta)`` with flexible coordinates ``d`` its work-equivalent generalized forces are
(``docs/theory.md`` §4.6)::

    Q_R = L q,    Q_theta = q . A Ĩ (U + N d),    Q_d = N^T A^T q

with ``L = int ds``, ``U = int u0 ds`` (``S.line_u0[e] = (L, U_x, U_y)``) and
``N = int S_e ds`` (``S.line_N[e]``, 2 x 6), integrals over the undeformed element.
"""

import numpy as np
from numba import njit

from .joints import _side, _side_hessian


@njit(cache=True, inline="always")
def torque_residual(S, wf, T, torques, R):
    """Subtract ``wf T`` of the torques ``torques`` (int64 indices) from the equation rows of
    ``R``: each acts on the body angle and on the nodal rotation (``S.torque_dofs``, ``-1``
    if absent); ``T`` (n_torque,) the values at this time [force·length]."""
    for i in torques:
        for j in range(2):
            d = S.torque_dofs[i, j]
            if d >= 0:
                R[d] -= wf * T[i]


@njit(cache=True, inline="always")
def point_load_residual(S, q, wf, F, loads, R):
    """Subtract ``wf Q_ext`` of the point forces among ``loads`` (int64 indices; line loads are
    skipped) from the equation rows of ``R``. ``S.load_dofs``, ``S.load_u0``: the point of
    application of each load (described as a constraint side); ``F`` (n_load, 2): the global
    force of each point load [force], or line load [force/length], at this time."""
    load_dofs, load_u0 = S.load_dofs, S.load_u0
    for i in loads:
        dofs = (load_dofs[i, 0], load_dofs[i, 1], load_dofs[i, 2], load_dofs[i, 3],
                load_dofs[i, 4], load_dofs[i, 5])
        if dofs[0] < 0 and dofs[2] < 0:
            continue  # a line load: no point
        for k in range(2):
            _, _, grad, _, _, _ = _side(k, dofs, load_u0[i, 0], load_u0[i, 1], q, q, q)
            for j in range(6):
                if dofs[j] >= 0:
                    R[dofs[j]] -= wf * grad[j] * F[i, k]


@njit(cache=True, inline="always")
def point_load_jacobian(S, q, cf, bh2, F, data):
    """Add ``-cf bh2 d(Q_ext)/dq`` of the point forces to ``data`` (positions ``S.load_map``
    (n_load, 6, 6))."""
    load_dofs, load_u0, load_map = S.load_dofs, S.load_u0, S.load_map
    for i in range(load_dofs.shape[0]):
        dofs = (load_dofs[i, 0], load_dofs[i, 1], load_dofs[i, 2], load_dofs[i, 3],
                load_dofs[i, 4], load_dofs[i, 5])
        if dofs[0] < 0 and dofs[2] < 0:
            continue
        for k in range(2):
            h22, h23, h24 = _side_hessian(k, dofs, load_u0[i, 0], load_u0[i, 1], q)
            for (j, m, h) in ((2, 2, h22), (2, 3, h23), (3, 2, h23), (2, 4, h24), (4, 2, h24)):
                p = load_map[i, j, m]
                if p >= 0:
                    data[p] -= cf * bh2 * F[i, k] * h


@njit(cache=True, inline="always")
def line_load_residual(S, q, wf, F, loads, R):
    """Subtract ``wf Q_ext`` of the line loads among ``loads`` (int64 indices; point loads have
    no line entries) from the equation rows of ``R`` (module docstring)."""
    for i in loads:
        qx, qy = wf * F[i, 0], wf * F[i, 1]
        for e in range(S.line_off[i], S.line_off[i + 1]):
            # Q_R = L q, Q_theta = (AĨ)^T q . (U + N d), Q_d = N^T A^T q (module docstring)
            el = S.line_elem[e]
            ref = S.body_ref[S.elem_body[el]]
            c, s = np.cos(q[ref[2]]), np.sin(q[ref[2]])
            ax, ay = c * qx + s * qy, c * qy - s * qx  # A^T q; (AĨ)^T q = (ay, -ax)
            mom = ay * S.line_u0[e, 1] - ax * S.line_u0[e, 2]
            for j in range(6):
                f = S.elem_fdof[el, j]
                if f >= 0:
                    d = S.flex_dof[f]
                    mom += (ay * S.line_N[e, 0, j] - ax * S.line_N[e, 1, j]) * q[d]
                    R[d] -= ax * S.line_N[e, 0, j] + ay * S.line_N[e, 1, j]
            R[ref[0]] -= S.line_u0[e, 0] * qx
            R[ref[1]] -= S.line_u0[e, 0] * qy
            R[ref[2]] -= mom


@njit(cache=True, inline="always")
def line_load_jacobian(S, q, cf, bh2, F, data):
    """Add ``-cf bh2 d(Q_ext)/dq`` of the line loads to ``data`` (positions ``S.line_map``
    (n_line, 7, 7))."""
    for i in range(S.line_off.shape[0] - 1):
        qx, qy = cf * bh2 * F[i, 0], cf * bh2 * F[i, 1]
        for e in range(S.line_off[i], S.line_off[i + 1]):
            # dQ_theta/dtheta = -A^T q . (U + N d); dQ_theta/dd = dQ_d/dtheta = N^T (AĨ)^T q
            el = S.line_elem[e]
            m = S.line_map[e]
            th = q[S.body_ref[S.elem_body[el], 2]]
            c, s = np.cos(th), np.sin(th)
            ax, ay = c * qx + s * qy, c * qy - s * qx
            mom = ax * S.line_u0[e, 1] + ay * S.line_u0[e, 2]
            for j in range(6):
                f = S.elem_fdof[el, j]
                if f >= 0:
                    mom += (ax * S.line_N[e, 0, j] + ay * S.line_N[e, 1, j]) * q[S.flex_dof[f]]
                    h = ay * S.line_N[e, 0, j] - ax * S.line_N[e, 1, j]
                    if m[0, 1 + j] >= 0:
                        data[m[0, 1 + j]] -= h
                    if m[1 + j, 0] >= 0:
                        data[m[1 + j, 0]] -= h
            if m[0, 0] >= 0:
                data[m[0, 0]] += mom
