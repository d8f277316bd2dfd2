"""Planar FFRF bodies: mass matrix, quadratic-velocity, gravity and elastic forces, and their
exact derivatives, for all bodies of a system in one call.

Body data (see ``morphlab.compile``)
------------------------------------
Every body — rigid or flexible — has reference coordinates ``(R_x, R_y, theta)`` at global DOFs
``body_ref[b]`` and scalar invariants ``body_scal[b] = (m, I_u_x, I_u_y, I_00)``. A flexible
body also owns the entries ``flex_off[b]:flex_off[b+1]`` of the *flex* arrays: the global DOF of
each retained deformation coordinate (``flex_dof``) and the invariants ``I_S`` (``flex_IS``,
shape (n_flex, 2)), ``I_0S`` and ``I_0ĨS``. Its elements hold their body-frame matrices
``M_ff``, ``S̃`` and ``K_ff`` (6 x 6) and the flex index of each element DOF (``elem_fdof``,
``-1`` where the reference condition removes the DOF). A rigid body is the special case with no
flex coordinates (and ``I_u = 0`` when the reference point is the centre of mass).

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

and the body's share of the generalized-alpha residual is
``w_m M(q) a + w_f (K q_f + beta_d K q_f' - Q_v - Q_g)``.

All kernels run unchanged for float64 and complex128 arrays, and for a real state with complex
body data (a sensitivity pseudo-load): temporaries that hold products with the data take the
dtype of the output array (``R`` or ``data``), those that hold the state its own.
"""

from typing import NamedTuple

import numpy as np
from numba import njit


@njit(cache=True)
def _flex_products(q, v, a, flex_dof, elem_body, body_damp, elem_fdof, elem_M, elem_St, elem_K,
                   elems, n_flex, full, like):
    """Gather flex coordinates and form the element-wise products used by forces and Jacobians.

    ``full=False`` (the residual) forms ``Mq, Ma, Sq, Sv`` and the elastic plus damping force
    ``Kd = K (q_f + beta_d q_f')`` (one product: ``beta_d`` is the body's); ``full=True`` (the
    Jacobian, which takes ``K`` itself) forms ``Mq, Mv, Sq, Sv, Sa`` and no ``Kd``.

    ``full`` is passed as ``np.bool_``, a run-time value: a literal ``True``/``False`` would make
    Numba compile this function twice.

    Only the elements listed in ``elems`` contribute (all of them, except when a sensitivity
    pseudo-load evaluates just the parts a design variable changes).

    Returns ``qf, vf, af, Mq, Mv, Ma, Sq, Sv, Sa, Kd`` (each (n_flex + 1,); zeros where not
    formed; the gathered state in its dtype, the products in that of ``like``, the caller's
    output array). Element DOFs removed by a reference condition (``elem_fdof == -1``) read and
    write the extra slot ``n_flex``, which holds zero coordinates, so the element loop has no
    branches.
    """
    dt = like.dtype
    m = n_flex + 1
    qf = np.zeros(m, dtype=q.dtype)
    vf = np.zeros(m, dtype=q.dtype)
    af = np.zeros(m, dtype=q.dtype)
    for k in range(n_flex):
        qf[k] = q[flex_dof[k]]
        vf[k] = v[flex_dof[k]]
        af[k] = a[flex_dof[k]]
    Mq = np.zeros(m, dtype=dt)
    Mv = np.zeros(m, dtype=dt)
    Ma = np.zeros(m, dtype=dt)
    Sq = np.zeros(m, dtype=dt)
    Sv = np.zeros(m, dtype=dt)
    Sa = np.zeros(m, dtype=dt)
    Kd = np.zeros(m, dtype=dt)
    _element_products(qf, vf, af, elem_body, body_damp, elem_fdof, elem_M, elem_St, elem_K,
                      elems, n_flex, full, Mq, Mv, Ma, Sq, Sv, Sa, Kd,
                      np.empty(6, dtype=np.int64), np.empty(6, dtype=q.dtype),
                      np.empty(6, dtype=q.dtype), np.empty(6, dtype=q.dtype),
                      np.empty(6, dtype=dt))
    return qf, vf, af, Mq, Mv, Ma, Sq, Sv, Sa, Kd


