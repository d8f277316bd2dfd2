"""Direct-differentiation kernels: the work of one sensitivity step in a few compiled calls.

After the primal has converged a step (``morphlab.sensitivity``), the right-hand side of design
variable ``i`` is ``-D_i R``, the derivative of the step residual at the converged unknowns
along ``(ds_n/dp_i, e_i)``. It is split into

* the state part, the same for every variable's direction: the residual depends on the old
  state through the Newmark predictors ``q_hat, v_hat`` (and, with the paper's weighting, through
  its old-level share), so ``R_q dq_hat + R_v dv_hat (+ old-level terms)``, with ``R_q`` and
  ``R_v`` taken from the primal's exact Newton-matrix kernel (:func:`split_matrices`) and
  applied to all n_x columns at once (:func:`state_loads`);
* the explicit part ``dR/dp_i`` at the converged (real) state, by complex step or forward
  difference of the primal's own residual kernel, evaluated only over the bodies, elements,
  flexible coordinates, constraint rows, loads and torques whose data variable ``i`` changes
  (:func:`explicit_loads`). The state is real, so the parts left out carry no imaginary part
  (and cancel in a difference): the derivative is exact, and a thickness variable of a few
  elements costs a few elements, not a whole residual.

Then one solve with the primal's last factorization, iterative refinement against the exact
converged matrix (:func:`csc_residual`, the matrix comes from :func:`state_loads`), and
:func:`update_sensitivities`, the Newmark update of the histories. A run forms the explicit
parts of a block of steps in one call (:func:`explicit_block`); with dense factors the whole
recursion over the block is one call as well (:func:`block_recursion`, for dense factors and
for sparse ones of one row order); for SuperLU's factors the solves are made from Python.

The step coefficients travel as the two arrays ``pc`` and ``upd`` of
:mod:`morphlab.kernels.newmark`, whose predictor and update the primal applies to its state and
these kernels to every sensitivity column.
"""

import numpy as np
from numba import njit

from .assemble import add_part_residual, fill_split
from .ffrf import PartScratch
from .newmark import predict, update
from .newton import solve_factored
from .system import Parts, set_design


@njit(cache=True)
def split_matrices(S, q, v, a, lam, w, scale, b0, b1, F, D):
    """Derivatives of one time level's residual share (weights ``w = (wm, wl, wf, wcm, wcf)``)
    as CSC data over the step pattern, in one pass over the model
    (:func:`~morphlab.kernels.assemble.fill_split`): ``D[0] = dR/d(a, lam/scale)`` with
    ``q, q'`` held, ``D[1] = dR/dq`` and ``D[2] = dR/dq'`` (their multiplier columns are
    zero). The Newton matrix is ``D[0] + bh2 D[1] + gh D[2]``. ``D`` (3, nnz) float64."""
    fill_split(S, q, v, a, lam, w[0], w[1], w[2], w[3], w[4], scale, b0, b1, F,
               ((1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0)), D)


@njit(cache=True)
def _subtract_product(data, indices, indptr, n_cols, X, out):
    """``out -= A[:, :n_cols] X`` for the CSC matrix ``A = (data, indices, indptr)``."""
    n_x = X.shape[1]
    for j in range(n_cols):
        for p in range(indptr[j], indptr[j + 1]):
            row = indices[p]
            aij = data[p]
            for i in range(n_x):
                out[row, i] -= aij * X[j, i]


