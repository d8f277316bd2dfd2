"""Spring-damper elements with exact derivatives (:data:`SPRINGS`, an optional kind).

A spring-damper acts between two sides P and Q, each described like a constraint side
(:mod:`morphlab.kernels.joints`: six DOFs ``R_x, R_y, theta, u, v, phi``, ``-1`` where absent,
all ``-1`` for the ground, and a body-frame point). It measures a scalar ``s(q)``:

* :data:`SPRING_LENGTH` (0): the distance ``l = |d|`` of the points, ``d = r_P - r_Q``
  (a translational spring; the ground side's point is its global position);
* :data:`SPRING_ANGLE` (1): the relative rotation ``(theta_P + phi_P) - (theta_Q + phi_Q)``.

Its force ``f = k (s - s0) + c s' + f0`` (``springs.par[i] = (k, c, s0, f0)``, ``s' = grad s
. q'``) adds ``wf f grad s`` to the equation rows. The Newton matrix of the step, with
``q = q_hat + bh2 a`` and ``q' = v_hat + gh a``, is
``wf [bh2 (grad s (k grad s + c H q')^T + f H) + gh c grad s grad s^T]``, ``H = d²s/dq²``:
for the length
``H = (D^T (I - e e^T) D) / l + e_x H_x + e_y H_y`` (``D = dd/dq``, ``e = d / l``, ``H_x``,
``H_y`` the point Hessians of the two components), zero for the angle
(``docs/theory.md`` §4.6).
"""

import numpy as np

from ._jit import inner, kernel
from .joints import point_angle, point_dofs, point_terms
from .schema import Kind, design, pattern, register, topology

#: Kinds of spring-damper (``springs.kind``): distance of two points, relative rotation.
SPRING_LENGTH, SPRING_ANGLE = 0, 1

SPRINGS = register(Kind("springs", [
    design("u0", (2, 2), "body-frame point of each side (ground: its global position)"),
    design("par", (4,), "k, c, s0, f0"),
    topology("kind", (), "SPRING_LENGTH or SPRING_ANGLE"),
    topology("dofs", (2, 6), "DOFs of each side, as a constraint row's"),
    pattern("map", (2, 2, 6, 6), "positions of (row DOF j of side r, column DOF k of side c)"),
], "a spring-damper between two points or two bodies' rotations",
   optional=True, module=__name__))


@SPRINGS.pattern_of
def coordinates(S, n_dof: int) -> dict:
    """(row, column) of the spring entries: every pair of the DOFs its measure depends on
    (``R, theta, u, v`` of both points for a length, ``theta, phi`` for an angle)."""
    A = S.springs
    n = A.dofs.shape[0]
    used = np.where((A.kind == SPRING_ANGLE)[:, None], np.array([0, 0, 1, 0, 0, 1], bool),
                    np.array([1, 1, 1, 1, 1, 0], bool))
    d = np.where(used[:, None, :], A.dofs, -1)  # (n, 2, 6)
    rows = np.broadcast_to(d[:, :, None, :, None], (n, 2, 2, 6, 6))
    cols = np.broadcast_to(d[:, None, :, None, :], (n, 2, 2, 6, 6))
    ok = (rows >= 0) & (cols >= 0)
    return {"map": (np.where(ok, rows, -1), np.where(ok, cols, -1))}


@inner
def _put(G, row, off, t, sign):
    """``G[row, off:off + 6] = sign t`` for a 6-tuple ``t``."""
    G[row, off] = sign * t[0]
    G[row, off + 1] = sign * t[1]
    G[row, off + 2] = sign * t[2]
    G[row, off + 3] = sign * t[3]
    G[row, off + 4] = sign * t[4]
    G[row, off + 5] = sign * t[5]


