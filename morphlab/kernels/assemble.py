"""Whole-system residual and step matrix: every kind of item adds its contribution.

This is the one place that lists the kinds' kernels: :func:`residual` and :func:`matrix` call
each kind's kernel with the kind's table of :data:`~morphlab.kernels.system.SystemArrays`
(a kernel returns at once for a kind the model does not have, and Numba then does not compile
it). The step matrix is written into the ``data`` arrays of a CSC matrix whose pattern was
fixed at compile time; every contribution has a precomputed position (``-1``: skipped).

A step's unknowns are ``z = (a, lam/scale)`` with ``q = q_hat + bh2 a`` and ``q' = v_hat +
gh a`` (:class:`Step`, :func:`level`); the step equations are ``R(z) = R_hist + E(z)`` and
their exact matrix ``dR/dz`` (``docs/theory.md`` §5).
"""

from typing import NamedTuple

import numpy as np

# the kernel modules: importing one registers its kinds (morphlab.kernels.schema.KINDS), in
# this order; a new kind of item is one module here and its two calls below
from . import ffrf, ffrf_matrix, forces, joints, loads, pressure, slides
from ._jit import inner, kernel
from .schema import KINDS
from .types import Level, Weights

#: Position of each kind in the order of registration (that of ``SystemArrays``).
POS = {name: j for j, name in enumerate(KINDS)}
BODIES, ELEMENTS, ROWS, SLIDES = POS["bodies"], POS["elements"], POS["rows"], POS["slides"]
TORQUES, LOADS, LINES, SPRINGS = POS["torques"], POS["loads"], POS["lines"], POS["springs"]
PRESSURES, FOLLOWERS = POS["pressures"], POS["followers"]


class Step(NamedTuple):
    """The data of one set of step equations: the predictors ``qh, vh`` (n_dof,), the constant
    old-level share ``R_hist`` (n,), the Newmark factors ``bh2``, ``gh``, the new level's
    :class:`~morphlab.kernels.types.Weights` ``w``, the coefficients ``C`` = ``[[1, bh2,
    gh]]`` (1, 3) of the Newton matrix, and where the time values are: table ``t``, time index
    ``k``."""

    qh: np.ndarray
    vh: np.ndarray
    R_hist: np.ndarray
    bh2: float
    gh: float
    w: Weights
    C: np.ndarray
    t: int
    k: int


@kernel
def residual(M, x, w, T, t, k, P, n_dof, R, W):
    """Add the residual share of the state ``x`` (:class:`~morphlab.kernels.types.Level`,
    weights ``w``) over the parts ``P`` (:data:`~morphlab.kernels.system.Parts`) to ``R``
    (n_dof + n_con): equation rows ``wm M a + wl J^T lam + wf (K q + D q' - Q_v - Q_g - Q_ext
    + Q_s)``, constraint rows ``scale (wcm J a - wcf F_c)`` (paper eq. 25–26 for one level).
    ``T``: the time values (:data:`~morphlab.kernels.system.Times`) at table ``t``, time index
    ``k``; ``W``: the bodies' scratch (:class:`~morphlab.kernels.ffrf.Scratch`)."""
    # the items of kind j are P.idx[P.off[j]:P.off[j + 1]] (written out: a helper called with
    # the constant j would be compiled once per constant); a kind without items in ``P`` is
    # not called (a pseudo-load's parts hold one or two kinds: each call passes its tables)
    o, i = P.off, P.idx
    if o[BODIES + 1] > o[BODIES]:
        ffrf.residual(M.bodies, M.flex, M.elements, M.gravity, x, w, i[o[BODIES]:o[BODIES + 1]],
                      i[o[ELEMENTS]:o[ELEMENTS + 1]], P.flex, R, W)
    if o[ROWS + 1] > o[ROWS]:
        joints.residual(M.rows, x, w, T.rows, t, k, i[o[ROWS]:o[ROWS + 1]], n_dof, R)
    if o[SLIDES + 1] > o[SLIDES]:
        slides.residual(M.slides, x, w, T.slides, t, k, i[o[SLIDES]:o[SLIDES + 1]], n_dof, R)
    if o[TORQUES + 1] > o[TORQUES]:
        loads.torque_residual(M.torques, w.wf, T.torques, t, k, i[o[TORQUES]:o[TORQUES + 1]],
                              R)
    if o[LOADS + 1] > o[LOADS]:
        loads.point_force_residual(M.loads, x.q, w.wf, T.loads, t, k,
                                   i[o[LOADS]:o[LOADS + 1]], R)
    if o[LINES + 1] > o[LINES]:
        loads.line_residual(M.lines, x.q, w.wf, T.lines, t, k, i[o[LINES]:o[LINES + 1]], R)
    if o[SPRINGS + 1] > o[SPRINGS]:
        forces.residual(M.springs, x, w.wf, i[o[SPRINGS]:o[SPRINGS + 1]], R)
    if o[PRESSURES + 1] > o[PRESSURES]:
        pressure.pressure_residual(M.pressures, x.q, w.wf, T.pressures, t, k,
                                   i[o[PRESSURES]:o[PRESSURES + 1]], R)
    if o[FOLLOWERS + 1] > o[FOLLOWERS]:
        loads.point_force_residual(M.followers, x.q, w.wf, T.followers, t, k,
                                   i[o[FOLLOWERS]:o[FOLLOWERS + 1]], R)


