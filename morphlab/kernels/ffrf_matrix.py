"""The step matrix of the planar FFRF bodies (:mod:`morphlab.kernels.ffrf`, whose residual
it differentiates): every body's reference block, its borders with the flexible coordinates
and the element blocks, exact, for all bodies in one call (``docs/theory.md`` §2.5-§2.9)."""

import numpy as np

from ._jit import inner
from .ffrf import _clear, _gather, _products, _sums, frame
from .types import add_split


@inner
def matrix(B, Fx, E, g, x, w, C, out, W):
    """Add every body's block of the step matrix to the CSC data arrays ``out`` (m, nnz).

    The block of ``w.wm M(q) a + w.wf F(q, q')`` along ``a`` is ``D0 + bh2 Dq + gh Dv`` with
    ``D0 = wm M``, ``Dq = wm d(Ma)/dq + wf dF/dq`` and ``Dv = wf dF/dq'`` (paper eq. 30,
    every term included); output ``r`` receives ``C[r, 0] D0 + C[r, 1] Dq + C[r, 2] Dv``
    (:mod:`morphlab.kernels.types`). Positions: ``bodies.block``, ``flex.border``,
    ``elements.map`` (``-1``: skipped). ``W``: a :class:`Scratch`, zero on entry and return.
    """
    if B is None:  # the model has none of this kind
        return
    cm, cf = w.wm, w.wf
    q, v, a = x.q, x.v, x.a
    n_flex = Fx.dof.shape[0]
    elems = np.arange(E.fdof.shape[0])
    bodies = np.arange(B.ref.shape[0])
    all_flex = np.ones(n_flex, dtype=np.bool_)
    _gather(B, Fx, E, x, bodies, elems, all_flex, W)
    _products(B, E, elems, np.bool_(True), W)
    Mq, Mv, Sq, Sv, Sa = W.p[0], W.p[1], W.p[3], W.p[4], W.p[5]
    gx = g[0]
    gy = g[1]
    # blk[k]: the 3 x 3 reference block of D0 (k = 0), Dq (1) and Dv (2)
    blk = np.zeros((3, 3, 3), dtype=out.dtype)
    for b in range(B.ref.shape[0]):
        f = frame(B, b, q, v, a, _sums(B, Fx, b, all_flex, W))
        # ---- 3 x 3 reference block (rows R_x, R_y, th; cols R_x, R_y, th)
        blk[:] = 0.0
        # mass
        blk[0, 0, 0] = cm * f.m
        blk[0, 1, 1] = cm * f.m
        blk[0, 0, 2] = cm * f.AIcx
        blk[0, 1, 2] = cm * f.AIcy
        blk[0, 2, 0] = cm * f.AIcx
        blk[0, 2, 1] = cm * f.AIcy
        blk[0, 2, 2] = cm * f.mthth
        # d(M a)/d th
        blk[1, 0, 2] = cm * (-f.Acx * f.tha + f.AIisa_x)
        blk[1, 1, 2] = cm * (-f.Acy * f.tha + f.AIisa_y)
        blk[1, 2, 2] = cm * (-(f.Acx * f.aRx + f.Acy * f.aRy))
        # F = -Q_v - Q_g: d/d th and d/d th'
        # Q_v,R = th'^2 A c_u - 2 th' AĨ I_S q_f'
        blk[1, 0, 2] -= cf * (f.thd * f.thd * f.AIcx + 2.0 * f.thd * f.Aisv_x)
        blk[1, 1, 2] -= cf * (f.thd * f.thd * f.AIcy + 2.0 * f.thd * f.Aisv_y)
        blk[2, 0, 2] = -cf * (2.0 * f.thd * f.Acx - 2.0 * f.AIisv_x)
        blk[2, 1, 2] = -cf * (2.0 * f.thd * f.Acy - 2.0 * f.AIisv_y)
        # Q_v,th = -2 th' (I_0S + M_ff q_f).q_f'  -> d/d th' only
        blk[2, 2, 2] = cf * 2.0 * (f.i0s_v + f.qMv)
        # Q_g,th = (AĨ c_u).g -> d/d th = -(A c_u).g
        blk[1, 2, 2] += cf * (f.Acx * gx + f.Acy * gy)
        for i in range(3):
            for j in range(3):
                p = B.block[b, i, j]
                if p >= 0:
                    add_split(out, C, p, blk[0, i, j], blk[1, i, j], blk[2, i, j])
        for k in range(B.flex[b, 0], B.flex[b, 1]):
            isx = Fx.IS[k, 0]
            isy = Fx.IS[k, 1]
            Aisx = f.c * isx - f.s * isy
            Aisy = f.s * isx + f.c * isy
            AIisx = -Aisy
            AIisy = Aisx
            bd = Fx.border[k]
            # rows R (0, 1), th (2); column f_k
            # -dQ_v,R/dq_f = -th'^2 A I_S ; -dQ_v,R/dq_f' = 2 th' AĨ I_S
            p = bd[0, 0]
            if p >= 0:
                add_split(out, C, p, cm * Aisx, cm * AIisx * f.tha - cf * f.thd * f.thd * Aisx,
                          cf * 2.0 * f.thd * AIisx)
            p = bd[0, 1]
            if p >= 0:
                add_split(out, C, p, cm * Aisy, cm * AIisy * f.tha - cf * f.thd * f.thd * Aisy,
                          cf * 2.0 * f.thd * AIisy)
            mthf = Fx.I0IS[k] + Sq[k]
            # Q_v,th = -2 th' (I_0S.q_f' + q_f^T M q_f'): d/dq_f = -2 th' (M q_f')_k,
            # d/dq_f' = -2 th' (I_0S + M q_f)_k ; Q_g,th: d/dq_f = (AĨ I_S)_k . g
            p = bd[0, 2]
            if p >= 0:
                add_split(out, C, p, cm * mthf,
                          cm * (AIisx * f.aRx + AIisy * f.aRy + f.tha * 2.0 * (Fx.I0S[k] + Mq[k])
                                - Sa[k]) - cf * (-2.0 * f.thd * Mv[k] + (AIisx * gx + AIisy * gy)),
                          cf * 2.0 * f.thd * (Fx.I0S[k] + Mq[k]))
            # row f_k; columns R_x, R_y, th
            p = bd[1, 0]
            if p >= 0:
                add_split(out, C, p, cm * Aisx, 0.0, 0.0)
            p = bd[1, 1]
            if p >= 0:
                add_split(out, C, p, cm * Aisy, 0.0, 0.0)
            # d(M a)_f/d th = (AĨ I_S_k).a_R; Q_g,f = I_S^T A^T g: d/d th = (AĨ I_S_k).g
            # Q_v,f = th'^2 (I_0S + M q_f) - 2 th' S̃ q_f': d/d th' = 2 th'(I_0S + Mq) - 2 S̃ q_f'
            p = bd[1, 2]
            if p >= 0:
                add_split(out, C, p, cm * mthf,
                          cm * (AIisx * f.aRx + AIisy * f.aRy) - cf * (AIisx * gx + AIisy * gy),
                          -cf * (2.0 * f.thd * (Fx.I0S[k] + Mq[k]) - 2.0 * Sv[k]))
    _clear(B, E, bodies, elems, all_flex, W)
    _element_blocks(B, E, x, cm, cf, C, out)


@inner
def _element_blocks(B, E, x, cm, cf, C, out):
    """The flex-flex block, element by element: ``cm M_ff - cf bh2 th'^2 M_ff + cf (bh2 + gh
    beta) K + (cm bh2 th'' + cf gh 2 th') S̃`` in the split form."""
    for e in range(E.fdof.shape[0]):
        b = E.body[e]
        ith = B.ref[b, 2]
        thd = x.v[ith]
        tha = x.a[ith]
        beta = B.damp[b]
        for r in range(C.shape[0]):
            c0, cq, cv = C[r, 0], C[r, 1], C[r, 2]
            coefM = c0 * cm - cq * cf * thd * thd
            coefK = cf * (cq + cv * beta)
            coefS = cq * cm * tha + cv * cf * 2.0 * thd
            o_r = out[r]
            for i in range(6):
                for j in range(6):
                    p = E.map[e, i, j]
                    if p >= 0:
                        o_r[p] += (coefM * E.M[e, i, j] + coefK * E.K[e, i, j]
                                   + coefS * E.St[e, i, j])