@njit(cache=True)
def state_loads(S, q1, v1, a1, l1, w_new, has_old, q0, v0, a0, l0, w_old, F, k_new, scale, b0,
                b1, bh2, gh, indices, indptr, n_dof, DQ, DV, DA, DG, DLAM, k, pc, mats, J, rhs):
    """Subtract the state part of every pseudo-load from ``rhs`` (n, n_x), and overwrite ``J``
    (nnz,) with the exact Newton matrix at the converged point (for the refinement).

    ``(q1, v1, a1, l1)``: the converged state at ``t_{n+1}``; ``(q0, v0, a0, l0)``: the state
    at ``t_n`` (read only when ``has_old``, the paper's weighting); ``F`` (n_t, n_load, 2):
    the point forces at every time; ``k_new`` and ``k``: the time indices of ``t_{n+1}`` and
    ``t_n``; ``DQ ... DLAM``: the sensitivity histories, (n_x, levels, width), level ``k`` is
    the old one; ``mats`` (6, nnz): scratch for the split matrices of both levels
    (:func:`split_matrices`). All arrays float64.
    """
    n_x = rhs.shape[1]
    D0, Dq, Dv = mats[0], mats[1], mats[2]
    split_matrices(S, q1, v1, a1, l1, w_new, scale, b0, b1, F[k_new], mats[0:3])
    for p in range(J.shape[0]):
        J[p] = D0[p] + bh2 * Dq[p] + gh * Dv[p]
    # each history may keep only its last levels (see update_sensitivities)
    kq, kv, ka, kg, kl = (k % DQ.shape[1], k % DV.shape[1], k % DA.shape[1], k % DG.shape[1],
                          k % DLAM.shape[1])
    dqh = np.empty((n_x, n_dof))
    dvh = np.empty((n_x, n_dof))
    for i in range(n_x):
        predict(pc, DQ[i, kq], DV[i, kv], DA[i, ka], DG[i, kg], dqh[i], dvh[i])
    _subtract_product(Dq, indices, indptr, n_dof, dqh.T, rhs)
    _subtract_product(Dv, indices, indptr, n_dof, dvh.T, rhs)
    if has_old:
        D0, Dq, Dv = mats[3], mats[4], mats[5]
        split_matrices(S, q0, v0, a0, l0, w_old, scale, b0, b1, F[k], mats[3:6])
        n_con = DLAM.shape[2]
        x0 = np.empty((n_dof + n_con, n_x))
        for i in range(n_x):
            for r in range(n_dof):
                x0[r, i] = DA[i, ka, r]
            for r in range(n_con):
                x0[n_dof + r, i] = DLAM[i, kl, r] / scale
        _subtract_product(Dq, indices, indptr, n_dof, DQ[:, kq, :].T, rhs)
        _subtract_product(Dv, indices, indptr, n_dof, DV[:, kv, :].T, rhs)
        _subtract_product(D0, indices, indptr, n_dof + n_con, x0, rhs)


@njit(cache=True)
def _explicit_residual(S, parts, q1, v1, a1, l1, w_new, ta_new, has_old, q0, v0, a0, l0, w_old,
                       ta_old, scale, b0, b1, n_dof, R, W):
    """Overwrite ``R`` with the step residual over ``parts`` (both levels when ``has_old``)."""
    R[:] = 0.0
    add_explicit_residual(S, parts, q1, v1, a1, l1, w_new, ta_new, has_old, q0, v0, a0, l0,
                          w_old, ta_old, scale, b0, b1, n_dof, R, W)


@njit(cache=True, inline="always")
def add_explicit_residual(S, parts, q1, v1, a1, l1, w_new, ta_new, has_old, q0, v0, a0, l0,
                          w_old, ta_old, scale, b0, b1, n_dof, R, W):
    """Add the step residual over ``parts`` (both levels when ``has_old``) to ``R``; ``W``:
    the scratch of :func:`~morphlab.kernels.ffrf.body_part_residual` (:func:`part_scratch`)."""
    if has_old:
        add_part_residual(S, parts, q0, v0, a0, l0, w_old[0], w_old[1], w_old[2], w_old[3],
                          w_old[4], scale, b0, b1, ta_old[0], ta_old[1], ta_old[2], ta_old[3],
                          ta_old[4], n_dof, R, W)
    add_part_residual(S, parts, q1, v1, a1, l1, w_new[0], w_new[1], w_new[2], w_new[3],
                      w_new[4], scale, b0, b1, ta_new[0], ta_new[1], ta_new[2], ta_new[3],
                      ta_new[4], n_dof, R, W)