@njit(cache=True, inline="always")
def _element_products(qf, vf, af, elem_body, body_damp, elem_fdof, elem_M, elem_St, elem_K,
                      elems, n_flex, full, Mq, Mv, Ma, Sq, Sv, Sa, Kd, idx, ql, vl, al, dl):
    """The element loop of :func:`_flex_products`: add the products of the elements ``elems``
    to ``Mq ... Kd`` (n_flex + 1,) from the gathered coordinates ``qf, vf, af``; ``idx``
    (6,) int64, ``ql, vl, al`` (6,) (``qf``'s dtype), ``dl`` (6,) (``Mq``'s): scratch."""
    for e in elems:
        beta = body_damp[elem_body[e]]
        for i in range(6):
            f = elem_fdof[e, i]
            idx[i] = f if f >= 0 else n_flex
            ql[i] = qf[idx[i]]
            vl[i] = vf[idx[i]]
            al[i] = af[idx[i]]
            dl[i] = ql[i] + beta * vl[i]
        Me = elem_M[e]
        Se = elem_St[e]
        Ke = elem_K[e]
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


@njit(cache=True, inline="always")
def _body_sums(b, body_scal, flex_off, flex_IS, flex_I0S, flex_I0IS, qf, vf, af, Mq, Sq,
               flex_on):
    """Reductions over a body's flex coordinates shared by residual and Jacobian:
    ``c_u`` (2), ``I_S a_f`` (2), ``I_S q_f'`` (2), ``I_0S.q_f``, ``I_0S.q_f'``,
    ``q_f^T M q_f``, ``q_f^T M q_f'``, ``I_0ĨS.a_f`` and ``(S̃ q_f).a_f``, over the
    coordinates with ``flex_on`` set (all of them but in a sensitivity pseudo-load)."""
    m = body_scal[b, 0]
    cux = body_scal[b, 1]
    cuy = body_scal[b, 2]
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
    for k in range(flex_off[b], flex_off[b + 1]):
        if not flex_on[k]:
            continue
        cux += flex_IS[k, 0] * qf[k]
        cuy += flex_IS[k, 1] * qf[k]
        isax += flex_IS[k, 0] * af[k]
        isay += flex_IS[k, 1] * af[k]
        isvx += flex_IS[k, 0] * vf[k]
        isvy += flex_IS[k, 1] * vf[k]
        i0s_q += flex_I0S[k] * qf[k]
        i0s_v += flex_I0S[k] * vf[k]
        qMq += qf[k] * Mq[k]
        qMv += Mq[k] * vf[k]
        i0is_a += flex_I0IS[k] * af[k]
        sq_a += Sq[k] * af[k]
    return cux, cuy, isax, isay, isvx, isvy, i0s_q, i0s_v, qMq, qMv, i0is_a, sq_a


@njit(cache=True, inline="always")
def _rotated(c, s, cux, cuy, isax, isay, isvx, isvy):
    """``A c_u``, ``AĨ c_u``, ``A I_S a_f``, ``AĨ I_S a_f``, ``A I_S q_f'``, ``AĨ I_S q_f'``
    (each an (x, y) pair) for ``A`` the rotation by the body angle (``c``, ``s`` its cosine
    and sine; ``AĨ x = (-(A x)_y, (A x)_x)``)."""
    cx, cy = c * cux - s * cuy, s * cux + c * cuy
    ax, ay = c * isax - s * isay, s * isax + c * isay
    vx, vy = c * isvx - s * isvy, s * isvx + c * isvy
    return (cx, cy), (-cy, cx), (ax, ay), (-ay, ax), (vx, vy), (-vy, vx)


@njit(cache=True)
def body_residual(S, q, v, a, wm, wf, parts, R):
    """Add the bodies' ``w_m M(q) a + w_f (K q_f + beta_d K q_f' - Q_v - Q_g)`` to ``R``.

    Parameters
    ----------
    q, v, a : (n_dof,)
        Generalized coordinates, velocities, accelerations (one dtype).
    wm, wf : scalar
        Weights of the inertia term and of the force terms.
    S : SystemArrays
        The system (:mod:`morphlab.kernels.system`).
    parts : Parts
        The bodies, elements and flexible coordinates evaluated: all of them for the residual.
        A sensitivity pseudo-load passes only those whose data a design variable changes (and
        the coordinates of its elements); with a real state the skipped parts carry no
        imaginary part (complex step) and cancel in a difference, so the derivative is exact
        although the real part is not the residual's.
    R : (>= n_dof,), in/out
        Residual; the body rows are added to.
    """
    bodies, elems, flex_on = parts.bodies, parts.elements, parts.flex
    if bodies.shape[0] == 0:
        return
    flex_dof = S.flex_dof
    n_flex = flex_dof.shape[0]
    qf, vf, af, Mq, Mv, Ma, Sq, Sv, Sa, Kd = _flex_products(
        q, v, a, flex_dof, S.elem_body, S.body_damp, S.elem_fdof, S.elem_M, S.elem_St, S.elem_K,
        elems, n_flex, np.bool_(False), R
    )
    _body_rows(S, q, v, a, wm, wf, bodies, flex_on, qf, vf, af, Mq, Ma, Sq, Sv, Kd, R)


