"""Direct differentiation of a run: the primal time loop with a step observer that solves the
sensitivities of the converged steps in blocks (``docs/theory.md`` §6).

The partial derivatives ``dR/dp_i`` of a step depend only on its converged primal states, the
recursion ``J dz_{n+1} = -D_i R`` on the previous step's sensitivities. So each step's state and
factorization are kept until a block is full (``block_bytes``), the coefficients change (the
initial solve) or the run ends; then the block's explicit partial derivatives are formed in one
compiled call (:func:`~morphlab.kernels.direct.explicit_block`) and the recursion runs over its
steps: the state part of the pseudo-loads (:func:`~morphlab.kernels.direct.state_loads`), one
solve with the primal's factorization for all columns, iterative refinement against the exact
converged matrix, the Newmark update. Steps whose factors belong to one compiled group run the
recursion in one call (:func:`~morphlab.kernels.direct.block_recursion`); SuperLU's own factors
are solved from Python. The results do not depend on the block size.
"""

from __future__ import annotations

import time as _time
from itertools import groupby

import numpy as np

from ..compile import System
from ..kernels.direct import (
    block_recursion,
    csc_residual,
    explicit_block,
    state_loads,
    update_sensitivities,
)
from ..solve.linalg import stacked_arrays
from ..solve.settings import Settings
from ..solve.timeloop import StepInfo, integrate
from .histories import HISTORIES, PerturbedResult
from .perturb import PseudoLoadData


def _factor_bytes(lu) -> int:
    """Approximate memory of a kept factorization: its arrays (a sparse LU shares its
    patterns with every factor of its row order; SuperLU's is an estimate) and ~0.5 kB for
    the Python objects and array headers."""
    return lu.nbytes + 500


class _DirectPass:
    """The step observer of a direct run (module docstring)."""

    def __init__(self, sys0: System, n_steps: int, data: PseudoLoadData, hist: tuple,
                 refine: int, refine_tol: float, block_bytes: int):
        self.sys0 = sys0
        self.n_steps = n_steps
        self.data = data
        self.hist = hist
        self.refine = refine
        self.refine_tol = refine_tol
        self.block_bytes = block_bytes
        n_x = data.dq0.shape[1]
        n, nnz = sys0.n, sys0.nnz
        self.work = np.zeros((2, n), dtype=data.dtype)
        self.mats = np.zeros((6, nnz))
        self.J = np.zeros(nnz)
        self.r = np.zeros((n, n_x))
        self.pending: list = []  # (time index, state, factorization, last Newton correction)
        self.pending_bytes = 0  # memory kept by the pending steps (estimate)
        self.first_old = None  # the state before the first pending step
        self.info = None  # the StepInfo of the first pending step (coefficients, tables)
        self.stats = {"refinement_residual": [], "refined_steps": 0, "sensitivity_time": 0.0,
                      "blocks": 0}

    def __call__(self, info: StepInfo) -> None:
        t0 = _time.perf_counter()
        if self.pending and info.coef is not self.info.coef:
            self.flush()
        if not self.pending:
            self.info = info
            if info.prev is None:  # initial solve: the state at t_0, no old level
                st = info.state
                self.first_old = (st.q, st.v, np.zeros(self.sys0.n_dof),
                                  np.zeros(self.sys0.n_con))
            else:
                p = info.prev
                self.first_old = (p.q, p.v, p.a, p.lam)
        last = info.newton_history[-1, 1] if len(info.newton_history) else 0.0
        self.pending.append((info.n, info.state, info.lu, last))
        self.pending_bytes += _factor_bytes(info.lu) + 8 * self.sys0.n * (self.r.shape[1] + 4)
        if self.pending_bytes >= self.block_bytes or info.n == self.n_steps:
            self.flush()
        self.stats["sensitivity_time"] += _time.perf_counter() - t0

    def flush(self) -> None:
        """Solve the sensitivities of the pending steps."""
        sys0, d, info = self.sys0, self.data, self.info
        stp, coef = info.stepper, info.coef
        w_old, w_new = coef.arrays.w_old, coef.arrays.w_new
        has_old = coef.old is not None
        steps = self.pending
        K = len(steps)
        k_new = np.array([s[0] for s in steps], dtype=np.int64)
        k_old = np.maximum(k_new - 1, 0)
        Q, V, A, L = (np.stack([self.first_old[c]] + [s[1][c + 1] for s in steps])
                      for c in range(4))  # State = (t, q, v, a, lam, g)
        E = np.zeros((K, sys0.n, self.r.shape[1]))
        explicit_block(d.S_nom, d.W, d.D, d.parts, d.lin, Q, V, A, L, w_new, has_old, w_old,
                       stp.scale, stp.b0, stp.b1, d.TAB, d.tab_of, k_old, k_new, sys0.n_dof,
                       d.pert, self.work, E)
        # The factorization is one Newton iterate behind (taken at z_k, z* = z_k + dz): its
        # relative error is O(|dz|). Where the last position correction exceeds refine_tol of
        # the model size, the solve is refined against the exact matrix J at z*.
        refine = np.array([self.refine > 0 and k > 0 and last > self.refine_tol
                           for k, _st, _lu, last in steps])
        refined = np.full(K, np.nan)
        j0 = 0
        for (group, _), run in groupby(steps, key=lambda s: (s[2].group, s[2].chunk)):
            j1 = j0 + len(list(run))
            if group is not None:  # these steps' recursion in one compiled call
                self._compiled(j0, j1, Q, V, A, L, k_old, k_new, E, refine, refined,
                               stacked_arrays([s[2] for s in steps[j0:j1]]))
            else:
                for j in range(j0, j1):
                    self._python_step(j, Q, V, A, L, k_old, k_new, E, refine, refined)
            j0 = j1
        self.stats["refined_steps"] += int(refine.sum())
        self.stats["refinement_residual"] += refined[refine].tolist()
        self.pending = []
        self.pending_bytes = 0
        self.stats["blocks"] += 1

    def _common(self):
        """The coefficients every step of the block shares, in kernel argument order."""
        stp, coef, sys0 = self.info.stepper, self.info.coef, self.sys0
        return (stp.scale, stp.b0, stp.b1, coef.bh2, coef.gh, sys0.indices, sys0.indptr,
                sys0.n_dof)

    def _compiled(self, j0, j1, Q, V, A, L, k_old, k_new, E, refine, refined, factors):
        info, coef = self.info, self.info.coef
        sl, sl1 = slice(j0, j1), slice(j0, j1 + 1)
        scratch = (self.r, np.empty_like(self.r), np.empty_like(self.r))
        block_recursion(info.stepper.S, Q[sl1], V[sl1], A[sl1], L[sl1], coef.arrays.w_new,
                        coef.old is not None, coef.arrays.w_old, info.table.F, k_old[sl],
                        k_new[sl], *self._common(), *self.hist, coef.arrays.pc,
                        coef.arrays.upd, self.mats, self.J, E[sl], *factors,
                        refine[sl], self.refine, *scratch, refined[sl])

    def _python_step(self, j, Q, V, A, L, k_old, k_new, E, refine, refined):
        """The same sequence for one step whose factors only solve from Python."""
        info, coef, sys0 = self.info, self.info.coef, self.sys0
        k, lu, rhs = self.pending[j][0], self.pending[j][2], E[j]
        state_loads(info.stepper.S, Q[j + 1], V[j + 1], A[j + 1], L[j + 1], coef.arrays.w_new,
                    coef.old is not None, Q[j], V[j], A[j], L[j], coef.arrays.w_old,
                    info.table.F, k, *self._common(), *self.hist, k_old[j], coef.arrays.pc,
                    self.mats, self.J, rhs)
        x = lu.solve(rhs)
        if refine[j]:
            for _ in range(self.refine):
                csc_residual(self.J, sys0.indices, sys0.indptr, x, rhs, self.r)
                x = x + lu.solve(self.r)
            rr, bb = csc_residual(self.J, sys0.indices, sys0.indptr, x, rhs, self.r)
            refined[j] = rr / max(bb, 1e-300)
        update_sensitivities(*self.hist, k, x, info.stepper.scale, sys0.n_dof, coef.arrays.pc,
                             coef.arrays.upd)


