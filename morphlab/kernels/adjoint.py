"""The backward sweep of the discrete adjoint over a block of steps, in one compiled call.

The exact transpose of :func:`morphlab.kernels.direct.block_recursion` (``docs/theory.md`` §7):
for the steps of a block from the last to the first, with the adjoint of the state ``x_n``
held in ``Bq, Bv, Ba, Bg, Bl`` ((width, m), one column per response) and the responses' own
derivatives at ``n`` added first (``Hq, Hv, Ha, Hl`` (K, width, m)):

* ``z̄ = (ā + bh2 q̄ + gh v̄ + ga ḡ, s λ̄)``;
* ``μ = J^-T z̄`` with the step's kept factors, refined against the exact matrix at the
  converged point where ``refine[j]``;
* ``q̂̄ = q̄ - R_q^T μ``, ``v̂̄ = v̄ - R_v^T μ`` (the state matrices of
  :func:`~morphlab.kernels.direct.split_matrices`, the same as the direct method's);
* the adjoint of ``x_n-1`` through the predictors and, with the paper's weighting, the
  old-level share.

``μ`` of every step is returned in ``MU`` (K, n, m): the design enters afterwards, through
the partial derivatives of the residual. At the initial solve (time index 0) the sweep stops
with ``Bq, Bv`` holding the adjoints of ``q_0, q'_0`` to meet their derivatives from ``build``.
"""

import numpy as np
from numba import njit

from .direct import (
    add_explicit_residual,
    csc_residual_transposed,
    csc_transposed_product,
    elastic_share,
    part_scratch,
    parts_of,
    split_matrices,
    table_at,
)
from .newton import solve_factored_transposed
from .system import set_design


@njit(cache=True, nogil=True)
def adjoint_block(S, Q, V, A, L, w_new, has_old, w_old, F, k_new, scale, b0, b1, bh2, gh,
                  indices, indptr, n_dof, pc, upd, Hq, Hv, Ha, Hl, Bq, Bv, Ba, Bg, Bl, mats,
                  J, LU, piv, Lx, Ux, Ud, pattern, refine, n_refine, MU, refined):
    """Steps ``K-1 .. 0`` of a block (module docstring). States ``(Q, V, A, L)[j + 1]`` are
    step ``j``'s, ``[0]`` the one before the block; ``k_new`` (K,) their time indices; the
    factors stacked as in ``block_recursion``; ``mats`` (3, nnz) scratch of the split
    matrices, ``J`` (nnz,) of the exact matrix; ``refined`` (K,) gets the
    relative residual of each refined solve. Returns the position of the initial solve in the
    block (the sweep stops there), or -1. Runs without the GIL: the designs' compile goes on
    on its thread meanwhile (``morphlab.sensitivity.adjoint``)."""
    K = MU.shape[0]
    n = indptr.shape[0] - 1
    m = Bq.shape[1]
    n_con = Bl.shape[0]
    h, cqa, cqg, cva, cvg = pc[0], pc[1], pc[2], pc[3], pc[4]
    ga, gan, ggn = upd[0], upd[1], upd[2]
    zb = np.empty((n, m))
    r = np.empty((n, m))
    work = np.empty((n, m))
    gb = np.empty((n_dof, m))
    D0, Dq, Dv = mats[0], mats[1], mats[2]
    for j in range(K - 1, -1, -1):
        _add(Bq, Hq, j)
        _add(Bv, Hv, j)
        _add(Ba, Ha, j)
        _add(Bl, Hl, j)
        for i in range(n_dof):
            for c in range(m):
                zb[i, c] = Ba[i, c] + bh2 * Bq[i, c] + gh * Bv[i, c] + ga * Bg[i, c]
        for i in range(n_con):
            for c in range(m):
                zb[n_dof + i, c] = scale * Bl[i, c]
        split_matrices(S, Q[j + 1], V[j + 1], A[j + 1], L[j + 1], w_new, scale, b0, b1,
                       F[k_new[j]], mats)
        mu = MU[j]
        mu[:, :] = zb
        solve_factored_transposed(mu, work, LU[j], piv[j], Lx[j], Ux[j], Ud[j], pattern)
        if refine[j]:
            for p in range(J.shape[0]):
                J[p] = D0[p] + bh2 * Dq[p] + gh * Dv[p]
            for _ in range(n_refine):
                csc_residual_transposed(J, indices, indptr, mu, zb, r)
                solve_factored_transposed(r, work, LU[j], piv[j], Lx[j], Ux[j], Ud[j],
                                          pattern)
                mu += r
            rr, bb = csc_residual_transposed(J, indices, indptr, mu, zb, r)
            refined[j] = rr / max(bb, 1e-300)
        csc_transposed_product(Dq, indices, indptr, n_dof, mu, Bq)  # now the adjoint of q_hat
        csc_transposed_product(Dv, indices, indptr, n_dof, mu, Bv)  # and of v_hat
        if k_new[j] == 0:
            return j
        gb[:, :] = Bg
        for i in range(n_dof):
            for c in range(m):
                qhb = Bq[i, c]
                vhb = Bv[i, c]
                Bg[i, c] = cqg * qhb + cvg * vhb + ggn * gb[i, c]
                Ba[i, c] = cqa * qhb + cva * vhb + gan * gb[i, c]
                Bv[i, c] = h * qhb + vhb
        Bl[:, :] = 0.0
        if has_old:  # the paper's weighting: the old level's share
            split_matrices(S, Q[j], V[j], A[j], L[j], w_old, scale, b0, b1, F[k_new[j] - 1],
                           mats)
            csc_transposed_product(Dq, indices, indptr, n_dof, mu, Bq)
            csc_transposed_product(Dv, indices, indptr, n_dof, mu, Bv)
            r[:, :] = 0.0
            csc_transposed_product(D0, indices, indptr, n, mu, r)
            for i in range(n_dof):
                for c in range(m):
                    Ba[i, c] += r[i, c]
            for i in range(n_con):
                for c in range(m):
                    Bl[i, c] += r[n_dof + i, c] / scale
    return -1