class PartScratch(NamedTuple):
    """Scratch of :func:`body_part_residual`, made once per pseudo-load kernel call
    (``kernels.direct.part_scratch``): ``q`` (3, n_flex + 1) the gathered coordinates (the
    state's dtype), ``p`` (7, n_flex + 1) the element products (the residual's), both kept
    zero between calls; ``idx`` (6,) int64, ``loc`` (3, 6) and ``dl`` (6,): one element's
    indices, coordinates and damped coordinates."""

    q: np.ndarray
    p: np.ndarray
    idx: np.ndarray
    loc: np.ndarray
    dl: np.ndarray


@njit(cache=True, inline="always")
def body_part_residual(S, q, v, a, wm, wf, parts, R, W):
    """:func:`body_residual` over a few parts (a sensitivity pseudo-load) at a cost that
    grows with the parts, not with the system: the gathered coordinates and the element
    products live in the scratch ``W`` (:class:`PartScratch`), whose arrays ``W.q`` and ``W.p``
    are zero on entry and are left zero; only the coordinates of the listed elements and the
    masked coordinates of the listed bodies are gathered. The numbers are
    :func:`body_residual`'s, term by term."""
    bodies, elems, flex_on = parts.bodies, parts.elements, parts.flex
    if bodies.shape[0] == 0:
        return
    flex_off, flex_dof, elem_fdof = S.flex_off, S.flex_dof, S.elem_fdof
    n_flex = flex_dof.shape[0]
    Wq, Wp = W.q, W.p
    qf, vf, af = Wq[0], Wq[1], Wq[2]
    Mq, Mv, Ma, Sq, Sv, Sa, Kd = Wp[0], Wp[1], Wp[2], Wp[3], Wp[4], Wp[5], Wp[6]
    for e in elems:
        for i in range(6):
            f = elem_fdof[e, i]
            if f >= 0:
                qf[f] = q[flex_dof[f]]
                vf[f] = v[flex_dof[f]]
                af[f] = a[flex_dof[f]]
    for b in bodies:
        for k in range(flex_off[b], flex_off[b + 1]):
            if flex_on[k]:
                qf[k] = q[flex_dof[k]]
                vf[k] = v[flex_dof[k]]
                af[k] = a[flex_dof[k]]
    _element_products(qf, vf, af, S.elem_body, S.body_damp, elem_fdof, S.elem_M, S.elem_St,
                      S.elem_K, elems, n_flex, np.bool_(False), Mq, Mv, Ma, Sq, Sv, Sa, Kd,
                      W.idx, W.loc[0], W.loc[1], W.loc[2], W.dl)
    _body_rows(S, q, v, a, wm, wf, bodies, flex_on, qf, vf, af, Mq, Ma, Sq, Sv, Kd, R)
    for e in elems:  # leave the scratch zero (the slot n_flex included)
        for i in range(6):
            f = elem_fdof[e, i]
            _clear(Wq, Wp, f if f >= 0 else n_flex)
    for b in bodies:
        for k in range(flex_off[b], flex_off[b + 1]):
            if flex_on[k]:
                _clear(Wq, Wp, k)


@njit(cache=True, inline="always")
def _clear(Wq, Wp, k):
    for r in range(Wq.shape[0]):
        Wq[r, k] = 0.0
    for r in range(Wp.shape[0]):
        Wp[r, k] = 0.0


