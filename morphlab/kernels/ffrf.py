"""Planar FFRF bodies: mass matrix, quadratic-velocity, gravity and elastic forces, and their
exact derivatives, for all bodies of a system in one call.

Three kinds of item hold a body's data (:data:`BODIES`, :data:`FLEX`, :data:`ELEMENTS`).
Every body — rigid or flexible — has reference coordinates ``(R_x, R_y, theta)`` at the DOFs
``bodies.ref[b]`` and scalar invariants ``bodies.scal[b] = (m, I_u_x, I_u_y, I_00)``. A
flexible body owns the flexible coordinates ``bodies.flex[b, 0] <= k < bodies.flex[b, 1]``:
the global DOF of each retained deformation coordinate (``flex.dof``) and the invariants
``I_S`` (``flex.IS``), ``I_0S`` and ``I_0ĨS``. Its elements hold their body-frame matrices
``M_ff``, ``S̃`` and ``K_ff`` (6 x 6) and the flexible coordinate of each element DOF
(``elements.fdof``, ``-1`` where the reference condition removes the DOF). A rigid body is the
special case with no flexible coordinates (``I_u = 0``: its reference point is the centre of
mass).

With ``c_u = I_u + I_S q_f``, ``A = Rot(theta)`` and ``Ĩ = [[0, -1], [1, 0]]``
(``docs/theory.md`` §2.5-§2.9)::

    M a   = [ m a_R + AĨ c_u a_th + A I_S a_f ;
              (AĨ c_u).a_R + M_thth a_th + (I_0ĨS + S̃ q_f).a_f ;
              I_S^T A^T a_R + (I_0ĨS + S̃ q_f) a_th + M_ff a_f ]
    M_thth = I_00 + 2 I_0S.q_f + q_f^T M_ff q_f
    Q_v   = [ th'^2 A c_u - 2 th' AĨ I_S q_f' ;
              -2 th' (I_0S + M_ff q_f).q_f' ;
              th'^2 (I_0S + M_ff q_f) - 2 th' S̃ q_f' ]
    Q_g   = [ m g ; (AĨ c_u).g ; I_S^T A^T g ]

and the body's share of the residual is ``w_m M(q) a + w_f (K q_f + beta_d K q_f' - Q_v -
Q_g)``. With the damping ``beta_d`` and the gravity ``g`` held, the share is linear in the
remaining design data (invariants and element matrices together): a sensitivity pseudo-load
of a section or material variable is this kernel evaluated with the data's derivatives in
their place (``morphlab.kernels.pseudo``).

The kernels run unchanged for float64 and complex128 (all arrays of one call share the
dtype). A call evaluates the parts of :class:`~morphlab.kernels.system.Parts` it is given:
every body and element for a step, those a design variable changes for a pseudo-load, at a
cost that grows with the parts: the gathered coordinates and element products live in a
:class:`Scratch` that is zero between calls.
"""

from typing import NamedTuple

import numpy as np

from ._jit import inner
from .schema import Kind, design, pattern, register, topology

BODIES = register(Kind("bodies", [
    design("scal", (4,), "m, I_u_x, I_u_y, I_00", linear=True),
    design("damp", (), "stiffness-proportional damping beta_d"),
    topology("ref", (3,), "DOFs of R_x, R_y, theta"),
    topology("flex", (2,), "the body's flexible coordinates: first, stop"),
    pattern("block", (3, 3), "positions of the 3 x 3 reference block"),
], "one floating frame: a rigid body, or one frame of a beam", module=__name__))

FLEX = register(Kind("flex", [
    design("IS", (2,), "I_S of the coordinate", linear=True),
    design("I0S", (), "I_0S", linear=True),
    design("I0IS", (), "I_0ĨS", linear=True),
    topology("dof", (), "global DOF of the coordinate"),
    pattern("border", (2, 3), "positions of (reference row i, this column), then "
                              "(this row, reference column i)"),
], "a flexible (deformation) coordinate of a body", module=__name__))