@inner
def _terms(A, i, q, v, G):
    """Measure ``s`` and rate ``s'`` of spring ``i``, with its derivatives over the twelve
    local DOFs (side P's six, then side Q's) in ``G`` (6, 12): row 0 ``grad s``, row 1
    ``H q'``, rows 2 and 3 the signed gradients ``D_x``, ``D_y`` of ``d = r_P - r_Q``, row 4
    the local velocities; row 5 holds, at columns ``6 side + (0, 1, 2)``, the entries
    ``(theta, theta), (theta, w_x), (theta, w_y)`` of ``e_x H_x + e_y H_y`` of that side.
    Returns ``(s, s', e_x, e_y, l)`` (``e``, ``l`` of a length; 0, 0, 1 for an angle).

    The point Hessians follow from the gradients: ``H_k(theta, theta) = -(A u)_k`` with
    ``A u = (D_y, -D_x)`` at theta, ``H_k(theta, w_x) = D_k(w_y)`` and
    ``H_k(theta, w_y) = -D_k(w_x)`` (``docs/theory.md`` §4.1)."""
    dofs, u = A.dofs[i], A.u0
    zero = q[0] * 0.0 + u[i, 0, 0] * 0.0
    for col in range(12):
        d = dofs[col // 6, col % 6]
        for row in range(6):
            G[row, col] = 0.0
        if d >= 0:
            G[4, col] = v[d]
    dP, dQ = point_dofs(dofs[0]), point_dofs(dofs[1])
    if A.kind[i] == SPRING_ANGLE:
        for col in (2, 5):
            G[0, col] = 1.0
            G[0, col + 6] = -1.0
        s = point_angle(dP, q, zero) - point_angle(dQ, q, zero)
        sd = point_angle(dP, v, zero) - point_angle(dQ, v, zero)
        return s, sd, zero, zero, zero + 1.0
    # a ground side (no DOFs) gives its body-frame point: its global position
    xP, _, DxP, _, _, _ = point_terms(np.int64(0), dP, u[i, 0, 0], u[i, 0, 1], q, v, v)
    yP, _, DyP, _, _, _ = point_terms(np.int64(1), dP, u[i, 0, 0], u[i, 0, 1], q, v, v)
    xQ, _, DxQ, _, _, _ = point_terms(np.int64(0), dQ, u[i, 1, 0], u[i, 1, 1], q, v, v)
    yQ, _, DyQ, _, _, _ = point_terms(np.int64(1), dQ, u[i, 1, 0], u[i, 1, 1], q, v, v)
    _put(G, 2, 0, DxP, 1.0)
    _put(G, 3, 0, DyP, 1.0)
    _put(G, 2, 6, DxQ, -1.0)
    _put(G, 3, 6, DyQ, -1.0)
    dx, dy = xP - xQ, yP - yQ
    ell = np.sqrt(dx * dx + dy * dy)
    ex, ey = dx / ell, dy / ell
    vx, vy = zero, zero  # the relative velocity D q'
    for col in range(12):
        vx += G[2, col] * G[4, col]
        vy += G[3, col] * G[4, col]
    sd = ex * vx + ey * vy
    # H q' = D^T (I - e e^T) D q' / l + (e_x H_x + e_y H_y) q'
    px, py = (vx - ex * sd) / ell, (vy - ey * sd) / ell
    for col in range(12):
        G[0, col] = ex * G[2, col] + ey * G[3, col]
        G[1, col] = G[2, col] * px + G[3, col] * py
    for b in (0, 6):
        t, wx, wy = b + 2, b + 3, b + 4
        htt = ey * G[2, t] - ex * G[3, t]
        htx = ex * G[2, wy] + ey * G[3, wy]
        hty = -(ex * G[2, wx] + ey * G[3, wx])
        G[5, b], G[5, b + 1], G[5, b + 2] = htt, htx, hty
        G[1, t] += htt * G[4, t] + htx * G[4, wx] + hty * G[4, wy]
        G[1, wx] += htx * G[4, t]
        G[1, wy] += hty * G[4, t]
    return ell, sd, ex, ey, ell


@inner
def residual(A, x, wf, items, R):
    """Add ``wf f grad s`` of the spring-dampers ``items`` (int64 indices) to the equation
    rows of ``R``."""
    if A is None:  # the model has none of this kind
        return
    G = np.zeros((6, 12), dtype=R.dtype)
    for i in items:
        s, sd, _, _, _ = _terms(A, i, x.q, x.v, G)
        f = A.par[i, 0] * (s - A.par[i, 2]) + A.par[i, 1] * sd + A.par[i, 3]
        for col in range(12):
            d = A.dofs[i, col // 6, col % 6]
            if d >= 0:
                R[d] += wf * f * G[0, col]


@inner
def matrix(A, x, cf, C, out):
    """Add ``d(wf f grad s)/da`` of every spring-damper (weight ``cf``) to ``out`` (m, nnz):
    the ``Dq`` and ``Dv`` parts (no ``D0``) weighted by ``C[r, 1]``, ``C[r, 2]``."""
    if A is None:  # the model has none of this kind
        return
    G = np.zeros((6, 12), dtype=out.dtype)
    for i in range(A.kind.shape[0]):
        s, sd, _, _, ell = _terms(A, i, x.q, x.v, G)
        k, c = A.par[i, 0], A.par[i, 1]
        f = k * (s - A.par[i, 2]) + c * sd + A.par[i, 3]
        length = A.kind[i] == SPRING_LENGTH
        for m in range(C.shape[0]):
            cq, cv = C[m, 1], C[m, 2]
            if cq == 0.0 and cv == 0.0:
                continue
            data = out[m]
            for row in range(12):
                r, j = row // 6, row % 6
                for col in range(12):
                    cs, kk = col // 6, col % 6
                    p = A.map[i, r, cs, j, kk]
                    if p < 0:
                        continue
                    gg = G[0, row] * G[0, col]
                    val = cq * (k * gg + c * G[0, row] * G[1, col]) + cv * c * gg
                    if length:
                        H = (G[2, row] * G[2, col] + G[3, row] * G[3, col] - gg) / ell
                        if r == cs and (j == 2 or kk == 2):
                            o = j + kk - 2  # 2: (theta, theta); 3: (theta, w_x); 4: (w_y)
                            if o >= 2 and o <= 4:
                                H += G[5, 6 * r + o - 2]
                        val += cq * f * H
                    data[p] += cf * val


@kernel
def measures(A, Q, V, out):
    """The measure ``s`` and its rate ``s'`` of every spring-damper at every stored time:
    ``Q, V`` (n_t, n_dof), ``out`` (n_t, n_spring, 2)."""
    if A is None:  # the model has none of this kind
        return
    G = np.zeros((6, 12), dtype=out.dtype)
    for t in range(Q.shape[0]):
        for i in range(A.kind.shape[0]):
            s, sd, _, _, _ = _terms(A, i, Q[t], V[t], G)
            out[t, i, 0] = s
            out[t, i, 1] = sd