@njit(cache=True, inline="always")
def _body_rows(S, q, v, a, wm, wf, bodies, flex_on, qf, vf, af, Mq, Ma, Sq, Sv, Kd, R):
    """The rows of the bodies ``bodies`` (:func:`body_residual`) from the gathered
    coordinates and the element products."""
    body_ref, body_scal, flex_off, flex_dof = S.body_ref, S.body_scal, S.flex_off, S.flex_dof
    flex_IS, flex_I0S, flex_I0IS = S.flex_IS, S.flex_I0S, S.flex_I0IS
    gx = S.gravity[0]
    gy = S.gravity[1]
    for b in bodies:
        iR0 = body_ref[b, 0]
        iR1 = body_ref[b, 1]
        ith = body_ref[b, 2]
        m = body_scal[b, 0]
        th = q[ith]
        thd = v[ith]
        tha = a[ith]
        c = np.cos(th)
        s = np.sin(th)
        (cux, cuy, isax, isay, isvx, isvy, i0s_q, i0s_v, qMq, qMv, i0is_a,
         sq_a) = _body_sums(b, body_scal, flex_off, flex_IS, flex_I0S, flex_I0IS, qf, vf, af,
                            Mq, Sq, flex_on)
        # A c_u, AĨ c_u, A I_S a_f, AĨ I_S q_f'
        ((Acx, Acy), (AIcx, AIcy), (Aisa_x, Aisa_y), _, _,
         (AIisv_x, AIisv_y)) = _rotated(c, s, cux, cuy, isax, isay, isvx, isvy)
        aRx = a[iR0]
        aRy = a[iR1]
        mthth = body_scal[b, 3] + 2.0 * i0s_q + qMq
        # inertia
        R[iR0] += wm * (m * aRx + AIcx * tha + Aisa_x)
        R[iR1] += wm * (m * aRy + AIcy * tha + Aisa_y)
        R[ith] += wm * (AIcx * aRx + AIcy * aRy + mthth * tha + i0is_a + sq_a)
        # forces: F = -Q_v - Q_g (+ elastic, flex rows below)
        qvx = thd * thd * Acx - 2.0 * thd * AIisv_x
        qvy = thd * thd * Acy - 2.0 * thd * AIisv_y
        qvth = -2.0 * thd * (i0s_v + qMv)
        R[iR0] -= wf * (qvx + m * gx)
        R[iR1] -= wf * (qvy + m * gy)
        R[ith] -= wf * (qvth + AIcx * gx + AIcy * gy)
        # A^T a_R and A^T g
        ATax = c * aRx + s * aRy
        ATay = -s * aRx + c * aRy
        ATgx = c * gx + s * gy
        ATgy = -s * gx + c * gy
        for k in range(flex_off[b], flex_off[b + 1]):
            if not flex_on[k]:
                continue
            i = flex_dof[k]
            isx = flex_IS[k, 0]
            isy = flex_IS[k, 1]
            R[i] += wm * (isx * ATax + isy * ATay + (flex_I0IS[k] + Sq[k]) * tha + Ma[k])
            qvf = thd * thd * (flex_I0S[k] + Mq[k]) - 2.0 * thd * Sv[k]
            qgf = isx * ATgx + isy * ATgy
            R[i] += wf * (Kd[k] - qvf - qgf)


@njit(cache=True, inline="always")
def add_split(out, C, p, x0, xq, xv):
    """Add an entry ``x0 + bh2 xq + gh xv`` of the Newton matrix at position ``p`` of every
    output: ``out[r, p] += C[r][0] x0 + C[r][1] xq + C[r][2] xv`` (``out`` (m, nnz), ``C`` m
    triples; see :func:`body_jacobian`)."""
    for r in range(len(C)):
        c = C[r]
        out[r, p] += c[0] * x0 + c[1] * xq + c[2] * xv


