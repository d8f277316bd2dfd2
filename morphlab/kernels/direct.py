"""The direct differentiation of a step, staggered after it (``docs/theory.md`` §6).

Differentiating the converged step equations ``R(z_{n+1}; s_n, p) = 0`` along design variable
``i`` gives ``J dz_{n+1}/dp_i = -D_i R``, with

    D_i R = Dq dq_hat_i + Dv dv_hat_i [+ the old level's terms] + dR/dp_i

``Dq``, ``Dv`` the derivatives of the residual along ``q`` and ``q'`` (the predictors move the
state by ``dq_hat``, ``dv_hat``), ``dR/dp_i`` the explicit part (:mod:`morphlab.kernels.pseudo`).
All variables' right-hand sides are solved at once, then the Newmark update advances the
sensitivity histories.

Which matrices (``docs/theory.md`` §6.4, the paper's eq. 39): with ``reuse``, the step's own
Newton matrix, as the primal's last iteration formed and factored it at the iterate before the
last correction, and the ``Dq``, ``Dv`` of that same fill (the primal fills them alongside the
Newton matrix): no matrix is formed for the sensitivities, and their relative error is of the
order of the last Newton correction, the accuracy of the primal itself. Without ``reuse`` (the
exact variant), ``Dq``, ``Dv`` and the Newton matrix ``J*`` are formed at the converged state
and ``refine`` sweeps of iterative refinement against ``J*`` remove the lag of the
factorization: exact to round-off.

Histories are ``(n_x, levels, width)``: level ``k % levels`` holds time index ``k``.
"""

from typing import NamedTuple

import numpy as np

from ._jit import inlined, inner, kernel
from .adjoint import kept_factor, kept_state
from .assemble import matrix
from .csc import residual, subtract_product
from .newmark import predict, update
from .newton import solve_factored
from .pseudo import explicit, load


class Direct(NamedTuple):
    """The work of a run's direct sensitivities: histories ``DQ, DV, DA, DG, DL``
    (module docstring), the pseudo-load data ``ps`` (:class:`~morphlab.kernels.pseudo.
    Pseudo`), buffers ``rhs``, ``x``, ``r``,
    ``work`` (n, n_x), ``column`` (:class:`~morphlab.kernels.pseudo.Column`), ``mats``
    (6, nnz) (split matrices at the converged and the old state), ``refined`` (n_t,): the
    relative residual of each refined solve, ``csc`` the step matrix's pattern
    (:class:`~morphlab.kernels.newton.Csc`)."""

    DQ: np.ndarray
    DV: np.ndarray
    DA: np.ndarray
    DG: np.ndarray
    DL: np.ndarray
    ps: tuple
    rhs: np.ndarray
    x: np.ndarray
    r: np.ndarray
    work: np.ndarray
    column: tuple
    mats: np.ndarray
    refined: np.ndarray
    csc: tuple


