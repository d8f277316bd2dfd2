"""External loads: point forces, torques and line loads on beam elements, with the exact
derivatives of the forces. Three optional kinds: :data:`LOADS`, :data:`TORQUES`,
:data:`LINES`.

A point force of fixed global direction at a material point ``P`` adds ``-wf L_P^T F`` to the
equation rows (``docs/theory.md`` §4.5); its dependence on the body angle and the nodal
displacement gives the load terms of the Newton matrix. The point's position, gradient and
second derivatives are those of a constraint side (:func:`morphlab.kernels.joints.side_terms`).

A torque acts on a body angle and, at a beam node, on the nodal rotation.

A line load ``q`` (force per undeformed length, global direction) on a beam is one entry of
:data:`LINES` per loaded element. On an element of a frame ``(R, theta)`` with flexible
coordinates ``d`` its work-equivalent generalized forces are (``docs/theory.md`` §4.6)::

    Q_R = L q,    Q_theta = q . A Ĩ (U + N d),    Q_d = N^T A^T q

with ``L = int ds``, ``U = int u0 ds`` (``lines.u0[e] = (L, U_x, U_y)``) and
``N = int S_e ds`` (``lines.N[e]``, 2 x 6), integrals over the undeformed element.

Every load is linear in its magnitude (the time values ``F``, ``T``, ``q``), and a line load
also in its integrals: the pseudo-loads of such design variables are these kernels evaluated
with the derivatives in their place.
"""

import numpy as np
from numba.extending import overload

from ._jit import inner
from .joints import (
    ROW_X,
    ROW_Y,
    hessian_coordinates,
    point_angle,
    point_dofs,
    point_terms,
    side_hessian,
)
from .schema import Kind, design, pattern, register, timed, topology

LOADS = register(Kind("loads", [
    design("u0", (2,), "body-frame point of application"),
    topology("dofs", (6,), "DOFs R_x, R_y, theta, u, v, phi of the point"),
    pattern("map", (6, 6), "positions of the point's Hessian entries"),
    timed("F", (2,), "the force (global components) [force]", linear=True),
], "a point force of fixed global direction",
   optional=True, timing="scale", work=True, module=__name__))

TORQUES = register(Kind("torques", [
    topology("dofs", (2,), "DOF of the body angle and of a nodal rotation (-1: none)"),
    timed("T", (), "the torque [force length]", linear=True),
], "a torque on a body (and a beam node)",
   optional=True, timing="scale", work=True, module=__name__))

LINES = register(Kind("lines", [
    design("u0", (3,), "int ds, int u0 ds of the element (undeformed, in its frame)"),
    design("N", (2, 6), "int S_e ds"),
    topology("ref", (3,), "DOFs R_x, R_y, theta of the element's frame"),
    topology("dofs", (6,), "global DOF of each element DOF (-1: removed)"),
    pattern("map", (7, 7), "positions over (theta, d_0 .. d_5)"),
    timed("q", (2,), "the load per length (global components) [force/length]"),
], "a loaded element of a line load",
   optional=True, timing="scale", work=True, module=__name__))


@LOADS.pattern_of
def load_coordinates(S, n_dof: int) -> dict:
    """(row, column) of the point loads' Hessian entries."""
    return {"map": hessian_coordinates(S.loads.dofs, True)}


@LINES.pattern_of
def line_coordinates(S, n_dof: int) -> dict:
    """(row, column) of the line-load entries: theta with itself and with every element
    coordinate, both ways."""
    A = S.lines
    local = np.concatenate([A.ref[:, 2:3], A.dofs], axis=1)
    n = local.shape[0]
    rows = np.broadcast_to(local[:, :, None], (n, 7, 7))
    cols = np.broadcast_to(local[:, None, :], (n, 7, 7))
    border = np.zeros((7, 7), dtype=bool)
    border[0, :] = border[:, 0] = True
    ok = border[None] & (rows >= 0) & (cols >= 0)
    return {"map": (np.where(ok, rows, -1), np.where(ok, cols, -1))}


@inner
def torque_residual(A, wf, T, t, k, items, R):
    """Subtract ``wf T`` of the torques ``items`` from the equation rows of ``R``."""
    if A is None:  # the model has none of this kind
        return
    for i in items:
        for j in range(2):
            d = A.dofs[i, j]
            if d >= 0:
                R[d] -= wf * T.T[t, k, i]


@inner
def add_point_force(dofs, ux0, uy0, q, wf, F0, F1, R):
    """Subtract ``wf grad^T F`` of a force ``F = (F0, F1)`` (global components) at the body-
    frame point ``(ux0, uy0)`` of the DOFs ``dofs`` (6-tuple) from the rows of ``R``."""
    for c in range(2):
        _, _, grad, _, _, _ = point_terms(c, dofs, ux0, uy0, q, q, q)
        Fc = F0 if c == 0 else F1
        for j in range(6):
            if dofs[j] >= 0:
                R[dofs[j]] -= wf * grad[j] * Fc


@inner
def add_point_stiffness(dofs, ux0, uy0, q, s, F0, F1, m, row):
    """Add ``-s d(grad^T F)/dq`` at ``F`` held (the point's Hessian against the force) to
    one output ``row`` (nnz,) at the positions ``m`` (6, 6) over the point's DOFs."""
    for c in range(2):
        h22, h23, h24 = side_hessian(c, dofs, ux0, uy0, q)
        Fc = F0 if c == 0 else F1
        for (j, n, h) in ((2, 2, h22), (2, 3, h23), (3, 2, h23), (2, 4, h24), (4, 2, h24)):
            p = m[j, n]
            if p >= 0:
                row[p] -= s * Fc * h


