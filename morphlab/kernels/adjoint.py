"""The discrete adjoint of the time loop: the forward record of each step and the backward
sweep over a segment of steps in one compiled call (``docs/theory.md`` §7).

The exact transpose of the direct recursion (:mod:`morphlab.kernels.direct`): for the steps of
a segment from the last to the first, with the adjoint of the state ``x_k`` held in ``Bq, Bv,
Ba, Bg, Bl`` ((width, m), one column per response) and the responses' own derivatives at
``k`` added first (``Hq, Hv, Ha, Hl`` (n_t, width, m)):

* ``z̄ = (ā + bh2 q̄ + gh v̄ + ga ḡ, s λ̄)``;
* ``μ = J^-T z̄`` with the step's kept factors;
* ``μ`` kept for the design's share (below);
* ``q̂̄ = q̄ - Dq^T μ``, ``v̂̄ = v̄ - Dv^T μ`` with the ``Dq``, ``Dv`` kept from the step's last
  Newton fill (the direct method's reuse variant transposed; the exact variant forms them and
  ``J*`` at the converged state and refines ``μ`` against ``J*``);
* the adjoint of ``x_k-1`` through the predictors and, with the paper's weighting, the old
  level's share.

At the initial solve (time index 0) the sweep stops with ``Bq, Bv`` holding the adjoints of
``q_0, q'_0``, which meet their derivatives from ``build``.

The design's share of each step, ``grad_i -= (dR/dp_i)^T μ`` (:mod:`morphlab.kernels.pseudo`,
over the residual rows variable ``i``'s parts touch; for the variables that change the bodies'
linear data alone, the data gradient ``G += d(μ^T R)/dD`` instead, once for all of them,
:mod:`morphlab.kernels.ffrf_adjoint`, which the caller contracts with their ``dD/dp``), feeds
nothing back into the recursion: a kernel of its own (:func:`shares`) forms it from the kept
``μ`` of a block of swept steps, beside the sweep of the next block. Apart, the sweep compiles
without the types of the pseudo-load data (about half its compile), and the shares take a
second core where one is free.
"""

from typing import NamedTuple

import numpy as np
from numba.core import types
from numba.extending import overload

from ._jit import inlined, inner, kernel
from .assemble import matrix
from .csc import residual, subtract_product, subtract_products_transposed
from .ffrf_adjoint import data_gradient, stiffness_share
from .newton import Factors, solve_factored_transposed
from .pseudo import explicit, load
from .types import Level


class Keep(NamedTuple):
    """The record of the steps ``k0 <= k < k0 + K`` a sensitivity method reads: row
    ``k - k0`` of the factor values (``LU`` (K, n, n), ``piv`` (K, n) dense; ``Lx``, ``Ux``,
    ``Ud`` (K, ...) sparse; the other kind's None), of ``D`` (K, 2, nnz), the
    ``Dq``, ``Dv`` of the step's last Newton fill, and row ``k - k0 + 1`` of the states ``Q,
    V, A`` (K + 1, n_dof), ``L`` (K + 1, n_con) (row 0: the state before the first step,
    which the caller writes). ``k0`` (1,) int64."""

    LU: np.ndarray
    piv: np.ndarray
    Lx: np.ndarray
    Ux: np.ndarray
    Ud: np.ndarray
    D: np.ndarray
    Q: np.ndarray
    V: np.ndarray
    A: np.ndarray
    L: np.ndarray
    k0: np.ndarray