@njit(cache=True)
def part_scratch(S, q, R):
    """The scratch of :func:`add_explicit_residual` (:class:`~morphlab.kernels.ffrf.
    PartScratch`) for the system ``S``, a state like ``q`` and a residual like ``R``."""
    m = S.flex_dof.shape[0] + 1
    return PartScratch(np.zeros((3, m), dtype=q.dtype), np.zeros((7, m), dtype=R.dtype),
                       np.zeros(6, dtype=np.int64), np.zeros((3, 6), dtype=q.dtype),
                       np.zeros(6, dtype=R.dtype))


@njit(cache=True, inline="always")
def table_at(TAB, k, t):
    """The time arrays ``(c, cd, cdd, F, T)`` of table ``t`` of ``TAB`` at time index ``k``."""
    return (TAB[0][k, t], TAB[1][k, t], TAB[2][k, t], TAB[3][k, t], TAB[4][k, t])


@njit(cache=True, inline="always")
def parts_of(parts, i, flex_on):
    """:class:`~morphlab.kernels.system.Parts` of variable ``i`` from the packed ``parts``
    (CSR over the variables, see :func:`explicit_loads`), with the mask ``flex_on``, and the
    variable's flexible coordinates (to set in and clear from that mask)."""
    (b_off, b_idx, e_off, e_idx, f_off, f_idx, c_off, c_idx, l_off, l_idx, t_off, t_idx, s_off,
     s_idx) = parts
    pi = Parts(b_idx[b_off[i]:b_off[i + 1]], e_idx[e_off[i]:e_off[i + 1]], flex_on,
               c_idx[c_off[i]:c_off[i + 1]], l_idx[l_off[i]:l_off[i + 1]],
               t_idx[t_off[i]:t_off[i + 1]], s_idx[s_off[i]:s_off[i + 1]])
    return pi, f_idx[f_off[i]:f_off[i + 1]]


@njit(cache=True, inline="always")
def elastic_force(S, dK, dC, e, q, v, fl):
    """``fl = dK q_e + dC v_e`` (6,) float64: the derivative of element ``e``'s elastic and
    damping force ``K_e (q_e + beta v_e)`` along a design change of its stiffness ``K_e`` and
    its body's damping ``beta`` alone (``dK = dK_e``, ``dC = d(beta K_e)``, (6, 6) float64), at
    the real state ``(q, v)``. Entries of coordinates removed by a reference condition are
    zero."""
    for a in range(6):
        fl[a] = 0.0
    for b in range(6):
        f = S.elem_fdof[e, b]
        if f < 0:
            continue
        r = S.flex_dof[f]
        qb = q[r]
        vb = v[r]
        for a in range(6):
            fl[a] += dK[a, b] * qb + dC[a, b] * vb
    for a in range(6):
        if S.elem_fdof[e, a] < 0:
            fl[a] = 0.0


@njit(cache=True, inline="always")
def elastic_share(S, lin, i, Q, V, j, has_old, w_new, w_old, fl, d):
    """Add to ``d`` (n,) float64 the partial derivative of step ``j``'s residual (from the
    state ``(Q[j], V[j])`` to ``(Q[j + 1], V[j + 1])``) along the stiffness variable ``i`` of
    ``lin`` (:func:`explicit_loads`): ``w_f (dK_e q_e + dC_e q_e')`` over its elements, at
    both levels when ``has_old``. Only the rows of the elements' flexible coordinates are
    written. ``fl`` (6,): scratch."""
    lin_off, lin_elem, lin_dK, lin_dC = lin
    for lev in range(2 if has_old else 1):
        jj, wf = (j + 1, w_new[2]) if lev == 0 else (j, w_old[2])
        for k in range(lin_off[i], lin_off[i + 1]):
            e = lin_elem[k]
            elastic_force(S, lin_dK[k], lin_dC[k], e, Q[jj], V[jj], fl)
            for a in range(6):
                f = S.elem_fdof[e, a]
                if f >= 0:
                    d[S.flex_dof[f]] += wf * fl[a]