@inner
def rhs(d, M, T, sc, D, new, old, k):
    """The right-hand sides ``-D_i R`` of step ``k`` into ``d.rhs`` (n, n_x): the explicit
    parts at the converged state ``new`` (and the old level's at ``old``), then the state
    parts with the split matrices ``D`` (6, nnz): rows 1, 2 ``Dq``, ``Dv`` of the new level
    and, for a scheme with an old level, rows 3-5 ``D0, Dq, Dv`` of the old one."""
    n_dof = new.q.shape[0]
    n_con = new.lam.shape[0]
    n_x = d.rhs.shape[1]
    lev = d.DQ.shape[1], d.DV.shape[1], d.DA.shape[1], d.DG.shape[1], d.DL.shape[1]
    m = k - 1 if k > 0 else 0  # the initial solve's "old" level: the initial state itself
    ps, column = d.ps, d.column  # bound before the loop (adjoint._design_share says why)
    col = column.R
    load(column.XN, new)  # the levels in the perturbed path's dtype, once for all variables
    if sc.has_old:
        load(column.XO, old)
    for i in range(n_x):
        for r in range(col.shape[0]):
            col[r] = 0.0
        explicit(ps, ps.MN, M, T, i, new, column.XN, sc.w_new, k, column)
        if sc.has_old:
            explicit(ps, ps.MN, M, T, i, old, column.XO, sc.w_old, m, column)
        for r in range(col.shape[0]):
            d.rhs[r, i] = -col[r]
    # the state part: R_q dq_hat + R_v dv_hat over the predictors of every column
    dqh = np.empty((n_dof, n_x))
    dvh = np.empty((n_dof, n_x))
    qh = np.empty(n_dof)
    vh = np.empty(n_dof)
    for i in range(n_x):
        predict(sc.pc, d.DQ[i, m % lev[0]], d.DV[i, m % lev[1]], d.DA[i, m % lev[2]],
                d.DG[i, m % lev[3]], qh, vh)
        for r in range(n_dof):
            dqh[r, i] = qh[r]
            dvh[r, i] = vh[r]
    subtract_product(D[1], d.csc.indices, d.csc.indptr, n_dof, dqh, d.rhs, False)
    subtract_product(D[2], d.csc.indices, d.csc.indptr, n_dof, dvh, d.rhs, False)
    if sc.has_old:
        x0 = np.empty((n_dof + n_con, n_x))
        for i in range(n_x):
            for r in range(n_dof):
                x0[r, i] = d.DA[i, m % lev[2], r]
                dqh[r, i] = d.DQ[i, m % lev[0], r]
                dvh[r, i] = d.DV[i, m % lev[1], r]
            for r in range(n_con):
                x0[n_dof + r, i] = d.DL[i, m % lev[4], r] / sc.w_new.scale
        subtract_product(D[4], d.csc.indices, d.csc.indptr, n_dof, dqh, d.rhs, False)
        subtract_product(D[5], d.csc.indices, d.csc.indptr, n_dof, dvh, d.rhs, False)
        subtract_product(D[3], d.csc.indices, d.csc.indptr, n_dof + n_con, x0, d.rhs,
                         False)


@kernel
def store(DQ, DV, DA, DG, DL, sc, x, k):
    """Store the step's solution ``x = (da, dlam/scale)`` (n, n_x) as time index ``k`` of the
    histories ``DQ, DV, DA, DG, DL`` (those of :class:`Direct`) and advance ``dq, dv, dg`` by
    the Newmark update from ``k - 1`` (``k == 0``: the initial solve, which sets ``da, dg,
    dlam`` only). The histories are passed, not the whole :class:`Direct`: Python calls this
    kernel, and unboxing ``Direct`` (its pseudo-load data) in the call's wrapper costs about a
    second of compile."""
    n_x = x.shape[1]
    n_dof = DQ.shape[2]
    n_con = DL.shape[2]
    lev = DQ.shape[1], DV.shape[1], DA.shape[1], DG.shape[1], DL.shape[1]
    scale = sc.w_new.scale
    if k == 0:
        for i in range(n_x):
            for r in range(n_dof):
                DA[i, 0, r] = x[r, i]
                DG[i, 0, r] = x[r, i]
            for r in range(n_con):
                DL[i, 0, r] = x[n_dof + r, i] * scale
        return
    m = k - 1
    qh = np.empty(n_dof)
    vh = np.empty(n_dof)
    da = np.empty(n_dof)
    for i in range(n_x):
        for r in range(n_dof):
            da[r] = x[r, i]
        predict(sc.pc, DQ[i, m % lev[0]], DV[i, m % lev[1]], DA[i, m % lev[2]],
                DG[i, m % lev[3]], qh, vh)
        update(sc.pc, sc.upd, qh, vh, da, DA[i, m % lev[2]], DG[i, m % lev[3]],
               DQ[i, k % lev[0]], DV[i, k % lev[1]], DG[i, k % lev[3]])
        for r in range(n_dof):
            DA[i, k % lev[2], r] = da[r]
        for r in range(n_con):
            DL[i, k % lev[4], r] = x[n_dof + r, i] * scale