@njit(cache=True)
def body_jacobian(S, q, v, a, cm, cf, C, out):
    """Add every body's block of ``d(residual)/d(a)`` to the CSC data arrays ``out``.

    The residual block is ``cm M(q) a + cf F(q, q')`` with ``q = q_pred + bh2 a`` and
    ``q' = qd_pred + gh a``, so the block is ``cm (M + bh2 d(Ma)/dq) + cf (bh2 dF/dq + gh dF/dq')``
    (paper eq. 30; every term included): ``D0 + bh2 Dq + gh Dv`` with ``D0 = cm M``,
    ``Dq = cm d(Ma)/dq + cf dF/dq`` and ``Dv = cf dF/dq'``. Output ``r`` receives
    ``C[r][0] D0 + C[r][1] Dq + C[r][2] Dv``: ``C = ((1, bh2, gh),)`` gives the Newton matrix,
    the identity the three matrices in one pass (``kernels.direct.split_matrices``).

    Parameters
    ----------
    cm, cf : scalar
        Weights of the inertia and force terms (``1 - alpha_m``, ``1 - alpha_f``).
    C : tuple of m tuples of 3 floats
        Coefficients of ``D0, Dq, Dv`` in each output (a tuple, not an array: its values stay
        in registers while the outputs are written).
    S : SystemArrays
        The system (:mod:`morphlab.kernels.system`); ``S.border_off`` are the offsets of each
        body's border entries in ``S.border_map``: the 3 x 3 reference block, then the
        3 x n_f reference-row/flex-column entries, then the n_f x 3 flex-row/reference-column
        entries (row-major within each part); ``S.border_map``, ``S.elem_map`` the position in
        the data arrays of every border and element entry (``-1``: skipped).
    out : (m, nnz), in/out
        CSC data arrays over the Newton matrix's pattern.
    """
    body_ref, body_scal, body_damp, flex_off, flex_dof = (S.body_ref, S.body_scal, S.body_damp,
                                                          S.flex_off, S.flex_dof)
    flex_IS, flex_I0S, flex_I0IS = S.flex_IS, S.flex_I0S, S.flex_I0IS
    elem_body, elem_fdof, elem_M, elem_St, elem_K = (S.elem_body, S.elem_fdof, S.elem_M, S.elem_St,
                                                     S.elem_K)
    border_off, border_map, elem_map = S.border_off, S.border_map, S.elem_map
    gravity = S.gravity
    n_flex = flex_dof.shape[0]
    qf, vf, af, Mq, Mv, Ma, Sq, Sv, Sa, _ = _flex_products(
        q, v, a, flex_dof, elem_body, body_damp, elem_fdof, elem_M, elem_St, elem_K,
        np.arange(elem_fdof.shape[0]), n_flex, np.bool_(True), out
    )
    all_flex = np.ones(n_flex, dtype=np.bool_)
    gx = gravity[0]
    gy = gravity[1]
    # blk[k]: the 3 x 3 reference block of D0 (k = 0), Dq (1) and Dv (2)
    blk = np.zeros((3, 3, 3), dtype=out.dtype)
    for b in range(body_ref.shape[0]):
        iR0 = body_ref[b, 0]
        iR1 = body_ref[b, 1]
        ith = body_ref[b, 2]
        m = body_scal[b, 0]
        th = q[ith]
        thd = v[ith]
        tha = a[ith]
        c = np.cos(th)
        s = np.sin(th)
        (cux, cuy, isax, isay, isvx, isvy, i0s_q, i0s_v, qMq, qMv, _,
         _) = _body_sums(b, body_scal, flex_off, flex_IS, flex_I0S, flex_I0IS, qf, vf, af,
                            Mq, Sq, all_flex)
        ((Acx, Acy), (AIcx, AIcy), _, (AIisa_x, AIisa_y), (Aisv_x, Aisv_y),
         (AIisv_x, AIisv_y)) = _rotated(c, s, cux, cuy, isax, isay, isvx, isvy)
        aRx = a[iR0]
        aRy = a[iR1]
        mthth = body_scal[b, 3] + 2.0 * i0s_q + qMq
        # ---- 3 x 3 reference block (rows R_x, R_y, th; cols R_x, R_y, th)
        blk[:] = 0.0
        # mass
        blk[0, 0, 0] = cm * m
        blk[0, 1, 1] = cm * m
        blk[0, 0, 2] = cm * AIcx
        blk[0, 1, 2] = cm * AIcy
        blk[0, 2, 0] = cm * AIcx
        blk[0, 2, 1] = cm * AIcy
        blk[0, 2, 2] = cm * mthth
        # d(M a)/d th
        blk[1, 0, 2] = cm * (-Acx * tha + AIisa_x)
        blk[1, 1, 2] = cm * (-Acy * tha + AIisa_y)
        blk[1, 2, 2] = cm * (-(Acx * aRx + Acy * aRy))
        # F = -Q_v - Q_g: d/d th and d/d th'
        # Q_v,R = th'^2 A c_u - 2 th' AĨ I_S q_f'
        blk[1, 0, 2] -= cf * (thd * thd * AIcx + 2.0 * thd * Aisv_x)
        blk[1, 1, 2] -= cf * (thd * thd * AIcy + 2.0 * thd * Aisv_y)
        blk[2, 0, 2] = -cf * (2.0 * thd * Acx - 2.0 * AIisv_x)
        blk[2, 1, 2] = -cf * (2.0 * thd * Acy - 2.0 * AIisv_y)
        # Q_v,th = -2 th' (I_0S + M_ff q_f).q_f'  -> d/d th' only
        blk[2, 2, 2] = cf * 2.0 * (i0s_v + qMv)
        # Q_g,th = (AĨ c_u).g -> d/d th = -(A c_u).g
        blk[1, 2, 2] += cf * (Acx * gx + Acy * gy)
        o = border_off[b]
        for i in range(3):
            for j in range(3):
                p = border_map[o + 3 * i + j]
                if p >= 0:
                    add_split(out, C, p, blk[0, i, j], blk[1, i, j], blk[2, i, j])
        f0 = flex_off[b]
        nf = flex_off[b + 1] - f0
        o_rf = o + 9
        o_fr = o + 9 + 3 * nf
        for kk in range(nf):
            k = f0 + kk
            isx = flex_IS[k, 0]
            isy = flex_IS[k, 1]
            Aisx = c * isx - s * isy
            Aisy = s * isx + c * isy
            AIisx = -Aisy
            AIisy = Aisx
            # rows R (0, 1), th (2); column f_k
            # -dQ_v,R/dq_f = -th'^2 A I_S ; -dQ_v,R/dq_f' = 2 th' AĨ I_S
            p = border_map[o_rf + kk]
            if p >= 0:
                add_split(out, C, p, cm * Aisx, cm * AIisx * tha - cf * thd * thd * Aisx,
                          cf * 2.0 * thd * AIisx)
            p = border_map[o_rf + nf + kk]
            if p >= 0:
                add_split(out, C, p, cm * Aisy, cm * AIisy * tha - cf * thd * thd * Aisy,
                          cf * 2.0 * thd * AIisy)
            mthf = flex_I0IS[k] + Sq[k]
            # Q_v,th = -2 th' (I_0S.q_f' + q_f^T M q_f'): d/dq_f = -2 th' (M q_f')_k,
            # d/dq_f' = -2 th' (I_0S + M q_f)_k ; Q_g,th: d/dq_f = (AĨ I_S)_k . g
            p = border_map[o_rf + 2 * nf + kk]
            if p >= 0:
                add_split(out, C, p, cm * mthf,
                          cm * (AIisx * aRx + AIisy * aRy + tha * 2.0 * (flex_I0S[k] + Mq[k])
                                - Sa[k]) - cf * (-2.0 * thd * Mv[k] + (AIisx * gx + AIisy * gy)),
                          cf * 2.0 * thd * (flex_I0S[k] + Mq[k]))
            # row f_k; columns R_x, R_y, th
            p = border_map[o_fr + 3 * kk]
            if p >= 0:
                add_split(out, C, p, cm * Aisx, 0.0, 0.0)
            p = border_map[o_fr + 3 * kk + 1]
            if p >= 0:
                add_split(out, C, p, cm * Aisy, 0.0, 0.0)
            # d(M a)_f/d th = (AĨ I_S_k).a_R; Q_g,f = I_S^T A^T g: d/d th = (AĨ I_S_k).g
            # Q_v,f = th'^2 (I_0S + M q_f) - 2 th' S̃ q_f': d/d th' = 2 th'(I_0S + Mq) - 2 S̃ q_f'
            p = border_map[o_fr + 3 * kk + 2]
            if p >= 0:
                add_split(out, C, p, cm * mthf,
                          cm * (AIisx * aRx + AIisy * aRy) - cf * (AIisx * gx + AIisy * gy),
                          -cf * (2.0 * thd * (flex_I0S[k] + Mq[k]) - 2.0 * Sv[k]))
    # ---- flex-flex block, element by element: cm M_ff - cf bh2 th'^2 M_ff
    # + cf (bh2 + gh beta) K + (cm bh2 th'' + cf gh 2 th') S̃
    for e in range(elem_fdof.shape[0]):
        b = elem_body[e]
        ith = body_ref[b, 2]
        thd = v[ith]
        tha = a[ith]
        beta = body_damp[b]
        for r in range(len(C)):
            c0, cq, cv = C[r]
            coefM = c0 * cm - cq * cf * thd * thd
            coefK = cf * (cq + cv * beta)
            coefS = cq * cm * tha + cv * cf * 2.0 * thd
            o_r = out[r]
            for i in range(6):
                for j in range(6):
                    p = elem_map[e, i, j]
                    if p >= 0:
                        o_r[p] += (coefM * elem_M[e, i, j] + coefK * elem_K[e, i, j]
                                   + coefS * elem_St[e, i, j])