ELEMENTS = register(Kind("elements", [
    design("M", (6, 6), "element M_ff in the body frame", linear=True),
    design("St", (6, 6), "element S̃", linear=True),
    design("K", (6, 6), "element stiffness", linear=True),
    design("B", (2, 2, 6), "stress map: ends x fibres x element DOFs (results only)",
           linear=True),
    topology("body", (), "the body of the element"),
    topology("fdof", (6,), "flexible coordinate of each element DOF (-1: removed)"),
    topology("dofs", (6,), "global DOF of each element DOF (-1: removed; results only)"),
    pattern("map", (6, 6), "positions of the element entries"),
], "an Euler-Bernoulli beam element of a body", module=__name__))


@BODIES.pattern_of
def body_coordinates(S, n_dof: int) -> dict:
    """(row, column) of each body's 3 x 3 reference block."""
    ref = S.bodies.ref
    return {"block": (ref[:, :, None], ref[:, None, :])}


@FLEX.pattern_of
def flex_coordinates(S, n_dof: int) -> dict:
    """(row, column) of each coordinate's border entries with its body's reference
    coordinates: (reference row i, this column), then (this row, reference column i)."""
    B, Fx = S.bodies, S.flex
    owner = np.repeat(np.arange(B.ref.shape[0]), B.flex[:, 1] - B.flex[:, 0])
    ref = B.ref[owner]  # (n_flex, 3)
    dof = np.broadcast_to(Fx.dof[:, None], ref.shape)
    return {"border": (np.stack([ref, dof], axis=1), np.stack([dof, ref], axis=1))}


@ELEMENTS.pattern_of
def element_coordinates(S, n_dof: int) -> dict:
    """(row, column) of the element entries (-1 for removed DOFs)."""
    fd = S.elements.fdof
    gd = np.where(fd >= 0, S.flex.dof[np.maximum(fd, 0)] if S.flex.dof.size else -1, -1)
    return {"map": (gd[:, :, None], gd[:, None, :])}


class Scratch(NamedTuple):
    """Zero-between-calls work arrays of the body kernels: ``q`` (3, n_flex + 1) the gathered
    ``q_f, q_f', q_f''``; ``p`` (7, n_flex + 1) the element products ``M q, M q', M a, S̃ q,
    S̃ q', S̃ a, K (q + beta q')``; ``idx`` (6,) int64 and ``loc`` (4, 6): one element's
    coordinates, values and damped values. Column ``n_flex`` stands for removed DOFs."""

    q: np.ndarray
    p: np.ndarray
    idx: np.ndarray
    loc: np.ndarray


def scratch(n_flex: int, like: np.ndarray) -> Scratch:
    """A :class:`Scratch` for ``n_flex`` coordinates in the dtype of ``like`` (allocated in
    NumPy: only Python asks for one, once per run or sensitivity set-up)."""
    m, dt = n_flex + 1, like.dtype
    return Scratch(np.zeros((3, m), dtype=dt), np.zeros((7, m), dtype=dt),
                   np.zeros(6, dtype=np.int64), np.zeros((4, 6), dtype=dt))


@inner
def _gather(B, Fx, E, x, bodies, elems, flex_on, W):
    """Gather ``q_f, q_f', q_f''`` of the coordinates of ``elems`` and the masked coordinates
    of ``bodies`` into ``W.q``."""
    fdof, dof = E.fdof, Fx.dof
    Wq = W.q
    for e in elems:
        for i in range(6):
            f = fdof[e, i]
            if f >= 0:
                Wq[0, f] = x.q[dof[f]]
                Wq[1, f] = x.v[dof[f]]
                Wq[2, f] = x.a[dof[f]]
    for b in bodies:
        for k in range(B.flex[b, 0], B.flex[b, 1]):
            if flex_on[k]:
                Wq[0, k] = x.q[dof[k]]
                Wq[1, k] = x.v[dof[k]]
                Wq[2, k] = x.a[dof[k]]