@inlined
def prepare(d, M, T, sc, Dq, Dv, new, old, k, refine, w_old):
    """The right-hand sides of step ``k`` (from the state ``old`` to ``new``) into ``d.rhs``
    and ``d.x`` (which the caller then solves in place), with the split matrices of the
    variant (module docstring) in ``d.mats``: ``Dq``, ``Dv`` (nnz,) those of the step's last
    Newton fill (the reuse variant's). ``refine``: None for the reuse variant (then the exact
    variant's code is not compiled), else the exact variant's number of refinement sweeps.
    ``w_old``: the weights of the scheme's old level, None for a scheme without one (then the
    old level's matrix code is not compiled; ``morphlab.solve.scheme.old_weights``).

    Inlined into :func:`chunk`, its one caller (a step solved from Python takes its
    right-hand sides from :func:`chunk` too, with ``rhs_only``): compiled as a kernel of its
    own, its code and that of everything it calls would be emitted once more (``_jit``'s
    docstring)."""
    C = np.array([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]])
    D = d.mats
    if refine is None:
        for p in range(D.shape[1]):
            D[1, p] = Dq[p]
            D[2, p] = Dv[p]
    else:
        matrix(M, new, sc.w_new, T, np.int64(0), k, C, D[0:3], d.ps.WL)
        bh2, gh = sc.pc[5], sc.pc[6]
        for p in range(D.shape[1]):
            D[0, p] = D[0, p] + bh2 * D[1, p] + gh * D[2, p]  # J* for the refinement
    if w_old is not None and sc.has_old:
        matrix(M, old, w_old, T, np.int64(0), k - 1, C, D[3:6], d.ps.WL)
    rhs(d, M, T, sc, D, new, old, k)
    for r in range(d.x.shape[0]):
        for i in range(d.x.shape[1]):
            d.x[r, i] = d.rhs[r, i]


@kernel
def refinement_residual(d):
    """``d.r = rhs - J* x`` (the exact variant's refinement); returns ``(|r|, |rhs|)``."""
    return residual(d.mats[0], d.csc.indices, d.csc.indptr, d.x, d.rhs, d.r, False)


@kernel(nogil=True)
def chunk(d, M, T, sc, F, K, k0, k1, refine, rhs_only, w_old):
    """The sensitivities of the recorded steps ``k0 .. k1 - 1`` (``K``:
    :class:`~morphlab.kernels.adjoint.Keep`; ``F``: a factor of the run, for the patterns):
    right-hand sides, one solve with the step's factors for every variable, refinement (exact
    variant) and the update, step by step (module docstring). ``refine``, ``w_old`` as for
    :func:`prepare`. ``rhs_only``: the right-hand sides of step ``k0`` alone, into ``d.rhs``
    and ``d.x`` (a step solved from Python: the caller solves, refines and stores it; the
    factor fields of ``K`` are not read). ``M``, ``T``: the system and time values, read to
    form matrices (the exact variant, the old level's share) and by the perturbed path's
    forward difference alone; else None."""
    x = d.x
    for k in range(k0, k1):
        j = k - K.k0[0]
        new, old = kept_state(K, j + 1), kept_state(K, j)
        prepare(d, M, T, sc, K.D[j, 0], K.D[j, 1], new, old, k, refine, w_old)
        if rhs_only:
            return
        Fk = kept_factor(K, F, j)
        solve_factored(x, d.work, Fk)
        if refine is not None:
            if refine > 0:
                for _ in range(refine):
                    refinement_residual(d)
                    solve_factored(d.r, d.work, Fk)
                    for r in range(x.shape[0]):
                        for i in range(x.shape[1]):
                            x[r, i] += d.r[r, i]
                rr, bb = refinement_residual(d)
                d.refined[k] = rr / max(bb, 1e-300)
        store(d.DQ, d.DV, d.DA, d.DG, d.DL, sc, x, k)
