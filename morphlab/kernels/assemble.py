"""Whole-system residual and Newton matrix: one compiled call each.

The system arrays travel as one :class:`~morphlab.kernels.system.SystemArrays` ``S`` (built once
per compiled model by ``morphlab.compile.kernel_arrays``), so a Newton iteration costs one call
for the residual and one for the matrix, whatever the number of bodies, elements and joints.
The matrix is written into the ``data`` array of a CSC matrix whose pattern was fixed at
compile time; every contribution has a precomputed position (``-1``: skipped). The applied
forces (torques, point forces, line loads, spring-dampers) go through :func:`applied_residual`
and :func:`applied_jacobian`, which compile all but the torques only for a model with extra
items (the switch ``S.extra_items`` of ``kernels.system``).
"""

import numpy as np
from numba import njit

from .ffrf import body_jacobian, body_part_residual, body_residual
from .forces import spring_jacobian, spring_residual
from .joints import constraint_jacobian, constraint_residual
from .loads import (
    line_load_jacobian,
    line_load_residual,
    point_load_jacobian,
    point_load_residual,
    torque_residual,
)
from .system import all_parts


@njit(cache=True)
def add_residual(S, q, v, a, lam, wm, wl, wf, wcm, wcf, scale, b0, b1, c, cd, cdd, F, T, n_dof, R):
    """Add one state's weighted share of the residual to ``R`` (n_dof + n_con).

    Equation rows: ``wm M a + wl J^T lam + wf (K q + D q' - Q_v - Q_g - Q_ext + Q_s)``
    (``Q_s``: the spring-dampers, ``kernels.forces``);
    constraint rows: ``scale (wcm J a - wcf F_c)`` (paper eq. 25–26 for one time level).
    """
    add_residual_parts(S, all_parts(S), q, v, a, lam, wm, wl, wf, wcm, wcf, scale, b0, b1, c, cd,
                       cdd, F, T, n_dof, R)


@njit(cache=True)
def add_residual_parts(S, parts, q, v, a, lam, wm, wl, wf, wcm, wcf, scale, b0, b1, c, cd, cdd,
                       F, T, n_dof, R):
    """:func:`add_residual` over the :class:`~morphlab.kernels.system.Parts` ``parts`` only:
    the sensitivity pseudo-loads evaluate the parts a design variable changes
    (``morphlab.kernels.direct``)."""
    body_residual(S, q, v, a, wm, wf, parts, R)
    constraint_residual(S.extra_items, S, q, v, a, lam, wl, wcm, wcf, scale, b0, b1, c, cd, cdd,
                        parts.rows, n_dof, R)
    applied_residual(S.extra_items, S, q, v, wf, F, T, parts.loads, parts.torques,
                     parts.springs, R)


@njit(cache=True, inline="always")
def add_part_residual(S, parts, q, v, a, lam, wm, wl, wf, wcm, wcf, scale, b0, b1, c, cd, cdd,
                      F, T, n_dof, R, W):
    """:func:`add_residual_parts` at a cost that grows with ``parts``, not with the system
    (the bodies through :func:`~morphlab.kernels.ffrf.body_part_residual`, whose scratch
    ``W`` it takes): the pseudo-loads of one design variable."""
    body_part_residual(S, q, v, a, wm, wf, parts, R, W)
    # the calls pass the whole system: skipped where there is nothing to evaluate
    if parts.rows.shape[0] > 0:
        constraint_residual(S.extra_items, S, q, v, a, lam, wl, wcm, wcf, scale, b0, b1, c, cd,
                            cdd, parts.rows, n_dof, R)
    if parts.loads.shape[0] + parts.torques.shape[0] + parts.springs.shape[0] > 0:
        applied_residual(S.extra_items, S, q, v, wf, F, T, parts.loads, parts.torques,
                         parts.springs, R)


@njit(cache=True)
def applied_residual(extra, S, q, v, wf, F, T, loads, torques, springs, R):
    """Add ``wf (Q_s - Q_ext)`` of the applied forces to ``R``: the torques ``torques``, the
    point forces and line loads among ``loads`` and the spring-dampers ``springs`` (int64
    indices; ``kernels.loads``, ``kernels.forces``). ``extra``: the switch ``S.extra_items``;
    Numba drops the code of all but the torques when it is None (``kernels.system``)."""
    torque_residual(S, wf, T, torques, R)
    if extra is not None:
        point_load_residual(S, q, wf, F, loads, R)
        line_load_residual(S, q, wf, F, loads, R)
        spring_residual(S, q, v, wf, springs, R)


@njit(cache=True)
def applied_jacobian(extra, S, q, v, cf, C, F, out):
    """The Newton-matrix terms of :func:`applied_residual` (weight ``cf``) into ``out``
    (m, nnz): they have no ``D0`` part, output ``r`` gets ``C[r][1] Dq + C[r][2] Dv``
    (:func:`fill_split`)."""
    if extra is not None:
        for r in range(len(C)):
            cq, cv = C[r][1], C[r][2]
            if cq == 0.0 and cv == 0.0:
                continue
            point_load_jacobian(S, q, cf, cq, F, out[r])
            line_load_jacobian(S, q, cf, cq, F, out[r])
            spring_jacobian(S, q, v, cf, cq, cv, out[r])