def turned(A, q, i, Fx, Fy):
    """The force of point item ``i`` of table ``A`` from its time value ``(Fx, Fy)``, and its
    derivative along the point's rotation psi: ``(F_x, F_y, dF_x/dpsi, dF_y/dpsi)``. A table
    with a field ``psi0`` (:data:`morphlab.kernels.pressure.FOLLOWERS`) turns the force with
    the point, ``F = A(psi - psi0) F_0``; any other (:data:`LOADS`) keeps its direction
    (module docstring). Decided when the kernel is typed, not per call."""


@overload(turned)
def _turned_typed(A, q, i, Fx, Fy):
    if "psi0" not in getattr(A, "fields", ()):
        return lambda A, q, i, Fx, Fy: (Fx, Fy, Fx * 0.0, Fy * 0.0)

    def follower(A, q, i, Fx, Fy):
        zero = q[0] * 0.0 + A.psi0[i] * 0.0
        psi = point_angle(point_dofs(A.dofs[i]), q, zero) - A.psi0[i]
        c, s = np.cos(psi), np.sin(psi)
        return c * Fx - s * Fy, s * Fx + c * Fy, -s * Fx - c * Fy, c * Fx - s * Fy
    return follower


@inner
def point_force_residual(A, q, wf, T, t, k, items, R):
    """Subtract ``wf grad^T F`` of the point forces ``items`` of table ``A`` (fixed-direction
    or follower forces, :func:`turned`) from the equation rows of ``R``."""
    if A is None:  # the model has none of this kind
        return
    for i in items:
        Fx, Fy, _, _ = turned(A, q, i, T.F[t, k, i, 0], T.F[t, k, i, 1])
        add_point_force(point_dofs(A.dofs[i]), A.u0[i, 0], A.u0[i, 1], q, wf, Fx, Fy, R)


@inner
def point_force_matrix(A, q, cf, T, t, k, C, out):
    """Add ``-cf d(grad^T F)/dq`` of the point forces of table ``A`` to the ``Dq`` part of
    ``out`` (m, nnz): the point's Hessian against ``F`` and, for a follower, ``grad^T
    dF/dpsi`` in the columns of theta and phi."""
    if A is None:  # the model has none of this kind
        return
    for i in range(A.dofs.shape[0]):
        dofs = point_dofs(A.dofs[i])
        m = A.map[i]
        Fx, Fy, dFx, dFy = turned(A, q, i, T.F[t, k, i, 0], T.F[t, k, i, 1])
        for r in range(C.shape[0]):
            cq = C[r, 1]
            if cq == 0.0:
                continue
            add_point_stiffness(dofs, A.u0[i, 0], A.u0[i, 1], q, cf * cq, Fx, Fy, m, out[r])
            if dFx == 0.0 and dFy == 0.0:  # a fixed direction (or no force)
                continue
            for comp in (ROW_X, ROW_Y):
                _, _, grad, _, _, _ = point_terms(comp, dofs, A.u0[i, 0], A.u0[i, 1], q, q, q)
                dF = dFx if comp == ROW_X else dFy
                for j in range(6):
                    for n in (2, 5):
                        if m[j, n] >= 0 and dofs[n] >= 0:
                            out[r, m[j, n]] -= cf * cq * grad[j] * dF


@inner
def line_residual(A, q, wf, T, t, k, items, R):
    """Subtract ``wf Q_ext`` of the line-load entries ``items`` from the equation rows of
    ``R`` (module docstring)."""
    if A is None:  # the model has none of this kind
        return
    for e in items:
        qx, qy = wf * T.q[t, k, e, 0], wf * T.q[t, k, e, 1]
        ref = A.ref[e]
        c, s = np.cos(q[ref[2]]), np.sin(q[ref[2]])
        ax, ay = c * qx + s * qy, c * qy - s * qx  # A^T q; (AĨ)^T q = (ay, -ax)
        mom = ay * A.u0[e, 1] - ax * A.u0[e, 2]
        for j in range(6):
            d = A.dofs[e, j]
            if d >= 0:
                mom += (ay * A.N[e, 0, j] - ax * A.N[e, 1, j]) * q[d]
                R[d] -= ax * A.N[e, 0, j] + ay * A.N[e, 1, j]
        R[ref[0]] -= A.u0[e, 0] * qx
        R[ref[1]] -= A.u0[e, 0] * qy
        R[ref[2]] -= mom


@inner
def line_matrix(A, q, cf, T, t, k, C, out):
    """Add ``-cf d(Q_ext)/dq`` of the line loads to the ``Dq`` part of ``out`` (m, nnz):
    ``dQ_theta/dtheta = -A^T q . (U + N d)``, ``dQ_theta/dd = dQ_d/dtheta = N^T (AĨ)^T q``."""
    if A is None:  # the model has none of this kind
        return
    for e in range(A.ref.shape[0]):
        m = A.map[e]
        th = q[A.ref[e, 2]]
        c, s = np.cos(th), np.sin(th)
        for r in range(C.shape[0]):
            scale = cf * C[r, 1]
            if scale == 0.0:
                continue
            qx, qy = scale * T.q[t, k, e, 0], scale * T.q[t, k, e, 1]
            ax, ay = c * qx + s * qy, c * qy - s * qx
            mom = ax * A.u0[e, 1] + ay * A.u0[e, 2]
            for j in range(6):
                d = A.dofs[e, j]
                if d >= 0:
                    mom += (ax * A.N[e, 0, j] + ay * A.N[e, 1, j]) * q[d]
                    h = ay * A.N[e, 0, j] - ax * A.N[e, 1, j]
                    if m[0, 1 + j] >= 0:
                        out[r, m[0, 1 + j]] -= h
                    if m[1 + j, 0] >= 0:
                        out[r, m[1 + j, 0]] -= h
            if m[0, 0] >= 0:
                out[r, m[0, 0]] += mom