class Sweep(NamedTuple):
    """The adjoint state and buffers of a backward sweep: ``Bq, Bv, Ba, Bg`` (n_dof, m),
    ``Bl`` (n_con, m) (module docstring); the responses' terms ``Hq, Hv, Ha`` (n_t, n_dof,
    m), ``Hl`` (n_t, n_con, m) (empty: none), their row ``k - h0[0]`` time index ``k``;
    buffers ``zb``, ``mu``, ``r``, ``work`` (n, m), ``gb`` (n_dof, m), ``mats`` (6, nnz),
    ``refined`` (n_t,) and the bodies' scratch ``W`` (:func:`~morphlab.kernels.ffrf.scratch`,
    real; None where the sweep forms no matrix). The design's shares are not here
    (:class:`Shares`): the sweep compiles without the pseudo-load data's types."""

    Bq: np.ndarray
    Bv: np.ndarray
    Ba: np.ndarray
    Bg: np.ndarray
    Bl: np.ndarray
    Hq: np.ndarray
    Hv: np.ndarray
    Ha: np.ndarray
    Hl: np.ndarray
    h0: np.ndarray
    zb: np.ndarray
    mu: np.ndarray
    r: np.ndarray
    work: np.ndarray
    gb: np.ndarray
    mats: np.ndarray
    refined: np.ndarray
    W: tuple


class Shares(NamedTuple):
    """What the design's shares read and accumulate (:func:`shares`): the pseudo-load data
    ``ps`` with the residual rows each variable touches ``RO`` (n_x + 1,), ``RI``, and its
    units of evaluation (unit ``u`` evaluates variable ``UV[u]`` of ``ps`` for the variables
    ``UI[UO[u]:UO[u + 1]]``: ``morphlab.sensitivity.units.share_units``); the gradient
    ``grad`` (n_x, m) and the bodies' data gradient ``G`` (n_design, m; no rows: none) with
    its offsets ``GO`` (:func:`~morphlab.kernels.ffrf_adjoint.data_gradient`), accumulated;
    the stiffness derivatives of its variables ``KO``, ``KX``, ``KE``, ``KV``
    (:func:`~morphlab.kernels.ffrf_adjoint.stiffness_share`); the buffer ``column``
    (:class:`~morphlab.kernels.pseudo.Column`); ``probe`` (units, n): no rows for the shares
    of a run; with rows, a probe of the rows the variables touch (:func:`_design_share`)."""

    ps: tuple
    RO: np.ndarray
    RI: np.ndarray
    UO: np.ndarray
    UI: np.ndarray
    UV: np.ndarray
    grad: np.ndarray
    G: np.ndarray
    GO: np.ndarray
    KO: np.ndarray
    KX: np.ndarray
    KE: np.ndarray
    KV: np.ndarray
    column: tuple
    probe: np.ndarray


@inner
def keep(K, F, data, x, k):
    """Record step ``k``'s factors ``F``, the ``Dq``, ``Dv`` of its last fill ``data`` (3, nnz)
    and its state ``x`` in ``K`` (None: nothing kept)."""
    if K is None or K.D.shape[0] == 0:  # nothing kept (an empty record: a primal run)
        return
    j = k - K.k0[0]
    for r in range(x.q.shape[0]):
        K.Q[j + 1, r] = x.q[r]
        K.V[j + 1, r] = x.v[r]
        K.A[j + 1, r] = x.a[r]
    for r in range(x.lam.shape[0]):
        K.L[j + 1, r] = x.lam[r]
    _copy_row(K.LU, F.LU, j)  # the fields of the factor's kind (the others are None)
    _copy_row(K.piv, F.piv, j)
    _copy_row(K.Lx, F.Lx, j)
    _copy_row(K.Ux, F.Ux, j)
    _copy_row(K.Ud, F.Ud, j)
    for p in range(K.D.shape[2]):  # the reuse variant's blocks (none in the exact one)
        K.D[j, 0, p] = data[1, p]
        K.D[j, 1, p] = data[2, p]


@inner
def _copy_row(rows, x, j):
    """``rows[j] = x`` (nothing when ``x`` is None: a field of the other kind of factor)."""
    if x is not None:
        flat, src = rows[j].reshape(-1), x.reshape(-1)
        for p in range(src.shape[0]):
            flat[p] = src[p]


def _row(x, j):
    """``x[j]``, or None for None (a field of the other kind of factor)."""


@overload(_row)
def _row_typed(x, j):
    if isinstance(x, types.NoneType):
        return lambda x, j: None
    return lambda x, j: x[j]