@kernel
def matrix(M, x, w, T, t, k, C, out, W):
    """Overwrite ``out`` (m, nnz) with the derivatives of the residual share of ``x``: output
    ``r`` gets ``C[r, 0] D0 + C[r, 1] Dq + C[r, 2] Dv`` (``D0 = dR/d(a, lam/scale)`` with ``q,
    q'`` held, ``Dq = dR/dq``, ``Dv = dR/dq'``; :mod:`morphlab.kernels.types`). One pass over
    the model, whatever ``m``. ``C``: one row, or three whose last two are ``(0, 1, 0)`` and
    ``(0, 0, 1)`` (:mod:`morphlab.kernels.types`; ValueError for another)."""
    if not (C.shape[0] == 1 or (C.shape[0] == 3 and C[1, 0] == 0.0 and C[1, 1] == 1.0
                                and C[1, 2] == 0.0 and C[2, 0] == 0.0 and C[2, 1] == 0.0
                                and C[2, 2] == 1.0)):
        raise ValueError("the step matrix's coefficients C must be one row, or three whose "
                         "last two are (0, 1, 0) and (0, 0, 1)")
    for r in range(out.shape[0]):
        for p in range(out.shape[1]):
            out[r, p] = 0.0
    ffrf_matrix.matrix(M.bodies, M.flex, M.elements, M.gravity, x, w, C, out, W)
    joints.matrix(M.rows, x, w, C, out)
    slides.matrix(M.slides, x, w, C, out)
    loads.point_force_matrix(M.loads, x.q, w.wf, T.loads, t, k, C, out)
    loads.line_matrix(M.lines, x.q, w.wf, T.lines, t, k, C, out)
    forces.matrix(M.springs, x, w.wf, C, out)
    pressure.pressure_matrix(M.pressures, x.q, w.wf, T.pressures, t, k, C, out)
    loads.point_force_matrix(M.followers, x.q, w.wf, T.followers, t, k, C, out)


@inner
def level(z, s):
    """The state (:class:`~morphlab.kernels.types.Level`) at the step unknowns ``z`` of the
    step ``s``: ``q = q_hat + bh2 a``, ``q' = v_hat + gh a``, ``lam = scale z_lam``."""
    n_dof = s.qh.shape[0]
    n_con = z.shape[0] - n_dof
    q = np.empty(n_dof, dtype=z.dtype)
    v = np.empty(n_dof, dtype=z.dtype)
    a = np.empty(n_dof, dtype=z.dtype)
    lam = np.empty(n_con, dtype=z.dtype)
    for i in range(n_dof):
        a[i] = z[i]
        q[i] = s.qh[i] + s.bh2 * z[i]
        v[i] = s.vh[i] + s.gh * z[i]
    for i in range(n_con):
        lam[i] = z[n_dof + i] * s.w.scale
    return Level(q, v, a, lam)


@kernel
def apply_correction(z, dz, n_dof):
    """``z + dz`` (new array), the largest ``|dz|`` of the first ``n_dof`` entries (the
    acceleration part) and whether every entry of ``dz`` is finite."""
    out = np.empty_like(z)
    big = 0.0
    finite = True
    for i in range(z.shape[0]):
        d = dz[i]
        if not (np.isfinite(d.real) and np.isfinite(d.imag)):
            finite = False
        out[i] = z[i] + d
        if i < n_dof:
            m = abs(d)
            if m > big:
                big = m
    return out, big, finite