def direct_run(sys0: System, settings: Settings, psys: list[System], data: PseudoLoadData,
               kept=HISTORIES, *, refine: int = 1, refine_tol: float = 1e-12,
               block_bytes: int = 64 * 2**20, progress=False):
    """The primal run of ``sys0`` with the direct-differentiation observer.

    Returns ``(result, perturbed, state, timing, stats)``: the primal Result, one complex
    :class:`~morphlab.sensitivity.histories.PerturbedResult` per variable (on its perturbed
    system ``psys[i]``), the kept sensitivity histories ``{name: (n_t, width, n_x)}``, the
    wall times and the observer's statistics."""
    n_x = data.dq0.shape[1]
    n_steps = settings.n_steps
    n_dof, n_con = sys0.n_dof, sys0.n_con

    # histories kept in full: those in ``kept``; the others (and the algorithmic
    # acceleration) hold the last two levels, all the time stepping reads;
    # layout (n_x, levels, width): one variable's history is contiguous
    def history(name, width):
        return np.zeros((n_x, (n_steps + 1) if name in kept else 2, width))

    full = {"q": history("q", n_dof), "v": history("v", n_dof), "a": history("a", n_dof),
            "lam": history("lam", n_con)}
    full["q"][:, 0], full["v"][:, 0] = data.dq0.T, data.dv0.T
    dg = np.zeros((n_x, 2, n_dof))
    by_variable = {k: full[k] for k in HISTORIES if k in kept}
    hist = (full["q"], full["v"], full["a"], dg, full["lam"])
    observer = _DirectPass(sys0, n_steps, data, hist, refine, refine_tol, block_bytes)

    t0 = _time.perf_counter()
    res0 = integrate(sys0, settings, observer=observer, progress=progress)
    total = _time.perf_counter() - t0
    stats = observer.stats
    stats["n_factorizations"] = res0.n_factorizations
    perturbed = [PerturbedResult(res0, s, by_variable, i) for i, s in enumerate(psys)]
    timing = {"primal": total - stats["sensitivity_time"],
              "sensitivity": stats["sensitivity_time"], "run": total}
    state = {k: np.moveaxis(v, 0, -1) for k, v in by_variable.items()}  # (n_t, width, n_x)
    return res0, perturbed, state, timing, stats