@inner
def kept_state(K, j):
    """The state (:class:`~morphlab.kernels.types.Level`) of row ``j`` of the record."""
    return Level(K.Q[j], K.V[j], K.A[j], K.L[j])


@inner
def kept_factor(K, F, j):
    """The :class:`~morphlab.kernels.newton.Factors` of row ``j`` of ``K`` (the patterns of
    ``F``)."""
    return Factors(_row(K.LU, j), _row(K.piv, j), _row(K.Lx, j), _row(K.Ux, j), _row(K.Ud, j),
                   F.order, F.pattern)


@inlined
def _design_share(a, M, T, sc, mu, new, old, k):
    """``grad_i -= (dR_k/dp_i)^T mu`` for every variable of a unit, over the rows it touches;
    the bodies' data gradient ``G += d(mu^T R_k)/dD`` (module docstring); ``a``:
    :class:`Shares`, ``mu`` (n, m) the step's adjoint vector. A probe (``a.probe`` with rows:
    ``morphlab.sensitivity.adjoint._touched``) writes unit ``u``'s explicit column into
    ``a.probe[u]`` instead, all of it: which rows a variable touches is what it finds."""
    # the fields the loop reads, bound before it (read inside, the large ``ps`` is extracted
    # from ``a`` again for every call), and ``explicit`` called here, not through a helper
    # (an inlined one copies ``ps`` too): each costs 0.2 of the pendulum's sweep
    ps, column, probe = a.ps, a.column, a.probe
    col = column.R
    m = mu.shape[1]
    load(column.XN, new)  # the levels in the perturbed path's dtype, once for all variables
    if sc.has_old:
        load(column.XO, old)
    B, Fx, E, g, L = M.bodies, M.flex, M.elements, M.gravity, ps.WL.loc
    data_gradient(B, Fx, E, g, new, sc.w_new, mu, a.G, a.GO, L)
    stiffness_share(B, Fx, E, new, sc.w_new, mu, a.KO, a.KX, a.KE, a.KV, a.grad, L)
    if sc.has_old:
        data_gradient(B, Fx, E, g, old, sc.w_old, mu, a.G, a.GO, L)
        stiffness_share(B, Fx, E, old, sc.w_old, mu, a.KO, a.KX, a.KE, a.KV, a.grad, L)
    for u in range(a.UV.shape[0]):  # a unit: one variable, or a group with disjoint rows
        v = a.UV[u]
        explicit(ps, ps.MN, M, T, v, new, column.XN, sc.w_new, k, column)
        if sc.has_old:
            explicit(ps, ps.MN, M, T, v, old, column.XO, sc.w_old, k - 1, column)
        if probe.shape[0] > 0:
            for r in range(col.shape[0]):
                probe[u, r] = col[r]
                col[r] = 0.0
            continue
        for jj in range(a.UO[u], a.UO[u + 1]):
            i = a.UI[jj]
            for j in range(a.RO[i], a.RO[i + 1]):
                r = a.RI[j]
                for c in range(m):
                    a.grad[i, c] -= col[r] * mu[r, c]
                col[r] = 0.0


@kernel(nogil=True)
def shares(a, M, T, sc, K, MU, k_hi, k_lo):
    """The design's shares (:func:`_design_share`) of the steps ``k_hi`` down to ``k_lo``
    recorded in ``K`` (:class:`Keep`; its states are read, its factor fields may be None)
    with their adjoint vectors ``MU[k - k_lo]`` (n, m), which :func:`sweep` wrote, into the
    :class:`Shares` ``a``. ``M``, ``T``: the nominal system and time values; without a
    perturbed path in ``a.ps``, the bodies' kinds of ``M`` are read alone, and ``T`` may be
    None. Apart from the sweep: nothing of the sweep reads them, so they can run beside the
    sweep's next steps."""
    for k in range(k_hi, k_lo - 1, -1):
        j = k - K.k0[0]
        _design_share(a, M, T, sc, MU[k - k_lo], kept_state(K, j + 1), kept_state(K, j), k)


