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
with their factors (:meth:`DirectHook._python_steps`; a sparse run's initial solve waits for
the row order, which gives the record its types). The Newmark update is linear, so
``dq_{n+1} = dq_hat + bh2 da_{n+1}``, ``dv_{n+1} = dv_hat + gh da_{n+1}``.

Which matrices: ``reuse=True`` (the default) solves with the step's own last Newton matrix
and the ``Dq``, ``Dv`` of that fill (the paper's eq. 39: no matrix is formed for the
sensitivities; their relative error is of the order of the last Newton correction, the
accuracy of the primal itself); ``reuse=False`` forms them at the converged state and refines
the solve against the exact matrix (exact to round-off).

Where the work goes (:class:`_Work`): the sensitivity work of a run is a queue of pieces in
the order the primal hands them over: first the design data (the variables' changes, built
by the user's ``build``, and the pseudo-load data), then the steps solved from Python and
each compiled chunk's sensitivities. With ``overlap`` the pieces run in the worker thread of
:mod:`morphlab.sensitivity.beside` while the primal's compiled chunks (which release the
interpreter lock) go on: the chunks are kept short (:data:`OVERLAP_STEPS`), each has a record
of its own until its sensitivities are done, and the primal waits for the worker only where
the records it holds would exceed :data:`OVERLAP_BYTES`, and at the end. The pieces are the
same calls on the same data in the same order as without ``overlap`` (then each runs at once
in the caller's thread): the same results, bit for bit. A piece's error is raised in the
caller's thread at the next chunk boundary; a failed or interrupted run stops the worker
(the pieces not started cancelled) before its error reaches the caller.

The responses: where every response has a ``vjp``, each is differentiated by the chain rule
over the sensitivity histories (:func:`response_gradients`, one pass per response, its vjp
formed while the worker finishes the last steps); otherwise each is evaluated on every
variable's complex result (``x + i h dx/dp_i``: one pass per response and variable), which
:meth:`~morphlab.sensitivity.api.SensitivityResult.derivative` does for any response later.
"""

from __future__ import annotations

import time as _time
from collections import deque
from collections.abc import Callable
from concurrent.futures import Future

import numpy as np

from ..compile import System
from ..kernels.adjoint import Keep
from ..kernels.assemble import matrix
from ..kernels.direct import Direct, chunk, refinement_residual, store
from ..kernels.newton import Csc
from ..kernels.pseudo import Column
from ..results.gradients import response_vjp
from ..solve.record import fits as _fits
from ..solve.record import keep_record, release, solved_step, template
from ..solve.scheme import kernel_scheme, old_weights
from ..solve.settings import Settings
from ..solve.timeloop import StepHook, integrate
from .beside import submit
from .designs import data_terms, system_read
from .histories import HISTORIES, PerturbedResult

#: A chunk's record holds a multiple of this many steps.
RECORD_STEPS = 32

#: Steps of a compiled chunk whose sensitivities run beside the primal (``overlap``): the
#: primal waits at its end for the last chunk's, so a chunk is short; each chunk costs a
#: call of the compiled loop and of the sensitivity kernel (tens of microseconds).
OVERLAP_STEPS = 64

#: Bytes of the records a run may have handed to the worker and not had back: beyond them
#: the primal waits for the worker (the worker is behind, a record is large).
OVERLAP_BYTES = 2**28


#: Time indices per block of the responses' derivatives (:func:`response_gradients`).
VJP_BLOCK = 256


def start_record(K: Keep, hist, k0: int) -> Keep:
    """``K`` for the steps from ``k0``: its first row the state before them (from the run's
    histories ``hist``)."""
    K.k0[0] = k0
    st = hist.state(k0 - 1)
    K.Q[0], K.V[0], K.A[0], K.L[0] = st.q, st.v, st.a, st.lam
    return K


def _nbytes(K: Keep) -> int:
    return sum(x.nbytes for x in K if x is not None)


class _Work:
    """The sensitivity work of a run, in the order it is handed over: with ``overlap`` queued
    on the worker thread (:func:`~morphlab.sensitivity.beside.submit`) while the primal goes
    on, else done at once. Each piece may hold a record, given back (:meth:`reap`) once the
    piece is done."""

    def __init__(self, overlap: bool):
        self.overlap = overlap
        self.jobs: deque[tuple[Future, Keep | None]] = deque()
        self.seconds = 0.0  # the pieces' own time, wherever they ran
        self.waited = 0.0  # the caller's time waiting for the worker

    def _timed(self, fn: Callable[[], None]) -> Callable[[], None]:
        def run():
            t0 = _time.perf_counter()
            try:
                fn()
            finally:
                self.seconds += _time.perf_counter() - t0
        return run

    def put(self, fn: Callable[[], None], record: Keep | None = None) -> list:
        """Hand over ``fn`` (holding ``record``); returns the records given back."""
        fut = submit(self._timed(fn)) if self.overlap else None
        if fut is None:
            self._timed(fn)()
            return [] if record is None else [record]
        self.jobs.append((fut, record))
        return self.reap()

    def reap(self, wait_bytes: int | None = None) -> list:
        """The records of the pieces done, in order (a failed piece's error raised); with
        ``wait_bytes``, waits for the oldest pieces while the records still held exceed it."""
        out = []
        while self.jobs:
            fut, record = self.jobs[0]
            if not fut.done():
                held = sum(_nbytes(R) for _, R in self.jobs if R is not None)
                if wait_bytes is None or held <= wait_bytes:
                    break
                t0 = _time.perf_counter()
                fut.exception()  # wait
                self.waited += _time.perf_counter() - t0
            self.jobs.popleft()
            fut.result()  # a failed piece's error, with its traceback
            if record is not None:
                out.append(record)
        return out

    def drain(self) -> list:
        """Wait for every piece; the records given back (an error raised)."""
        return self.reap(wait_bytes=-1)

    def abandon(self) -> list:
        """After a failure of the run: the pieces not started cancelled, the one running
        waited for (it writes the run's buffers); every record given back, errors dropped."""
        out = []
        for fut, record in self.jobs:
            if not fut.cancel():
                fut.exception()
            if record is not None:
                out.append(record)
        self.jobs.clear()
        return out


class DirectHook(StepHook):
    """The step hook of a direct run (module docstring).

    ``design()`` gives ``(ps, dq0, dv0, kept)``: the pseudo-load data, the derivatives of
    the initial state (n_dof, n_x) and the histories kept in full; it is the first piece of
    the sensitivity work, so with ``overlap`` it runs in the worker thread beside the primal's
    first steps."""

    def __init__(self, system: System, n_steps: int, design: Callable[[], tuple], *,
                 reuse: bool = True, refine: int = 1, overlap: bool = False):
        self.system, self.n_steps, self.design = system, n_steps, design
        # the variant: ``refine`` None for the reuse variant (as the kernels take it), else
        # the exact variant's refinement sweeps
        self.reuse, self.refine = reuse, None if reuse else refine
        self.rows = 3 if reuse else 1
        self.work = _Work(overlap)
        self.d = self.full = self.kept = None  # formed by the first piece of work
        self.begun = False
        self.records: list[Keep] = []  # every record of the run
        self.free: list[Keep] = []  # those not held by a piece of work
        self.current: Keep | None = None  # the record of the chunk the primal is in
        self.like = None  # the last chunk's record and factor arrays (the records' types)
        self.pending: list = []  # steps solved from Python, not yet handed over
        self.main_seconds = 0.0  # the caller's time in the hook

    # --------------------------------------------------------------- the caller's side
    def start(self, stepper, hist) -> None:
        self.stepper, self.hist = stepper, hist
        self.sc = stepper.scheme_of()
        self.sc0 = kernel_scheme(stepper.init_coef, stepper.scale, stepper.b0, stepper.b1,
                                 split=self.rows == 3)
        self.w_old = old_weights(self.sc)

    def python_step(self, k: int, out) -> None:
        """Step ``k`` solved from Python: kept with its factor, handed over (:meth:`_hand`)
        once the factorization has compiled factors, whose record types the kernels take it
        with (at once, but for a sparse run's first steps: SuperLU chooses the row order on
        the first step after the initial solve)."""
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
        if stp.newton.factorization.settled:
            self._hand()
        self.main_seconds += _time.perf_counter() - t0

    def chunk(self, k0: int, k1: int) -> int:
        return min(k1, k0 + OVERLAP_STEPS) if self.work.overlap else k1

    def kernels(self, k0: int, k1: int) -> Keep:
        t0 = _time.perf_counter()
        self._begin()
        F = self.stepper.newton.factorization.loop_arrays()
        K = k1 - k0
        self.free += self.work.reap(wait_bytes=OVERLAP_BYTES)
        j = next((j for j, R in enumerate(self.free)
                  if R.Q.shape[0] >= K + 1 and _fits(R, F)), None)
        if j is None:
            # rounded up, so that runs whose chunks differ by a few steps share the record
            # the last one released (morphlab.solve.record)
            R = keep_record(self.system, F, -(-K // RECORD_STEPS) * RECORD_STEPS, k0,
                            self.reuse, pool="direct", chunks=True)
            self.records.append(R)
        else:
            R = self.free.pop(j)
        self.current = start_record(R, self.hist, k0)
        self.main_seconds += _time.perf_counter() - t0
        return self.current

    def after_chunk(self, k0: int, k1: int) -> None:
        t0 = _time.perf_counter()
        R, self.current = self.current, None
        if k1 <= k0:
            self.free.append(R)
        else:
            F = self.stepper.newton.factorization.loop_arrays()
            self.like = (R, F)
            self._hand()  # the steps before k0 solved from Python

            def sensitivities():
                chunk(self.d, self.M, self.T, self.sc, F, R, k0, k1, self.refine, False,
                      self.w_old)

            self.free += self.work.put(sensitivities, R)
        self.main_seconds += _time.perf_counter() - t0

    def finish(self) -> None:
        """After the run: the steps still kept handed over, and all the work waited for."""
        t0 = _time.perf_counter()
        self._hand()
        self._begin()  # a run of no steps still forms its histories
        self.free += self.work.drain()
        self.main_seconds += _time.perf_counter() - t0

    def abandon(self) -> None:
        """After a failed or interrupted run: the work stopped (:meth:`_Work.abandon`)."""
        self.free += self.work.abandon()

    def _begin(self) -> None:
        """Hand over the first piece of work (:meth:`_prepare`), once. Not before the first
        compiled chunk or handed step: the worker would compete with the run's own Python set-up
        for the interpreter."""
        if not self.begun:
            self.begun = True
            self.free += self.work.put(self._prepare)

    def _hand(self) -> None:
        """Hand over the sensitivities of the steps solved from Python and kept."""
        if not self.pending:
            return
        self._begin()
        # the types of the last chunk's record; before one ran (its record may exist with no
        # step converged in it), those of a record of no steps
        like = (template(self.system, self.stepper.newton.factorization, self.reuse)
                if self.like is None else self.like)
        steps, self.pending = self.pending, []
        self.free += self.work.put(lambda: self._python_steps(steps, like))

    # --------------------------------------------------------------------- the work
    def _prepare(self) -> None:
        """The design data, the histories and the buffers of the sensitivities."""
        ps, dq0, dv0, kept = self.design()
        system, n_steps = self.system, self.n_steps
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
        self.M, self.T = system_read(self.stepper, self.refine, self.w_old, ps)  # the chunk's

    def _python_steps(self, steps: list, like) -> None:
        """The sensitivities of steps solved from Python, in order: right-hand sides by the
        compiled chunk (``rhs_only``, on a record of the step: :func:`~morphlab.solve.record.
        solved_step`), the solves with the step's factor from Python, the update by the
        compiled kernel."""
        d = self.d
        for k, sc, new, old, Dq, Dv, lu in steps:
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
    :meth:`DirectHook._python_steps`)."""
    from ..kernels.types import Level

    return Level(np.array(st.q), np.array(st.v), np.array(st.a), np.array(st.lam))


def direct_run(sys0: System, settings: Settings, design: Callable[[], tuple],
               changes: Callable[[], list], *, responses: dict | None = None,
               reuse: bool = True, refine: int = 1, overlap: bool = False, progress=False):
    """The primal run of ``sys0`` with the direct method's hook: ``design`` as for
    :class:`DirectHook` (with ``overlap`` it runs in the worker thread, and so do the
    sensitivities of each chunk of steps while the primal goes on); ``changes()``: the
    variables' complex-step :class:`~morphlab.sensitivity.designs.Change` (asked for after
    the run: their systems are the perturbed results'). ``responses``: responses, each with
    a ``vjp``, to differentiate by :func:`response_gradients` (their vjps formed while the
    worker finishes), or None.

    Returns ``(result, perturbed, state, timing, stats, values, gradients)``: the primal
    Result, one complex :class:`~morphlab.sensitivity.histories.PerturbedResult` per
    variable, the kept sensitivity histories ``{name: (n_t, width, n_x)}``, the wall times
    (``primal``: the run's without the time the caller spent on or waited for the
    sensitivities; ``sensitivity``: the sensitivity work's own time, wherever it ran), the
    statistics, and the values and gradients (n_x,) of ``responses`` (None without them, or
    where they read a history the run did not keep)."""
    hook = DirectHook(sys0, settings.n_steps, design, reuse=reuse, refine=refine,
                      overlap=overlap)
    t0 = _time.perf_counter()
    vjps = None
    try:
        res0 = integrate(sys0, settings, hook=hook, progress=progress)
        if responses is not None:  # while the worker finishes the last steps' sensitivities
            vjps = [response_vjp(k, fn, res0) for k, fn in responses.items()]
        hook.finish()
    except BaseException:
        hook.abandon()  # the worker writes no more before the run's error is raised
        raise
    finally:
        release(hook.records, "direct")  # the next run's records are made of them
    total = _time.perf_counter() - t0
    by_variable = {k: hook.full[k] for k in HISTORIES if k in hook.kept}
    perturbed = [PerturbedResult(res0, ch.system, by_variable, i)
                 for i, ch in enumerate(changes())]
    refined = hook.d.refined[np.isfinite(hook.d.refined)]
    stats = {"n_factorizations": res0.n_factorizations, "reuse": reuse, "overlap": overlap,
             "refinement_residual": refined.tolist(), "refined_steps": int(refined.size)}
    timing = {"primal": total - hook.main_seconds, "sensitivity": hook.work.seconds,
              "waited": hook.work.waited, "run": total}
    state = {k: np.moveaxis(v, 0, -1) for k, v in by_variable.items()}  # (n_t, width, n_x)
    values = gradients = None
    if vjps is not None:
        t1 = _time.perf_counter()
        G = response_gradients(vjps, state, sys0, changes())
        if G is not None:
            values = {k: vj.value for k, vj in zip(responses, vjps)}
            gradients = {k: G[r] for r, k in enumerate(responses)}
        timing["responses_by_vjp"] = _time.perf_counter() - t1
    stats["responses_by_vjp"] = gradients is not None
    return res0, perturbed, state, timing, stats, values, gradients


def response_gradients(vjps: list, state: dict, sys0: System, changes: list
                       ) -> np.ndarray | None:
    """The gradients (m, n_x) of the responses whose ``vjps`` (their
    :class:`~morphlab.results.gradients.ResponseVJP` at a direct run's result) are given, from
    the run's sensitivity histories ``state`` (``{name: (n_t, width, n_x)}``): the chain rule
    ``df/dp_i = sum_n df/dz_n . dz_n/dp_i`` over the times a response reads (blocks of
    :data:`VJP_BLOCK`), plus its derivatives through the system data
    (:func:`~morphlab.sensitivity.designs.data_terms`, ``changes`` the variables'
    complex-step changes). One pass per response, where evaluating it on every variable's
    complex result takes one per variable. None where a response reads a history the run did
    not keep (then the caller evaluates the responses)."""
    G = data_terms(vjps, sys0, changes).T.copy()  # (m, n_x)
    n_t = next(iter(state.values())).shape[0] if state else 0
    for b in range(0, n_t, VJP_BLOCK):
        e = min(n_t, b + VJP_BLOCK)
        ns = np.arange(b, e)
        for r, vj in enumerate(vjps):
            for name, g in vj.over(ns).items():
                if name not in state:
                    return None
                G[r] += np.einsum("nw,nwx->x", g, state[name][b:e])
    return G
