"""Direct differentiation of a run (``docs/theory.md`` §6): the primal time loop with a
:class:`~morphlab.solve.timeloop.StepHook` that solves the sensitivities of every step right
after it, for all variables at once.

Differentiating the converged step equations ``R(z_{n+1}; s_n, p) = 0`` along design variable
``p_i`` gives ``J dz_{n+1}/dp_i = -D_i R``: the state part through the predictors (the
``Dq``, ``Dv`` of the step), the explicit part ``dR/dp_i`` (:mod:`morphlab.kernels.pseudo`).
The steps the run solves in compiled chunks record their factors, their last fill's ``Dq``,
``Dv`` and their states (:class:`~morphlab.kernels.adjoint.Keep`), and each chunk's
sensitivities follow in one compiled call (:func:`~morphlab.kernels.direct.chunk`); the steps
solved from Python (the initial solve, the step SuperLU chooses a row order on) have their
right-hand sides formed by the same compiled call on a record of the step, which Python solves
with their factors (:meth:`DirectHook.solve_pending`; a sparse run's initial solve waits for
the row order, which gives the record its types). The Newmark update is linear, so
``dq_{n+1} = dq_hat + bh2 da_{n+1}``, ``dv_{n+1} = dv_hat + gh da_{n+1}``.

Which matrices: ``reuse=True`` (the default) solves with the step's own last Newton matrix
and the ``Dq``, ``Dv`` of that fill (the paper's eq. 39: no matrix is formed for the
sensitivities; their relative error is of the order of the last Newton correction, the
accuracy of the primal itself); ``reuse=False`` forms them at the converged state and refines
the solve against the exact matrix (exact to round-off).
"""

from __future__ import annotations

import time as _time

import numpy as np

from ..compile import System
from ..kernels.adjoint import Keep
from ..kernels.assemble import matrix
from ..kernels.direct import Direct, chunk, refinement_residual, store
from ..kernels.newton import Csc
from ..kernels.pseudo import Column, Pseudo
from ..solve.record import fits as _fits
from ..solve.record import keep_record, release, solved_step, template
from ..solve.scheme import kernel_scheme, old_weights
from ..solve.settings import Settings
from ..solve.timeloop import StepHook, integrate
from .designs import system_read
from .histories import HISTORIES, PerturbedResult

#: A chunk's record holds a multiple of this many steps.
RECORD_STEPS = 32


def start_record(K: Keep, hist, k0: int) -> Keep:
    """``K`` for the steps from ``k0``: its first row the state before them (from the run's
    histories ``hist``)."""
    K.k0[0] = k0
    st = hist.state(k0 - 1)
    K.Q[0], K.V[0], K.A[0], K.L[0] = st.q, st.v, st.a, st.lam
    return K