@inner
def begin(Bq, Bv, Ba, Bg, Bl, Hq, Hv, Ha, Hl, h0, zb, mu, sc, k):
    """Add the responses' terms at time index ``k`` to the adjoint state and form ``z̄`` into
    ``zb`` and ``mu`` (then solved in place with ``J^-T``); the arguments are the fields of
    :class:`Sweep` of those names. Called by :func:`sweep` alone: a step solved from Python is
    begun by the sweep too (its ``stop``)."""
    n_dof = Bq.shape[0]
    n_con = Bl.shape[0]
    m = Bq.shape[1]
    bh2, gh, ga = sc.pc[5], sc.pc[6], sc.upd[0]
    h = k - h0[0]
    if 0 <= h < Hq.shape[0]:
        for i in range(n_dof):
            for c in range(m):
                Bq[i, c] += Hq[h, i, c]
                Bv[i, c] += Hv[h, i, c]
                Ba[i, c] += Ha[h, i, c]
        for i in range(n_con):
            for c in range(m):
                Bl[i, c] += Hl[h, i, c]
    for i in range(n_dof):
        for c in range(m):
            zb[i, c] = Ba[i, c] + bh2 * Bq[i, c] + gh * Bv[i, c] + ga * Bg[i, c]
    for i in range(n_con):
        for c in range(m):
            zb[n_dof + i, c] = sc.w_new.scale * Bl[i, c]
    for i in range(n_dof + n_con):
        for c in range(m):
            mu[i, c] = zb[i, c]


@kernel
def exact_matrices(a, M, T, sc, new, k):
    """The exact variant: ``D0, Dq, Dv`` at the converged state ``new`` of time index ``k``
    into ``a.mats[0:3]`` and ``J* = D0 + bh2 Dq + gh Dv`` over ``a.mats[0]``."""
    C = np.array([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]])
    matrix(M, new, sc.w_new, T, np.int64(0), k, C, a.mats[0:3], a.W)
    bh2, gh = sc.pc[5], sc.pc[6]
    J = a.mats[0]
    for p in range(J.shape[0]):
        J[p] = J[p] + bh2 * a.mats[1, p] + gh * a.mats[2, p]


@kernel
def refinement_residual(a, csc):
    """``a.r = z̄ - J*^T μ`` (the exact variant's refinement); returns ``(|r|, |z̄|)``."""
    return residual(a.mats[0], csc.indices, csc.indptr, a.mu, a.zb, a.r, True)


@inlined
def finish(a, M, T, sc, csc, Dq, Dv, new, old, k, w_old):
    """The rest of step ``k`` (from the state ``old`` to ``new``) once ``a.mu`` holds ``μ``:
    the adjoints of the predictors (``Dq``, ``Dv`` the step's, (nnz,)) and of the previous
    state, with the old level's share for ``w_old`` not None (the :func:`sweep`'s). Returns
    True at the initial solve (``k == 0``).

    Inlined into :func:`sweep`, its one caller (a step solved from Python goes through
    :func:`sweep` too, with ``stop`` and ``solved``): compiled as a kernel of its own, its
    code and that of everything it calls would be emitted once more (``_jit``'s
    docstring)."""
    n_dof = a.Bq.shape[0]
    n_con = a.Bl.shape[0]
    n = n_dof + n_con
    m = a.Bq.shape[1]
    h, cqa, cqg, cva, cvg = sc.pc[0], sc.pc[1], sc.pc[2], sc.pc[3], sc.pc[4]
    gan, ggn = sc.upd[1], sc.upd[2]
    # the adjoints of q_hat and v_hat
    subtract_products_transposed(Dq, Dv, csc.indices, csc.indptr, n_dof, a.mu, a.Bq, a.Bv)
    if k == 0:
        return True
    for i in range(n_dof):
        for c in range(m):
            a.gb[i, c] = a.Bg[i, c]
    for i in range(n_dof):
        for c in range(m):
            qhb = a.Bq[i, c]
            vhb = a.Bv[i, c]
            a.Bg[i, c] = cqg * qhb + cvg * vhb + ggn * a.gb[i, c]
            a.Ba[i, c] = cqa * qhb + cva * vhb + gan * a.gb[i, c]
            a.Bv[i, c] = h * qhb + vhb
    for i in range(n_con):
        for c in range(m):
            a.Bl[i, c] = 0.0
    if w_old is not None and sc.has_old:  # the paper's weighting: the old level's share
        C = np.array([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]])
        matrix(M, old, w_old, T, np.int64(0), k - 1, C, a.mats[3:6], a.W)
        subtract_products_transposed(a.mats[4], a.mats[5], csc.indices, csc.indptr, n_dof,
                                     a.mu, a.Bq, a.Bv)
        for i in range(n):
            for c in range(m):
                a.r[i, c] = 0.0
        subtract_product(a.mats[3], csc.indices, csc.indptr, n, a.mu, a.r, True)
        for i in range(n_dof):
            for c in range(m):
                a.Ba[i, c] += a.r[i, c]
        for i in range(n_con):
            for c in range(m):
                a.Bl[i, c] += a.r[n_dof + i, c] / sc.w_new.scale
    return False


