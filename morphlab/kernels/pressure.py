"""Follower loads: pressure on beams and point forces that turn with the body. Two optional
kinds: :data:`PRESSURES` and :data:`FOLLOWERS`.

**Pressure.** A pressure ``p`` [force/area] on a beam of width ``b`` acts normal to the
*deformed* centre line. With ``P = p b`` [force/length] and ``r(s)`` the deformed centre line,
the force on a piece ``ds`` of the undeformed line is ``P Ĩ r' ds`` (``r' = dr/ds``, ``Ĩ =
[[0, -1], [1, 0]]``: the left normal of the direction of the nodes' order, scaled by the
stretch). On an element of a frame ``(R, theta)``, with ``r = R + A (u0 + S d)`` and ``P``
linear between the element's nodal values ``P_1, P_2`` (shape functions ``N_1 = 1 - xi``,
``N_2 = xi``), the virtual work ``int P Ĩ r' . dr ds`` gives the generalized forces
(``docs/theory.md`` §4.7)::

    Q_R     = A Ĩ sum_a P_a (c_a + D_a d)
    Q_theta =     sum_a P_a (e_a + f_a . d + d . H_a d)
    Q_d     =     sum_a P_a (g_a + G_a d)

with the element integrals (undeformed, in the frame; ``u0' = du0/ds``, ``S' = dS/ds``)::

    c_a = int N_a u0' ds        D_a = int N_a S' ds         e_a = int N_a u0 . u0' ds
    f_a = int N_a (S^T u0' + S'^T u0) ds                   H_a = int N_a S^T S' ds
    g_a = int N_a S^T Ĩ u0' ds  G_a = int N_a S^T Ĩ S' ds

(``(AĨ)^T AĨ = 1`` and ``A^T A Ĩ = Ĩ``: only ``Q_R`` depends on the frame angle). The load is
not conservative: its stiffness ``-dQ/dq`` is not symmetric (``G_a`` is not), and it is exact
here, so Newton converges quadratically under a follower load.

**Follower force.** A point force whose direction turns with the material point's rotation
``psi`` (the body angle, plus the nodal rotation at a beam node): ``F = A(psi - psi_0) F_0``,
``F_0`` given in the initial configuration. Its generalized force is ``grad^T F`` with the
gradient of the point's position (:func:`morphlab.kernels.joints.side_terms`). Its kernels are
those of the fixed-direction point force (:func:`morphlab.kernels.loads.point_force_residual`,
:func:`~morphlab.kernels.loads.point_force_matrix`), which turn a table's forces when it has
the field ``psi0``.

Both residuals are linear in the load values (time fields): the pseudo-loads of a load's
magnitude are these kernels evaluated with its derivative in its place. The pressure is
linear in its integrals too, but not in integrals and load values together (it is bilinear):
the integrals, which change with the beam's geometry, take the perturbed path.
"""

import numpy as np

from ._jit import inner
from .schema import Kind, design, pattern, register, timed, topology

PRESSURES = register(Kind("pressures", [
    design("c", (2, 2), "int N_a u0' ds"),
    design("D", (2, 2, 6), "int N_a S' ds"),
    design("e", (2,), "int N_a u0 . u0' ds"),
    design("f", (2, 6), "int N_a (S^T u0' + S'^T u0) ds"),
    design("H", (2, 6, 6), "int N_a S^T S' ds"),
    design("g", (2, 6), "int N_a S^T Ĩ u0' ds"),
    design("G", (2, 6, 6), "int N_a S^T Ĩ S' ds"),
    topology("ref", (3,), "DOFs R_x, R_y, theta of the element's frame"),
    topology("dofs", (6,), "global DOF of each element DOF (-1: removed)"),
    pattern("map", (9, 9), "positions over (R_x, R_y, theta, d_0 .. d_5)"),
    timed("P", (2,), "pressure times width at the element's nodes [force/length]",
          linear=True),
], "a loaded element of a follower pressure",
   optional=True, timing="scale", work=True, module=__name__))

FOLLOWERS = register(Kind("followers", [
    design("u0", (2,), "body-frame point of application"),
    design("psi0", (), "initial rotation of the point (body angle + nodal rotation)"),
    topology("dofs", (6,), "DOFs R_x, R_y, theta, u, v, phi of the point"),
    pattern("map", (6, 6), "positions over the point's DOFs"),
    timed("F", (2,), "the force in the initial configuration's axes [force]", linear=True),
], "a point force that turns with the material point",
   optional=True, timing="scale", work=True, module=__name__))


def _local(ref: np.ndarray, dofs: np.ndarray) -> np.ndarray:
    """``(n, 9)``: the DOFs (R_x, R_y, theta, d_0 .. d_5) of each pressure entry."""
    return np.concatenate([ref, dofs], axis=1)


#: The (row, column) entries of ``-dQ/dq`` of a pressure entry over its local DOFs: the
#: force rows against theta and d, the moment row against d, the d rows against d.
PRESSURE_ENTRIES = np.zeros((9, 9), dtype=bool)
PRESSURE_ENTRIES[0:2, 2:] = True
PRESSURE_ENTRIES[2, 3:] = True
PRESSURE_ENTRIES[3:, 3:] = True