@njit(cache=True, inline="always")
def fill_split(S, q, v, a, lam, cm, cl, cf, ccm, ccf, scale, b0, b1, F, C, out):
    """Overwrite ``out`` (m, nnz) with combinations of the derivatives of one time level's
    residual share at the given state: the Newton matrix is ``D0 + bh2 Dq + gh Dv`` (the chain
    rule through ``q = q_pred + bh2 a``, ``q' = qd_pred + gh a``: ``D0 = dR/d(a, lam/scale)``
    with ``q, q'`` held, ``Dq = dR/dq``, ``Dv = dR/dq'``), and output ``r`` receives
    ``C[r][0] D0 + C[r][1] Dq + C[r][2] Dv`` (``C``: m triples of floats). ``cm, cl, cf`` weight the
    inertia, multiplier and force terms, ``ccm, ccf`` the constraint rows (paper eq. 30–33,
    every derivative term). One pass over the model, whatever ``m``."""
    out[:, :] = 0.0
    body_jacobian(S, q, v, a, cm, cf, C, out)
    constraint_jacobian(S.extra_items, S, q, v, a, lam, cl, ccm, ccf, C, scale, b0, b1, out)
    applied_jacobian(S.extra_items, S, q, v, cf, C, F, out)


@njit(cache=True, inline="always")
def fill_matrix(S, q, v, a, lam, cm, cl, cf, ccm, ccf, bh2, gh, scale, b0, b1, F, data):
    """Overwrite ``data`` (nnz,) with the Newton matrix ``d(residual)/d(a, lambda/scale)`` at
    the given state (:func:`fill_split` with ``C = ((1, bh2, gh),)``)."""
    fill_split(S, q, v, a, lam, cm, cl, cf, ccm, ccf, scale, b0, b1, F, ((1.0, bh2, gh),),
               data.reshape((1, data.shape[0])))


@njit(cache=True, inline="always")
def _step_state(z, qh, vh, bh2, gh, scale, n_dof):
    """``(q, v, a, lam)`` of a step at the unknowns ``z = (a, lam/scale)``:
    ``q = q_hat + bh2 a``, ``v = v_hat + gh a``."""
    n_con = z.shape[0] - n_dof
    q = np.empty(n_dof, dtype=z.dtype)
    v = np.empty(n_dof, dtype=z.dtype)
    a = np.empty(n_dof, dtype=z.dtype)
    lam = np.empty(n_con, dtype=z.dtype)
    for k in range(n_dof):
        a[k] = z[k]
        q[k] = qh[k] + bh2 * z[k]
        v[k] = vh[k] + gh * z[k]
    for k in range(n_con):
        lam[k] = z[n_dof + k] * scale
    return q, v, a, lam


@njit(cache=True)
def step_residual(S, z, qh, vh, bh2, gh, scale, w, b0, b1, c, cd, cdd, F, T, n_dof, R_hist, R):
    """``R = R_hist +`` the new level's share (weights ``w``) at the step unknowns ``z``: the
    Newton residual in one call (``morphlab.solve.newton.StepProblem``). Returns ``|R|²`` (NaN
    or Inf when an entry is not finite)."""
    q, v, a, lam = _step_state(z, qh, vh, bh2, gh, scale, n_dof)
    # an element loop, not ``R[:] = R_hist``: for an array assignment Numba compiles a
    # formatted shape-mismatch error, which lengthens every cold start
    for k in range(R.shape[0]):
        R[k] = R_hist[k]
    parts = all_parts(S)
    body_residual(S, q, v, a, w[0], w[2], parts, R)
    constraint_residual(S.extra_items, S, q, v, a, lam, w[1], w[3], w[4], scale, b0, b1, c, cd, cdd,
                        parts.rows, n_dof, R)
    applied_residual(S.extra_items, S, q, v, w[2], F, T, parts.loads, parts.torques,
                     parts.springs, R)
    ssq = 0.0
    for k in range(R.shape[0]):
        ssq += R[k].real * R[k].real + R[k].imag * R[k].imag
    return ssq


@njit(cache=True)
def step_matrix(S, z, qh, vh, bh2, gh, scale, w, b0, b1, F, data):
    """The exact Newton matrix at the step unknowns ``z`` into ``data`` (weights ``w``)."""
    q, v, a, lam = _step_state(z, qh, vh, bh2, gh, scale, qh.shape[0])
    fill_matrix(S, q, v, a, lam, w[0], w[1], w[2], w[3], w[4], bh2, gh, scale, b0, b1, F, data)


@njit(cache=True)
def apply_correction(z, dz, n_dof):
    """``z + dz`` (new array), the largest ``|dz|`` of the first ``n_dof`` entries (the
    acceleration part) and whether every entry of ``dz`` is finite."""
    out = np.empty_like(z)
    big = 0.0
    finite = True
    for k in range(z.shape[0]):
        d = dz[k]
        if not (np.isfinite(d.real) and np.isfinite(d.imag)):
            finite = False
        out[k] = z[k] + d
        if k < n_dof:
            m = abs(d)
            if m > big:
                big = m
    return out, big, finite