@kernel(nogil=True)
def sweep(M, T, sc, csc, F, K, a, MU, k_hi, k_lo, refine, solved, stop, w_old):
    """Steps ``k_hi`` down to ``k_lo`` of the backward sweep (module docstring) with the
    factors, fills and states recorded in ``K`` (:class:`Keep`), each step's ``μ`` into
    ``MU[k - k_lo]`` for its design's share (:func:`shares`); ``F``: a factor of the run,
    for the patterns; ``refine``: None for the reuse variant (then the exact variant's code is
    not compiled), else the exact variant's number of refinement sweeps. A step whose factor
    the caller solves (a step solved from Python) takes two calls: the first with ``stop``
    its time index returns with its ``z̄`` formed in ``a.zb`` and ``a.mu``; the caller solves
    ``μ`` in place (and, in the exact variant, forms ``a.mats`` and refines), and the second
    with ``solved`` its time index goes on from there (its factor fields in ``K`` are not
    read). -1: none. ``w_old``: the weights of the scheme's old level (``sc.w_old``), None
    for a scheme without one: then the old level's matrix code is not compiled (Numba prunes
    a branch on an argument that is None, not on a field of one). Returns True when it
    reached the initial solve. ``M``, ``T``: the system and time values, read only to form
    matrices (the exact variant, the old level's share), else None."""
    n = a.mu.shape[0]
    m = a.mu.shape[1]
    for k in range(k_hi, k_lo - 1, -1):
        j = k - K.k0[0]
        new, old = kept_state(K, j + 1), kept_state(K, j)
        if k != solved:
            begin(a.Bq, a.Bv, a.Ba, a.Bg, a.Bl, a.Hq, a.Hv, a.Ha, a.Hl, a.h0, a.zb, a.mu, sc,
                  k)
            if k == stop:
                return False
            Fk = kept_factor(K, F, j)
            solve_factored_transposed(a.mu, a.work, Fk)
            if refine is not None:
                exact_matrices(a, M, T, sc, new, k)
                if refine > 0:
                    for _ in range(refine):
                        refinement_residual(a, csc)
                        solve_factored_transposed(a.r, a.work, Fk)
                        for i in range(n):
                            for c in range(m):
                                a.mu[i, c] += a.r[i, c]
                    rr, bb = refinement_residual(a, csc)
                    a.refined[k] = rr / max(bb, 1e-300)
        for i in range(n):
            for c in range(m):
                MU[k - k_lo, i, c] = a.mu[i, c]
        if refine is None:
            Dq, Dv = K.D[j, 0], K.D[j, 1]
        else:
            Dq, Dv = a.mats[1], a.mats[2]
        if finish(a, M, T, sc, csc, Dq, Dv, new, old, k, w_old):
            return True
    return False