@inner
def _products(B, E, elems, full, W):
    """Add the element products of ``elems`` to ``W.p`` from ``W.q``: ``M q, S̃ q, S̃ q'``
    always; with ``full`` (the matrix) ``M q', S̃ a``, else (the residual) ``M a`` and the
    elastic plus damping force ``K (q_f + beta q_f')``."""
    n_flex = W.q.shape[1] - 1
    qf, vf, af = W.q[0], W.q[1], W.q[2]
    Mq, Mv, Ma, Sq, Sv, Sa, Kd = W.p[0], W.p[1], W.p[2], W.p[3], W.p[4], W.p[5], W.p[6]
    idx = W.idx
    ql, vl, al, dl = W.loc[0], W.loc[1], W.loc[2], W.loc[3]
    for e in elems:
        beta = B.damp[E.body[e]]
        for i in range(6):
            f = E.fdof[e, i]
            idx[i] = f if f >= 0 else n_flex
            ql[i] = qf[idx[i]]
            vl[i] = vf[idx[i]]
            al[i] = af[idx[i]]
            dl[i] = ql[i] + beta * vl[i]
        Me, Se, Ke = E.M[e], E.St[e], E.K[e]
        for i in range(6):
            mq = 0.0 * dl[0]
            sq = 0.0 * dl[0]
            sv = 0.0 * dl[0]
            for j in range(6):
                mq += Me[i, j] * ql[j]
                sq += Se[i, j] * ql[j]
                sv += Se[i, j] * vl[j]
            k = idx[i]
            Mq[k] += mq
            Sq[k] += sq
            Sv[k] += sv
            if full:
                mv = 0.0 * dl[0]
                sa = 0.0 * dl[0]
                for j in range(6):
                    mv += Me[i, j] * vl[j]
                    sa += Se[i, j] * al[j]
                Mv[k] += mv
                Sa[k] += sa
            else:
                ma = 0.0 * dl[0]
                kd = 0.0 * dl[0]
                for j in range(6):
                    ma += Me[i, j] * al[j]
                    kd += Ke[i, j] * dl[j]
                Ma[k] += ma
                Kd[k] += kd


@inner
def _clear(B, E, bodies, elems, flex_on, W):
    """Zero what :func:`_gather` and :func:`_products` wrote (the column ``n_flex`` too)."""
    n_flex = W.q.shape[1] - 1
    for e in elems:
        for i in range(6):
            f = E.fdof[e, i]
            k = f if f >= 0 else n_flex
            for r in range(3):
                W.q[r, k] = 0.0
            for r in range(7):
                W.p[r, k] = 0.0
    for b in bodies:
        for k in range(B.flex[b, 0], B.flex[b, 1]):
            if flex_on[k]:
                for r in range(3):
                    W.q[r, k] = 0.0
                for r in range(7):
                    W.p[r, k] = 0.0