@PRESSURES.pattern_of
def pressure_coordinates(S, n_dof: int) -> dict:
    """(row, column) of the pressure entries (:data:`PRESSURE_ENTRIES`)."""
    local = _local(S.pressures.ref, S.pressures.dofs)
    n = local.shape[0]
    rows = np.broadcast_to(local[:, :, None], (n, 9, 9))
    cols = np.broadcast_to(local[:, None, :], (n, 9, 9))
    ok = PRESSURE_ENTRIES[None] & (rows >= 0) & (cols >= 0)
    return {"map": (np.where(ok, rows, -1), np.where(ok, cols, -1))}


@FOLLOWERS.pattern_of
def follower_coordinates(S, n_dof: int) -> dict:
    """(row, column) of the follower forces' entries: every pair of the point's DOFs."""
    dofs = S.followers.dofs
    n = dofs.shape[0]
    rows = np.broadcast_to(dofs[:, :, None], (n, 6, 6))
    cols = np.broadcast_to(dofs[:, None, :], (n, 6, 6))
    ok = (rows >= 0) & (cols >= 0)
    return {"map": (np.where(ok, rows, -1), np.where(ok, cols, -1))}


@inner
def _scratch(A, q):
    """Room for an element's six coordinates, of the scalar type of state and data."""
    return np.zeros(6) + (q[0] * 0.0 + A.e[0, 0] * 0.0)


@inner
def _coordinates(A, q, e, d):
    """Write the coordinates of pressure entry ``e``'s element into ``d`` (6,): its frame's
    flexible coordinates of both nodes, 0 where a coordinate is removed."""
    for j in range(6):
        d[j] = 0.0
        if A.dofs[e, j] >= 0:
            d[j] = q[A.dofs[e, j]]


@inner
def pressure_residual(A, q, wf, T, t, k, items, R):
    """Subtract ``wf Q_ext`` of the pressure entries ``items`` from the equation rows of ``R``
    (module docstring)."""
    if A is None:  # the model has none of this kind
        return
    d = _scratch(A, q)
    for e in items:
        ref = A.ref[e]
        zero = q[0] * 0.0 + A.e[e, 0] * 0.0
        _coordinates(A, q, e, d)
        vx, vy, mom = zero, zero, zero
        for a in range(2):
            P = wf * T.P[t, k, e, a]
            if P == 0.0:
                continue
            ux, uy, m = A.c[e, a, 0] + zero, A.c[e, a, 1] + zero, A.e[e, a] + zero
            for j in range(6):
                ux += A.D[e, a, 0, j] * d[j]
                uy += A.D[e, a, 1, j] * d[j]
                Hd = zero
                Gd = A.g[e, a, j] + zero
                for i in range(6):
                    Hd += A.H[e, a, j, i] * d[i]
                    Gd += A.G[e, a, j, i] * d[i]
                m += (A.f[e, a, j] + Hd) * d[j]
                dj = A.dofs[e, j]
                if dj >= 0:
                    R[dj] -= P * Gd
            vx += P * ux
            vy += P * uy
            mom += P * m
        th = q[ref[2]]
        c, s = np.cos(th), np.sin(th)
        # A Ĩ v = A (-v_y, v_x)
        R[ref[0]] -= -c * vy - s * vx
        R[ref[1]] -= -s * vy + c * vx
        R[ref[2]] -= mom


@inner
def pressure_matrix(A, q, cf, T, t, k, C, out):
    """Add ``-cf d(Q_ext)/dq`` of the pressure entries to the ``Dq`` part of ``out`` (m, nnz):
    ``dQ_R/dtheta = -A v``, ``dQ_R/dd = A Ĩ sum P_a D_a``, ``dQ_theta/dd = sum P_a (f_a +
    (H_a + H_a^T) d)``, ``dQ_d/dd = sum P_a G_a``."""
    if A is None:  # the model has none of this kind
        return
    d = _scratch(A, q)
    for r in range(C.shape[0]):
        cq = C[r, 1]
        if cq == 0.0:
            continue
        data = out[r]
        for e in range(A.ref.shape[0]):
            m = A.map[e]
            zero = q[0] * 0.0 + A.e[e, 0] * 0.0
            _coordinates(A, q, e, d)
            th = q[A.ref[e, 2]]
            c, s = np.cos(th), np.sin(th)
            for a in range(2):
                P = cf * cq * T.P[t, k, e, a]
                if P == 0.0:
                    continue
                vx, vy = A.c[e, a, 0] + zero, A.c[e, a, 1] + zero
                for j in range(6):
                    vx += A.D[e, a, 0, j] * d[j]
                    vy += A.D[e, a, 1, j] * d[j]
                # -dQ_R/dtheta = A v
                if m[0, 2] >= 0:
                    data[m[0, 2]] += P * (c * vx - s * vy)
                if m[1, 2] >= 0:
                    data[m[1, 2]] += P * (s * vx + c * vy)
                for j in range(6):
                    Dx, Dy = A.D[e, a, 0, j], A.D[e, a, 1, j]
                    if m[0, 3 + j] >= 0:
                        data[m[0, 3 + j]] -= P * (-c * Dy - s * Dx)
                    if m[1, 3 + j] >= 0:
                        data[m[1, 3 + j]] -= P * (-s * Dy + c * Dx)
                    if m[2, 3 + j] >= 0:
                        h = A.f[e, a, j] + zero
                        for i in range(6):
                            h += (A.H[e, a, j, i] + A.H[e, a, i, j]) * d[i]
                        data[m[2, 3 + j]] -= P * h
                    for i in range(6):
                        p = m[3 + i, 3 + j]
                        if p >= 0:
                            data[p] -= P * A.G[e, a, i, j]
