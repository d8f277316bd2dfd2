"""The time loop of a run in compiled chunks of steps.

Once a run's factorization has settled (``morphlab.solve.linalg.StepFactorization``: the dense
LU, or the sparse refactorization with a kept row order), :func:`run_steps` advances it
through a chunk of steps in one call: predictors, the old level's share (the paper's form),
Newton (:func:`~morphlab.kernels.newton.newton_loop`), the Newmark update and the histories,
with the same kernels and arithmetic as the step-by-step loop from Python. After each
converged step it records what a sensitivity run reads of it, if one asks (the factors and
the ``Dq``, ``Dv`` of its last Newton fill and its state: :func:`morphlab.kernels.adjoint.
keep`), for the direct method's chunk of sensitivity steps right after
(:func:`morphlab.kernels.direct.chunk`) or the adjoint's backward sweep. A step's fills form
``Dq``, ``Dv`` from the iteration at which the step before converged onwards
(:func:`~morphlab.kernels.newton.newton_loop`'s ``full_from``). It returns at the end
of the chunk (the caller reports progress and checks for an interrupt) or at a step whose
Newton iteration failed or needs Python (a sparse pivot that asks SuperLU for a new row
order), with every step before it recorded.

Histories are (levels, width) arrays: level ``k % levels`` holds time index ``k``, so a history
the run keeps in full has ``n_t`` levels and one it only steps with two.
"""

from typing import NamedTuple

import numpy as np

from . import adjoint
from ._jit import kernel
from .assemble import Step, residual
from .histories import state_at, violations
from .newmark import predict, update
from .newton import CONVERGED, newton_loop
from .types import Level, Weights


class Scheme(NamedTuple):
    """A regular step's coefficients: ``pc`` (7,), ``upd`` (3,) of
    :mod:`morphlab.kernels.newmark`; the weights of the new and (``has_old``) the old level;
    ``C`` (m, 3) the combinations of ``D0, Dq, Dv`` the Newton fill forms (row 0 the Newton
    matrix, rows 1, 2 ``Dq``, ``Dv`` for a sensitivity run)."""

    pc: np.ndarray
    upd: np.ndarray
    w_new: Weights
    w_old: Weights
    has_old: bool
    C: np.ndarray


@kernel(nogil=True)
def run_steps(M, T, P, sc, csc, F, opt, ws, H, k0, k1, keep):
    """Advance from time index ``k0 - 1`` to ``k1 - 1`` (steps ``k0 .. k1 - 1``; module
    docstring). ``M``, ``T``, ``P``: the system's arrays, time values (table 0) and parts (all
    of them); ``sc``: :class:`Scheme`; ``csc``, ``F``, ``opt``, ``ws``: the pattern, factor
    arrays, options and buffers of :func:`~morphlab.kernels.newton.newton_loop`; ``H``:
    :class:`~morphlab.kernels.histories.Histories`; ``keep``: the record of the steps a
    sensitivity method reads (:class:`~morphlab.kernels.adjoint.Keep`), or None.

    Returns ``(k, status, bad, it, z)``: the time index of the step that stopped the chunk
    (``k1`` when all converged) with Newton's status, ``bad`` and iteration count, and the
    iterate ``z`` it stopped at (:func:`~morphlab.kernels.newton.newton_loop`)."""
    n_dof = H.Q.shape[1]
    n_con = H.L.shape[1]
    n = n_dof + n_con
    scale = sc.w_new.scale
    bh2, gh = sc.pc[5], sc.pc[6]
    qh = np.empty(n_dof)
    vh = np.empty(n_dof)
    R_hist = np.zeros(n)
    z = np.empty(n)
    for k in range(k0, k1):
        old, g_old = state_at(H, k - 1)
        predict(sc.pc, old.q, old.v, old.a, g_old, qh, vh)
        if sc.has_old:
            for i in range(n):
                R_hist[i] = 0.0
            residual(M, old, sc.w_old, T, np.int64(0), k - 1, P, n_dof, R_hist, ws.W)
        s = Step(qh, vh, R_hist, bh2, gh, sc.w_new, sc.C, 0, k)
        for i in range(n_dof):
            z[i] = old.a[i]
        for i in range(n_con):
            z[n_dof + i] = old.lam[i] / scale
        # Dq, Dv from the iteration the step before converged at (nearly always the last)
        z1, it, status, bad = newton_loop(M, T, P, s, z, csc, F, opt, ws,
                                          max(H.iters[k - 1], 1))
        if status != CONVERGED:
            return k, status, bad, it, z1
        q1, v1 = H.Q[k % H.Q.shape[0]], H.V[k % H.V.shape[0]]
        a1, g1 = H.A[k % H.A.shape[0]], H.G[k % H.G.shape[0]]
        for i in range(n_dof):
            a1[i] = z1[i]
        update(sc.pc, sc.upd, qh, vh, a1, old.a, g_old, q1, v1, g1)
        lam1 = H.L[k % H.L.shape[0]]
        for i in range(n_con):
            lam1[i] = z1[n_dof + i] * scale
        H.iters[k] = it
        for j in range(it):
            H.newton[k, j, 0] = ws.hist[j, 0]
            H.newton[k, j, 1] = ws.hist[j, 1]
        if H.track:
            violations(M, T, H, k, k + 1)
        adjoint.keep(keep, F, ws.data, Level(q1, v1, a1, lam1), k)
    return k1, CONVERGED, -1, 0, z