@inner
def _sums(B, Fx, b, flex_on, W):
    """Reductions over a body's coordinates (those with ``flex_on`` set): ``c_u`` (2),
    ``I_S a_f`` (2), ``I_S q_f'`` (2), ``I_0S.q_f``, ``I_0S.q_f'``, ``q_f^T M q_f``,
    ``q_f^T M q_f'``, ``I_0ĨS.a_f`` and ``(S̃ q_f).a_f``."""
    qf, vf, af = W.q[0], W.q[1], W.q[2]
    Mq, Sq = W.p[0], W.p[3]
    m = B.scal[b, 0]
    cux = B.scal[b, 1]
    cuy = B.scal[b, 2]
    isax = 0.0 * m
    isay = 0.0 * m
    isvx = 0.0 * m
    isvy = 0.0 * m
    i0s_q = 0.0 * m
    i0s_v = 0.0 * m
    qMq = 0.0 * m
    qMv = 0.0 * m
    i0is_a = 0.0 * m
    sq_a = 0.0 * m
    for k in range(B.flex[b, 0], B.flex[b, 1]):
        if not flex_on[k]:
            continue
        cux += Fx.IS[k, 0] * qf[k]
        cuy += Fx.IS[k, 1] * qf[k]
        isax += Fx.IS[k, 0] * af[k]
        isay += Fx.IS[k, 1] * af[k]
        isvx += Fx.IS[k, 0] * vf[k]
        isvy += Fx.IS[k, 1] * vf[k]
        i0s_q += Fx.I0S[k] * qf[k]
        i0s_v += Fx.I0S[k] * vf[k]
        qMq += qf[k] * Mq[k]
        qMv += Mq[k] * vf[k]
        i0is_a += Fx.I0IS[k] * af[k]
        sq_a += Sq[k] * af[k]
    return cux, cuy, isax, isay, isvx, isvy, i0s_q, i0s_v, qMq, qMv, i0is_a, sq_a


class Frame(NamedTuple):
    """What a body's terms of the residual and the step matrix read of its frame: the
    reference rows ``iR0, iR1, ith``, the mass ``m``, ``thd, tha`` (theta', theta''), ``c, s``
    (cos and sin theta); the reductions of :func:`_sums` (``cux, cuy`` = c_u, ``isa*`` = I_S
    a_f, ``isv*`` = I_S q_f', ``i0s_q, i0s_v`` = I_0S.q_f, I_0S.q_f', ``qMq, qMv`` = q_f^T M
    q_f, q_f^T M q_f', ``i0is_a``, ``sq_a``); their rotations ``Ac*`` = A c_u, ``AIc*`` = AĨ
    c_u, ``Aisa_*`` = A I_S a_f, ``AIisa_*``, ``Aisv_*`` = A I_S q_f', ``AIisv_*``; ``aRx,
    aRy`` the reference acceleration and ``mthth`` = I_thth + 2 I_0S.q_f + q_f^T M q_f."""

    iR0: int
    iR1: int
    ith: int
    m: float
    thd: float
    tha: float
    c: float
    s: float
    cux: float
    cuy: float
    isax: float
    isay: float
    isvx: float
    isvy: float
    i0s_q: float
    i0s_v: float
    qMq: float
    qMv: float
    i0is_a: float
    sq_a: float
    Acx: float
    Acy: float
    AIcx: float
    AIcy: float
    Aisa_x: float
    Aisa_y: float
    AIisa_x: float
    AIisa_y: float
    Aisv_x: float
    Aisv_y: float
    AIisv_x: float
    AIisv_y: float
    aRx: float
    aRy: float
    mthth: float


@inner
def frame(B, b, q, v, a, sums):
    """Body ``b``'s :class:`Frame` at the state ``q, v, a`` from its reductions ``sums``
    (:func:`_sums`, taken by the caller: a helper that gathered them itself would receive the
    body's tables and scratch by value, which costs more than the frame)."""
    iR0, iR1, ith = B.ref[b, 0], B.ref[b, 1], B.ref[b, 2]
    c, s = np.cos(q[ith]), np.sin(q[ith])
    cux, cuy, isax, isay, isvx, isvy, i0s_q, i0s_v, qMq, qMv, i0is_a, sq_a = sums
    Acx, Acy = c * cux - s * cuy, s * cux + c * cuy
    Aisa_x, Aisa_y = c * isax - s * isay, s * isax + c * isay
    Aisv_x, Aisv_y = c * isvx - s * isvy, s * isvx + c * isvy
    return Frame(iR0, iR1, ith, B.scal[b, 0], v[ith], a[ith], c, s, cux, cuy, isax, isay, isvx,
                 isvy, i0s_q, i0s_v, qMq, qMv, i0is_a, sq_a, Acx, Acy, -Acy, Acx, Aisa_x,
                 Aisa_y, -Aisa_y, Aisa_x, Aisv_x, Aisv_y, -Aisv_y, Aisv_x, a[iR0], a[iR1],
                 B.scal[b, 3] + 2.0 * i0s_q + qMq)