@njit(cache=True)
def explicit_loads(S, W, D, parts, lin, q1, v1, a1, l1, w_new, has_old, q0, v0, a0, l0, w_old,
                   scale, b0, b1, TAB, tab_of, k_old, k_new, n_dof, pert, work, rhs):
    """Subtract the explicit part of every pseudo-load from ``rhs`` (n, n_x):
    ``rhs[:, i] -= Re[(R_i(D_i) - R_i(D_0)) / pert_i]``, ``R_i`` the step residual at the
    converged state over variable ``i``'s parts, with design ``i``'s data and time arrays table
    ``tab_of[i]`` of ``TAB``, or the nominal ``S`` and table 0. With a complex step
    (``pert_i = i h``) this is ``Im R_i(D_i) / h`` and ``R_i(D_0)`` is not evaluated.

    Parameters
    ----------
    S : SystemArrays
        Nominal system arrays in the dtype of ``work``.
    W : SystemArrays
        ``S`` with its own copy of the design data: design ``i`` is written into it while its
        part is evaluated (:func:`~morphlab.kernels.system.set_design`), then ``S``'s again.
    D : DesignRows
        The rows of the design data each of the n_x perturbed designs changes.
    parts : tuple of 14 int64 arrays
        ``(offsets, indices)`` of the bodies, elements, flexible coordinates, constraint rows,
        loads, torques and spring-dampers each variable changes (CSR layout over the
        variables).
    lin : ``(off, elems, dK, dC)``
        The variables that change element stiffnesses and stiffness-proportional damping and
        nothing else (CSR over the variables, ``off`` (n_x + 1,) int64; ``elems`` (nnz,)
        int64; ``dK``, ``dC`` (nnz, 6, 6) float64 the derivatives of each element's ``K_e``
        and ``beta K_e``). The residual is linear in both, so their partial derivative is
        ``w_f (dK_e q_e + dC_e q_e')`` over their elements in real arithmetic
        (:func:`elastic_force`), not a residual of complex data over their bodies; ``parts``
        is not read for them.
    q1, v1, a1, l1 / q0, v0, a0, l0 : float64
        Converged states at ``t_{n+1}`` and ``t_n`` (the latter used when ``has_old``), kept
        real: with complex data only the products with changed data are complex (the
        kernels' temporaries take the dtype of the residual), cheaper than casting the state
        to complex.
    TAB : tuple ``(C, CD, CDD, F, T)`` with leading axes (n_t, n_tab)
        The distinct time arrays of the designs at every time, table 0 the nominal one.
    tab_of : (n_x,) int64
        The table of each variable's design (0 where it changes no profile or constant).
    k_old, k_new : int
        Time indices of ``t_n`` and ``t_{n+1}``.
    pert : (n_x,)
        ``1e-30j`` (complex step) or the forward-difference steps (dtype of ``work``).
    work : (2, n)
        Scratch residuals.
    """
    explicit_block(S, W, D, parts, lin, np.stack((q0, q1)), np.stack((v0, v1)), np.stack((a0, a1)),
                   np.stack((l0, l1)), w_new, has_old, w_old, scale, b0, b1, TAB, tab_of,
                   np.array([k_old]), np.array([k_new]), n_dof, pert, work,
                   rhs.reshape((1, rhs.shape[0], rhs.shape[1])))