@njit(cache=True)
def _add(B, H, j):
    """``B += H[j]`` when the response terms ``H`` are present (an empty ``H``: none)."""
    if H.shape[0] > 0:
        for i in range(B.shape[0]):
            for c in range(B.shape[1]):
                B[i, c] += H[j, i, c]


@njit(cache=True, nogil=True)
def explicit_adjoint_block(S, W, D, parts, lin, touched, Q, V, A, L, w_new, has_old, w_old,
                           scale, b0, b1, TAB, tab_of, k_old, k_new, n_dof, pert, i0, i1, work,
                           MU, grad):
    """The design's share of the adjoint gradient over a block of steps, for the variables
    ``i0 .. i1-1``: ``grad[i] -= sum_j (dR_j/dp_i)^T MU[j]`` (n_x, m), with the partial
    derivative of step ``j``'s residual along variable ``i`` formed as in
    :func:`~morphlab.kernels.direct.explicit_loads` (complex step or forward difference over
    the parts ``i`` changes, its time arrays table ``tab_of[i]`` of ``TAB``, the nominal's
    table 0; design ``i`` written into ``W``, a copy of ``S``, from its rows ``D``) and
    contracted with ``MU[j]`` (K, n, m) over the residual rows
    those parts can touch only (``touched = (offsets, rows)``, CSR over the variables). No
    (n, n_x) right-hand side is formed: the cost per variable is that of its parts, not of the
    system. A variable that changes only element stiffnesses and damping (``lin``, as for
    :func:`~morphlab.kernels.direct.explicit_loads`) contributes ``w_f (dK_e q_e + dC_e
    q_e')`` in real arithmetic. ``work`` (2, n): scratch residuals, zero on entry and on
    exit. Runs without the GIL: the sweep's next block, and other ranges of variables (each
    with its own ``W`` and ``work``), go on meanwhile (``morphlab.sensitivity.adjoint``)."""
    r_off, r_idx = touched
    forward = pert[0].imag == 0.0
    R = work[0]
    R0 = work[1]
    scr = part_scratch(S, Q[0], R)
    flex_on = np.zeros(S.flex_dof.shape[0], dtype=np.bool_)
    m = grad.shape[1]
    lin_off = lin[0]
    fl = np.empty(6)
    share = np.zeros(R.shape[0])
    for i in range(i0, i1):
        if lin_off[i + 1] > lin_off[i]:  # the stiffness alone: real products per element
            rows = r_idx[r_off[i]:r_off[i + 1]]  # they hold the elements' coordinates
            for j in range(MU.shape[0]):
                elastic_share(S, lin, i, Q, V, j, has_old, w_new, w_old, fl, share)
                for r in rows:
                    for c in range(m):
                        grad[i, c] -= share[r] * MU[j, r, c]
                    share[r] = 0.0
            continue
        pi, flex = parts_of(parts, i, flex_on)
        if (pi.bodies.size + pi.rows.size + pi.loads.size + pi.torques.size
                + pi.springs.size) == 0:
            continue  # the variable changes only the initial state
        rows = r_idx[r_off[i]:r_off[i + 1]]
        for k in flex:
            flex_on[k] = True
        set_design(W, S, D, i, True)
        ti = tab_of[i]
        for j in range(MU.shape[0]):
            ko, kn = k_old[j], k_new[j]
            add_explicit_residual(W, pi, Q[j + 1], V[j + 1], A[j + 1], L[j + 1], w_new,
                                  table_at(TAB, kn, ti), has_old, Q[j], V[j], A[j], L[j],
                                  w_old, table_at(TAB, ko, ti), scale, b0, b1, n_dof, R, scr)
            if forward:
                add_explicit_residual(S, pi, Q[j + 1], V[j + 1], A[j + 1], L[j + 1], w_new,
                                      table_at(TAB, kn, 0), has_old, Q[j], V[j], A[j], L[j],
                                      w_old, table_at(TAB, ko, 0), scale, b0, b1, n_dof, R0,
                                      scr)
                for r in rows:
                    d = ((R[r] - R0[r]) / pert[i]).real
                    for c in range(m):
                        grad[i, c] -= d * MU[j, r, c]
                    R[r] = 0.0
                    R0[r] = 0.0
            else:  # Re(R / (i h)) = Im(R) / h
                h = pert[i].imag
                for r in rows:
                    d = R[r].imag / h
                    for c in range(m):
                        grad[i, c] -= d * MU[j, r, c]
                    R[r] = 0.0
        set_design(W, S, D, i, False)
        for k in flex:
            flex_on[k] = False