class DirectHook(StepHook):
    """The step hook of a direct run (module docstring)."""

    def __init__(self, system: System, n_steps: int, ps: Pseudo, dq0, dv0, kept, *,
                 reuse: bool = True, refine: int = 1):
        self.system, self.ps = system, ps
        # the variant: ``refine`` None for the reuse variant (as the kernels take it), else
        # the exact variant's refinement sweeps
        self.reuse, self.refine = reuse, None if reuse else refine
        self.rows = 3 if reuse else 1
        n_x = dq0.shape[1]
        n, n_dof, n_con = system.n, system.n_dof, system.n_con

        def history(name, width):  # (n_x, levels, width): one variable's history contiguous
            return np.zeros((n_x, (n_steps + 1) if name in kept else 2, width))

        self.full = {"q": history("q", n_dof), "v": history("v", n_dof),
                     "a": history("a", n_dof), "lam": history("lam", n_con)}
        self.full["q"][:, 0], self.full["v"][:, 0] = dq0.T, dv0.T
        self.kept = kept
        self.d = Direct(self.full["q"], self.full["v"], self.full["a"],
                        np.zeros((n_x, 2, n_dof)), self.full["lam"], ps,
                        np.zeros((n, n_x)), np.zeros((n, n_x)), np.zeros((n, n_x)),
                        np.zeros((n, n_x)),
                        Column.zeros(n_dof, n_con, system.count("flex"), ps),
                        np.zeros((6, system.nnz)), np.full(n_steps + 1, np.nan),
                        Csc(system.indices, system.indptr))
        self.record = None
        self.factor_arrays = None  # those of the last chunk that ran (the record's types)
        self.pending: list = []  # steps solved from Python, before their sensitivities
        self.seconds = 0.0

    def start(self, stepper, hist) -> None:
        self.stepper, self.hist = stepper, hist
        self.sc = stepper.scheme_of()
        self.sc0 = kernel_scheme(stepper.init_coef, stepper.scale, stepper.b0, stepper.b1,
                                 split=self.rows == 3)
        self.w_old = old_weights(self.sc)
        self.M, self.T = system_read(stepper, self.refine, self.w_old, self.d.ps)  # the chunk's

    def python_step(self, k: int, out) -> None:
        """Step ``k`` solved from Python: its sensitivities (:meth:`solve_pending`) once the
        factorization has compiled factors, whose record types the kernels take it with (at
        once, but for a sparse run's first steps: SuperLU chooses the row order on the first
        step after the initial solve); until then kept with its factor."""
        t0 = _time.perf_counter()
        stp = self.stepper
        sc = self.sc0 if k == 0 else self.sc
        new = _level(out.state)
        old = new if k == 0 else _level(self.hist.state(k - 1))
        data = stp.newton.data
        if not self.reuse:  # the exact variant forms its matrices at the converged state
            Dq = Dv = None
        elif k == 0:  # the initial solve's fill was at its starting guess
            Dq, Dv = converged_blocks(stp, sc, new)
        else:
            Dq, Dv = data[1].copy(), data[2].copy()
        self.pending.append((k, sc, new, old, Dq, Dv, out.factor))
        self.seconds += _time.perf_counter() - t0
        if stp.newton.factorization.settled:
            self.solve_pending()

    def solve_pending(self) -> None:
        """The sensitivities of the steps solved from Python and kept, in order: right-hand
        sides by the compiled chunk (``rhs_only``, on a record of the step:
        :func:`~morphlab.solve.record.solved_step`), the solves with the step's factor from
        Python, the update by the compiled kernel."""
        if not self.pending:
            return
        t0 = _time.perf_counter()
        d, stp = self.d, self.stepper
        # the types of the last chunk's record; before one ran (its record may exist with no
        # step converged in it), those of a record of no steps
        like = (template(self.system, stp.newton.factorization, self.reuse)
                if self.factor_arrays is None else (self.record, self.factor_arrays))
        for k, sc, new, old, Dq, Dv, lu in self.pending:
            K, F = solved_step(like, new, old, Dq, Dv, k)
            chunk(d, self.M, self.T, sc, F, K, k, k + 1, self.refine, True, self.w_old)
            x = np.ascontiguousarray(lu.solve(d.rhs), dtype=float)
            if self.refine:  # the exact variant, refined
                for _ in range(self.refine):
                    d.x[:] = x
                    refinement_residual(d)
                    x = x + lu.solve(d.r)
                d.x[:] = x
                rr, bb = refinement_residual(d)
                d.refined[k] = rr / max(bb, 1e-300)
            store(d.DQ, d.DV, d.DA, d.DG, d.DL, sc, x, k)
        self.pending.clear()
        self.seconds += _time.perf_counter() - t0

    def kernels(self, k0: int, k1: int) -> tuple:
        F = self.stepper.newton.factorization.loop_arrays()
        K = k1 - k0
        if self.record is None or self.record.Q.shape[0] < K + 1 or not _fits(self.record, F):
            # rounded up, so that runs whose chunks differ by a few steps share the record
            # the last one released (morphlab.solve.record)
            self.record = keep_record(self.system, F, -(-K // RECORD_STEPS) * RECORD_STEPS,
                                      k0, self.reuse, pool="direct", chunks=True)
        return start_record(self.record, self.hist, k0)

    def after_chunk(self, k0: int, k1: int) -> None:
        if k1 <= k0:
            return
        stp = self.stepper
        self.factor_arrays = stp.newton.factorization.loop_arrays()
        self.solve_pending()  # the steps before k0 solved from Python
        t0 = _time.perf_counter()
        chunk(self.d, self.M, self.T, self.sc, self.factor_arrays, self.record, k0, k1,
              self.refine, False, self.w_old)
        self.seconds += _time.perf_counter() - t0


def converged_blocks(stepper, sc, new) -> tuple:
    """``Dq``, ``Dv`` (nnz,) of the initial solve at its solution ``new``. The reuse variant
    takes them from a step's last Newton fill, which differs from the converged state by the
    last correction; the initial accelerations are solved in one linear step from zero, so
    that fill is at ``a = 0, lam = 0``, and the initial step forms its own (one fill)."""
    data = np.zeros((3, stepper.system.nnz), dtype=stepper.system.dtype)
    matrix(stepper.M, new, sc.w_new, stepper.T, np.int64(0), np.int64(0), np.eye(3), data,
           stepper.newton.W)
    return data[1], data[2]


def _level(st):
    """The state ``st`` as a :class:`~morphlab.kernels.types.Level` of copies (kept until
    :meth:`DirectHook.solve_pending`)."""
    from ..kernels.types import Level

    return Level(np.array(st.q), np.array(st.v), np.array(st.a), np.array(st.lam))


def direct_run(sys0: System, settings: Settings, psys: list, ps: Pseudo, dq0, dv0,
               kept=HISTORIES, *, reuse: bool = True, refine: int = 1, progress=False):
    """The primal run of ``sys0`` with the direct method's hook.

    Returns ``(result, perturbed, state, timing, stats)``: the primal Result, one complex
    :class:`~morphlab.sensitivity.histories.PerturbedResult` per variable (on its perturbed
    system ``psys[i]``), the kept sensitivity histories ``{name: (n_t, width, n_x)}``, the
    wall times and the statistics."""
    hook = DirectHook(sys0, settings.n_steps, ps, dq0, dv0, kept, reuse=reuse, refine=refine)
    t0 = _time.perf_counter()
    res0 = integrate(sys0, settings, hook=hook, progress=progress)
    hook.solve_pending()  # any kept to the end (a run without compiled factors)
    release([hook.record], "direct")  # the next run's record is made of it
    total = _time.perf_counter() - t0
    by_variable = {k: hook.full[k] for k in HISTORIES if k in kept}
    perturbed = [PerturbedResult(res0, s, by_variable, i) for i, s in enumerate(psys)]
    refined = hook.d.refined[np.isfinite(hook.d.refined)]
    stats = {"n_factorizations": res0.n_factorizations, "reuse": reuse,
             "refinement_residual": refined.tolist(), "refined_steps": int(refined.size)}
    timing = {"primal": total - hook.seconds, "sensitivity": hook.seconds, "run": total}
    state = {k: np.moveaxis(v, 0, -1) for k, v in by_variable.items()}  # (n_t, width, n_x)
    return res0, perturbed, state, timing, stats