@njit(cache=True)
def explicit_block(S, W, D, parts, lin, Q, V, A, L, w_new, has_old, w_old, scale, b0, b1,
                   TAB, tab_of, k_old, k_new, n_dof, pert, work, E):
    """:func:`explicit_loads` of ``K`` consecutive steps in one call: step ``j`` goes from the
    state ``(Q[j], V[j], A[j], L[j])`` at time index ``k_old[j]`` to ``(Q[j+1], ...)`` at
    ``k_new[j]`` (state arrays (K + 1, width)); its explicit parts are subtracted from
    ``E[j]`` (K, n, n_x). The partial derivatives need only the converged primal states, so
    a run forms them for a block of steps at once, variable by variable: design ``i`` is
    written into ``W`` once for all the steps of the block."""
    n_x = E.shape[2]
    n = E.shape[1]
    forward = pert[0].imag == 0.0
    R = work[0]
    R0 = work[1]
    scr = part_scratch(S, Q[0], R)
    flex_on = np.zeros(S.flex_dof.shape[0], dtype=np.bool_)
    lin_off, lin_elem = lin[0], lin[1]
    fl = np.empty(6)
    share = np.zeros(n)
    for i in range(n_x):
        if lin_off[i + 1] > lin_off[i]:  # the stiffness alone: real products per element
            for j in range(E.shape[0]):
                elastic_share(S, lin, i, Q, V, j, has_old, w_new, w_old, fl, share)
                for k in range(lin_off[i], lin_off[i + 1]):
                    for f in S.elem_fdof[lin_elem[k]]:
                        if f >= 0:
                            r = S.flex_dof[f]
                            E[j, r, i] -= share[r]
                            share[r] = 0.0
            continue
        pi, flex = parts_of(parts, i, flex_on)
        if (pi.bodies.size + pi.rows.size + pi.loads.size + pi.torques.size
                + pi.springs.size) == 0:
            continue  # the variable changes only the initial state
        for k in flex:
            flex_on[k] = True
        ti = tab_of[i]
        set_design(W, S, D, i, True)
        for j in range(E.shape[0]):
            ko, kn = k_old[j], k_new[j]
            _explicit_residual(W, pi, Q[j + 1], V[j + 1], A[j + 1], L[j + 1], w_new,
                               table_at(TAB, kn, ti), has_old, Q[j], V[j], A[j], L[j], w_old,
                               table_at(TAB, ko, ti), scale, b0, b1, n_dof, R, scr)
            if forward:
                _explicit_residual(S, pi, Q[j + 1], V[j + 1], A[j + 1], L[j + 1], w_new,
                                   table_at(TAB, kn, 0), has_old, Q[j], V[j], A[j], L[j],
                                   w_old, table_at(TAB, ko, 0), scale, b0, b1, n_dof, R0, scr)
                for r in range(n):
                    E[j, r, i] -= ((R[r] - R0[r]) / pert[i]).real
            else:  # Re(R / (i h)) = Im(R) / h
                h = pert[i].imag
                for r in range(n):
                    E[j, r, i] -= R[r].imag / h
        set_design(W, S, D, i, False)
        for k in flex:
            flex_on[k] = False


@njit(cache=True)
def block_recursion(S, Q, V, A, L, w_new, has_old, w_old, F, k_old, k_new, scale, b0, b1, bh2,
                    gh, indices, indptr, n_dof, DQ, DV, DA, DG, DLAM, pc, upd, mats, J, E,
                    LU, piv, Lx, Ux, Ud, pattern, refine, n_refine, r, x, work, refined):
    """The sensitivity recursion over a block of steps in one call, for steps whose factors are
    all dense (``LU``, ``piv``: (K, n, n), (K, n); ``morphlab.kernels.dense``) or all sparse
    with one row order (``Lx``, ``Ux``, ``Ud``: (K, ...) and their ``pattern``); the other
    kind's stacks hold K empty factors (e.g. ``LU`` (K, 0, 0)), so step ``j``'s factor is
    :func:`morphlab.kernels.newton.solve_factored`'s ``LU[j], piv[j], Lx[j], ...``. Per step
    ``j``, as ``morphlab.sensitivity.direct._DirectPass`` does from Python for other
    factors: the state part (:func:`state_loads`) subtracted from ``E[j]``, which holds the
    explicit part; the solve with the step's factors; ``n_refine`` refinement sweeps against
    the exact converged matrix where ``refine[j]``, writing the relative residual to
    ``refined[j]``; the Newmark update (:func:`update_sensitivities`). ``r``, ``x``,
    ``work``: (n, n_x) scratch."""
    for j in range(E.shape[0]):
        rhs = E[j]
        state_loads(S, Q[j + 1], V[j + 1], A[j + 1], L[j + 1], w_new, has_old, Q[j], V[j],
                    A[j], L[j], w_old, F, k_new[j], scale, b0, b1, bh2, gh, indices, indptr,
                    n_dof, DQ, DV, DA, DG, DLAM, k_old[j], pc, mats, J, rhs)
        x[:, :] = rhs
        solve_factored(x, work, LU[j], piv[j], Lx[j], Ux[j], Ud[j], pattern)
        if refine[j]:
            for _ in range(n_refine):
                csc_residual(J, indices, indptr, x, rhs, r)
                solve_factored(r, work, LU[j], piv[j], Lx[j], Ux[j], Ud[j], pattern)
                x += r
            rr, bb = csc_residual(J, indices, indptr, x, rhs, r)
            refined[j] = rr / max(bb, 1e-300)
        update_sensitivities(DQ, DV, DA, DG, DLAM, k_new[j], x, scale, n_dof, pc, upd)