@inner
def residual(B, Fx, E, g, x, w, bodies, elems, flex_on, R, W):
    """Add ``w.wm M(q) a + w.wf (K q_f + beta_d K q_f' - Q_v - Q_g)`` of the bodies
    ``bodies`` (with the elements ``elems`` and the coordinates with ``flex_on`` set) to ``R``.

    Parameters
    ----------
    B, Fx, E : the arrays of :data:`BODIES`, :data:`FLEX`, :data:`ELEMENTS`
    g : (2,)
        Gravitational acceleration.
    x : :class:`~morphlab.kernels.types.Level`
    w : :class:`~morphlab.kernels.types.Weights`
    bodies, elems : int64 arrays; flex_on : (n_flex,) bool
        What is evaluated: everything for a step; for a pseudo-load the parts whose data a
        design variable changes (the derivative of the left-out parts is zero).
    R : (>= n_dof,), in/out
    W : :class:`Scratch`, zero on entry and on return
    """
    if B is None:  # the model has none of this kind
        return
    if bodies.shape[0] == 0:
        return
    wm, wf = w.wm, w.wf
    _gather(B, Fx, E, x, bodies, elems, flex_on, W)
    _products(B, E, elems, np.bool_(False), W)
    q, v, a = x.q, x.v, x.a
    Mq, Ma, Sq, Sv, Kd = W.p[0], W.p[2], W.p[3], W.p[4], W.p[6]
    gx = g[0]
    gy = g[1]
    for b in bodies:
        f = frame(B, b, q, v, a, _sums(B, Fx, b, flex_on, W))
        # inertia
        R[f.iR0] += wm * (f.m * f.aRx + f.AIcx * f.tha + f.Aisa_x)
        R[f.iR1] += wm * (f.m * f.aRy + f.AIcy * f.tha + f.Aisa_y)
        R[f.ith] += wm * (f.AIcx * f.aRx + f.AIcy * f.aRy + f.mthth * f.tha + f.i0is_a + f.sq_a)
        # forces: F = -Q_v - Q_g (+ elastic, flex rows below)
        qvx = f.thd * f.thd * f.Acx - 2.0 * f.thd * f.AIisv_x
        qvy = f.thd * f.thd * f.Acy - 2.0 * f.thd * f.AIisv_y
        qvth = -2.0 * f.thd * (f.i0s_v + f.qMv)
        R[f.iR0] -= wf * (qvx + f.m * gx)
        R[f.iR1] -= wf * (qvy + f.m * gy)
        R[f.ith] -= wf * (qvth + f.AIcx * gx + f.AIcy * gy)
        # A^T a_R and A^T g
        ATax = f.c * f.aRx + f.s * f.aRy
        ATay = -f.s * f.aRx + f.c * f.aRy
        ATgx = f.c * gx + f.s * gy
        ATgy = -f.s * gx + f.c * gy
        for k in range(B.flex[b, 0], B.flex[b, 1]):
            if not flex_on[k]:
                continue
            i = Fx.dof[k]
            isx = Fx.IS[k, 0]
            isy = Fx.IS[k, 1]
            R[i] += wm * (isx * ATax + isy * ATay + (Fx.I0IS[k] + Sq[k]) * f.tha + Ma[k])
            qvf = f.thd * f.thd * (Fx.I0S[k] + Mq[k]) - 2.0 * f.thd * Sv[k]
            qgf = isx * ATgx + isy * ATgy
            R[i] += wf * (Kd[k] - qvf - qgf)
    _clear(B, E, bodies, elems, flex_on, W)