@njit(cache=True)
def update_sensitivities(DQ, DV, DA, DG, DLAM, n, x, scale, n_dof, pc, upd):
    """Store the step's solution ``x = (da, dlam/scale)`` (n, n_x) as entry ``n`` of the
    histories and advance ``dq, dv, dg`` by the Newmark update from entry ``n - 1``
    (``n == 0``: the initial solve, which sets ``da, dg, dlam`` only). A history the caller
    does not keep may hold just two levels: entry ``n`` of ``X`` is ``X[:, n % X.shape[1]]``
    (``DG``, the algorithmic acceleration, is only needed by the next step). Layout
    ``(n_x, levels, width)``: one variable's history is contiguous."""
    n_x = x.shape[1]
    nq, nv, na, n_g, nl = DQ.shape[1], DV.shape[1], DA.shape[1], DG.shape[1], DLAM.shape[1]
    n_con = DLAM.shape[2]
    if n == 0:
        for i in range(n_x):
            for r in range(n_dof):
                DA[i, 0, r] = x[r, i]
                DG[i, 0, r] = x[r, i]
            for r in range(n_con):
                DLAM[i, 0, r] = x[n_dof + r, i] * scale
        return
    m = n - 1
    qn, qm, vn, vm, an, am = n % nq, m % nq, n % nv, m % nv, n % na, m % na
    gn, gm, ln = n % n_g, m % n_g, n % nl
    qh = np.empty(n_dof)
    vh = np.empty(n_dof)
    for i in range(n_x):
        da = x[:n_dof, i]
        predict(pc, DQ[i, qm], DV[i, vm], DA[i, am], DG[i, gm], qh, vh)
        update(pc, upd, qh, vh, da, DA[i, am], DG[i, gm], DQ[i, qn], DV[i, vn], DG[i, gn])
        for r in range(n_dof):
            DA[i, an, r] = da[r]
        for r in range(n_con):
            DLAM[i, ln, r] = x[n_dof + r, i] * scale


@njit(cache=True)
def csc_residual(data, indices, indptr, x, b, r):
    """``r = b - A x`` for the CSC matrix ``A = (data, indices, indptr)`` and ``x`` (n, n_x);
    returns ``(|r|_F, |b|_F)``."""
    n = indptr.shape[0] - 1
    n_x = x.shape[1]
    r[:, :] = b
    _subtract_product(data, indices, indptr, n, x, r)
    rr = 0.0
    bb = 0.0
    for j in range(n):
        for i in range(n_x):
            rr += r[j, i] * r[j, i]
            bb += b[j, i] * b[j, i]
    return np.sqrt(rr), np.sqrt(bb)


@njit(cache=True)
def csc_transposed_product(data, indices, indptr, n_cols, x, out):
    """``out[:n_cols] -= A[:, :n_cols]^T x`` for the CSC matrix ``A = (data, indices, indptr)``
    and ``x`` (n, m): the transposed products of the adjoint sweep."""
    m = x.shape[1]
    for j in range(n_cols):
        for p in range(indptr[j], indptr[j + 1]):
            row = indices[p]
            aij = data[p]
            for i in range(m):
                out[j, i] -= aij * x[row, i]


@njit(cache=True)
def csc_residual_transposed(data, indices, indptr, x, b, r):
    """``r = b - A^T x`` for the CSC matrix ``A`` and ``x`` (n, m); returns
    ``(|r|_F, |b|_F)``."""
    n = indptr.shape[0] - 1
    r[:, :] = b
    csc_transposed_product(data, indices, indptr, n, x, r)
    rr = 0.0
    bb = 0.0
    for j in range(n):
        for i in range(x.shape[1]):
            rr += r[j, i] * r[j, i]
            bb += b[j, i] * b[j, i]
    return np.sqrt(rr), np.sqrt(bb)
