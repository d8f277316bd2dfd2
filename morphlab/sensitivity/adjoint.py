"""The discrete adjoint of the time loop (``docs/theory.md`` §7).

The direct method carries ``dx_n/dp`` forward, one column per design variable. The adjoint
carries ``x̄_n = dψ/dx_n`` backward, one column per response ``ψ``: it is the exact transpose
of the direct recursion (:mod:`morphlab.sensitivity.direct`), so both agree to round-off.
For step ``n`` (from the last to the initial solve), with ``x̄`` holding the adjoint of the
state ``x_n = (q, q', q'', g, λ)_n`` plus the response's own derivative at ``n``:

* through the Newmark update ``q = q̂ + bh2 a``, ``q' = v̂ + gh a``, ``g = ga a + gan a_n-1 +
  ggn g_n-1``, ``λ = s z_λ``: the adjoint of the step unknowns ``z̄ = (ā + bh2 q̄ + gh v̄ + ga ḡ,
  s λ̄)``;
* through the step solve ``J z = -D R``: ``μ = J^-T z̄`` with the primal's kept factorization
  (refined against the exact converged matrix where the primal's last Newton correction was
  not negligible, as in the direct method);
* through the pseudo-load: the predictors get ``-R_q^T μ``, ``-R_v^T μ`` (and, with the
  paper's weighting, the previous state its old-level share), and the design gets
  ``-μ^T ∂R/∂p``;
* through the predictors ``q̂ = q + h v + cqa a + cqg g``, ``v̂ = v + cva a + cvg g``: the
  adjoint of the previous state.

At the initial solve the adjoints of ``q_0``, ``q'_0`` meet their derivatives from ``build``.
The state matrices ``R_q``, ``R_v`` come from the same kernels as the direct method's
(:func:`~morphlab.kernels.direct.split_matrices`), the transposed solves from the same factors
(:meth:`morphlab.solve.linalg.Factor.solve_transposed`).
"""

from __future__ import annotations

import os
import time as _time
from collections import deque
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from itertools import groupby

import numpy as np

from ..compile import System
from ..compile.system import table_at
from ..kernels.adjoint import adjoint_block, explicit_adjoint_block
from ..kernels.direct import csc_residual_transposed, csc_transposed_product, split_matrices
from ..kernels.system import DESIGN_FIELDS
from ..results.gradients import ResponseVJP, response_vjp, system_data
from ..solve.linalg import stacked_arrays
from ..solve.settings import Settings
from ..solve.timeloop import StepInfo, integrate
from .histories import to_store
from .perturb import CS_STEP, ComplexDesigns, PseudoLoadData


def _state_bytes(st) -> int:
    return sum(x.nbytes for x in (st.q, st.v, st.a, st.lam, st.g))


class _Recorder:
    """Forward observer: keeps every converged step — ``(n, state, factorization, last Newton
    correction, coefficients)`` — while they fit ``budget`` bytes. When they would not (known
    after the first steps from the bytes per step and the number of steps, or found when the
    kept steps exceed the budget) the run keeps only checkpoints, the state after every
    ``K``-th step (``K`` chosen so that one segment of ``K`` recomputed steps takes half the
    budget), and the backward sweep recomputes the steps of each segment from its checkpoint
    (:func:`_segments`), in compiled blocks whose stacked factors take ~1/8 of the budget."""

    def __init__(self, budget: int, n_steps: int, check: Callable[[], None] | None = None):
        self.budget, self.n_steps, self.check = budget, n_steps, check
        self.per_step = 0.0
        self.steps: list = []
        self.bytes = 0
        self.K: int | None = None
        self.checkpoints: dict = {}  # step -> state
        self.stepper = None
        self.table = None

    def __call__(self, info: StepInfo) -> None:
        if self.check is not None:  # a failed compile of the perturbed designs ends the run
            self.check()
        self.stepper, self.table = info.stepper, info.table
        last = info.newton_history[-1, 1] if len(info.newton_history) else 0.0
        if self.K is not None:
            if info.n % self.K == 0:
                self.checkpoints[info.n] = info.state
            return
        self.steps.append((info.n, info.state, info.lu, last, info.coef))
        self.bytes += _state_bytes(info.state) + info.lu.nbytes + 500
        self.per_step = self.bytes / len(self.steps)
        # checkpoints from now on: when the kept steps exceed the budget, or (from the first
        # steps on) when the whole run would, so that the budget is never filled and dropped
        projected = info.n > 2 and self.per_step * (self.n_steps + 1) > self.budget
        if self.bytes > self.budget or projected:
            self.K = max(1, int(self.budget // (2 * self.per_step)))
            self.checkpoints = {n: st for n, st, *_ in self.steps if n % self.K == 0}
            self.steps = []


def _segments(rec: _Recorder, settings: Settings, q0, v0):
    """The recorded steps in segments, last segment first: ``(steps, prev)`` with ``steps`` a
    list of ``(n, state, factor, last, coef)`` in time order and ``prev`` the state before
    the first of them (None for the initial solve). Kept steps come as one segment; with
    checkpoints each segment's steps are recomputed from the checkpoint before them, with the
    run's settings and scale."""
    if rec.K is None:
        yield rec.steps, None
        return
    stp = rec.stepper
    fresh = type(stp).dynamic(stp.system, settings, scale=stp.scale)
    table = rec.table
    n_steps = settings.n_steps
    t = settings.t_start + settings.h * np.arange(n_steps + 1)
    for c in sorted(rec.checkpoints, reverse=True):
        if c == n_steps:
            continue
        steps = []
        if c == 0:
            st, lu, _ = fresh.initial(t[0], q0, v0, ta=table_at(table, 0))
            steps.append((0, st, lu, 0.0, fresh.init_coef))
            prev = None
        else:
            st = prev = rec.checkpoints[c]
        for n in range(c + 1, min(c + rec.K, n_steps) + 1):
            new, lu, _, _, _, _, _, hist = fresh.step(st, float(t[n]), n, table_at(table, n - 1),
                                                    table_at(table, n))
            steps.append((n, new, lu, hist[-1, 1] if len(hist) else 0.0, fresh.step_coef))
            st = new
        yield steps, prev


def _design_share(sys0: System, stp, data: PseudoLoadData, W, i0: int, i1: int, Q, V, A, L,
                  coef, k_new, MU, grad) -> None:
    """``grad[i] -= sum_j (dR_j/dp_i)^T MU[j]`` for the variables ``i0 .. i1-1`` over steps
    with states ``(Q, V, A, L)[j + 1]`` (``[0]`` the state before them), coefficients
    ``coef`` and time indices ``k_new``; ``W``: design scratch, a copy of ``data.W``
    (:func:`~morphlab.kernels.adjoint.explicit_adjoint_block`)."""
    work = np.zeros((2, sys0.n), dtype=data.dtype)
    explicit_adjoint_block(data.S_nom, W, data.D, data.parts, data.lin, data.touched, Q, V, A, L,
                           coef.arrays.w_new, coef.old is not None, coef.arrays.w_old,
                           stp.scale, stp.b0, stp.b1, data.TAB, data.tab_of,
                           np.maximum(k_new - 1, 0), k_new, sys0.n_dof, data.pert, i0, i1,
                           work, np.ascontiguousarray(MU), grad)


def _split(stp, st, w, F, n_dof):
    """``(D0, Dq, Dv)`` CSC data of one level's residual share at the state ``st``."""
    D = np.zeros((3, stp.system.nnz))
    split_matrices(stp.S, st.q, st.v, st.a, st.lam, w, stp.scale, stp.b0, stp.b1, F, D)
    return D[0], D[1], D[2]


def _tproduct(sys0: System, D, x, n_cols: int) -> np.ndarray:
    """``-D[:, :n_cols]^T x`` (n_cols, m)."""
    out = np.zeros((n_cols, x.shape[1]))
    csc_transposed_product(D, sys0.indices, sys0.indptr, n_cols, x, out)
    return out


#: Blocks whose design share may wait for the shares' threads (:class:`_Sweep`): their states
#: and adjoint vectors are held meanwhile, each block at most an eighth of the memory budget.
PENDING_SHARES = 2
#: Threads adding the design's shares, each for a contiguous range of the variables.
SHARE_THREADS = min(2, os.cpu_count() or 1)


class _Sweep:
    """The backward sweep (module docstring) over segments of steps: the adjoint state
    ``bar`` of the step last processed and the gradient ``grad`` (n_x, m) so far, without the
    responses' own data terms. ``data()`` forms the pseudo-load data once ``wait()`` has
    returned (the designs compiled); until ``ready()`` says so, the design's share of each
    block is kept (:meth:`_design`) and added once they are.

    The design's shares are added on threads of their own (:data:`SHARE_THREADS`, each for a
    range of the variables, so each row of ``grad`` gains its terms in the order of the
    blocks: the same gradient to the bit) while the sweep goes on to the next block. The
    kernels run without the GIL: on two cores the shares cost no wall time while they are
    shorter than the sweep, and those left at the end (the designs compiled last) take both
    cores. At most :data:`PENDING_SHARES` blocks wait for them. :meth:`finish` (or
    :meth:`close`, on an error) ends the threads."""

    def __init__(self, sys0: System, stp, vjps: list[ResponseVJP],
                 data: Callable[[], PseudoLoadData], n_x: int, refine: int, refine_tol: float,
                 F, stats: dict, block_bytes: float = np.inf, step_bytes: float = 1.0,
                 ready: Callable[[], bool] = lambda: True, wait: Callable[[], object] = list):
        self.sys0, self.stp, self.vjps, self.F = sys0, stp, vjps, F
        self.block_bytes, self.step_bytes = block_bytes, step_bytes
        self.refine, self.refine_tol, self.stats = refine, refine_tol, stats
        n_dof, n_con, m = sys0.n_dof, sys0.n_con, len(vjps)
        self.bar = {k: np.zeros((w, m)) for k, w in (("q", n_dof), ("v", n_dof),
                                                      ("a", n_dof), ("g", n_dof),
                                                      ("lam", n_con))}
        self.grad = np.zeros((n_x, m))
        # the design's share waits (``_deferred``, at most ``block_bytes``) while the designs
        # still compile on their thread: the state sweep needs none of them
        self._data, self._ready, self._wait, self.data = data, ready, wait, None
        self._deferred: list = []
        self._deferred_bytes = 0
        self.wait = 0.0
        cuts = np.linspace(0, n_x, min(SHARE_THREADS, max(n_x, 1)) + 1).astype(int)
        self._ranges = list(zip(cuts[:-1].tolist(), cuts[1:].tolist()))
        self._shares = [ThreadPoolExecutor(1, thread_name_prefix="morphlab-shares")
                        for _ in self._ranges]
        self._W: list = []  # each thread's design scratch
        self._pending: deque = deque()

    def _design(self, *args) -> None:
        """The design's share of steps (:func:`_design_share` without its first six
        arguments; ``("initial", q̄, v̄)``: the terms of ``dq0``, ``dv0``), now if the designs
        are compiled or the deferred shares would exceed ``block_bytes``, else later."""
        if self.data is None and not self._ready():
            size = sum(a.nbytes for a in args if isinstance(a, np.ndarray))
            if self._deferred_bytes + size <= self.block_bytes:
                self._deferred.append(args)
                self._deferred_bytes += size
                self.stats["deferred_shares"] = self.stats.get("deferred_shares", 0) + 1
                return
        self._flush()
        self._apply(args)

    def _apply(self, args) -> None:
        """Hand one share to the shares' threads (waiting for the oldest beyond
        :data:`PENDING_SHARES`)."""
        if not self._W:
            W = self.data.W
            self._W = [W] + [W._replace(**{k: getattr(W, k).copy() for k in DESIGN_FIELDS})
                             for _ in self._ranges[1:]]
        self._pending.append([pool.submit(self._add_share, k, args)
                              for k, pool in enumerate(self._shares)])
        while len(self._pending) > PENDING_SHARES:
            for f in self._pending.popleft():
                f.result()

    def _add_share(self, k: int, args) -> None:
        """The share ``args`` (:meth:`_design`) for the variables of range ``k``."""
        i0, i1 = self._ranges[k]
        if isinstance(args[0], str):  # ("initial", q̄, v̄)
            d = self.data
            self.grad[i0:i1] += d.dq0[:, i0:i1].T @ args[1] + d.dv0[:, i0:i1].T @ args[2]
        else:
            _design_share(self.sys0, self.stp, self.data, self._W[k], i0, i1, *args,
                          self.grad)

    def _flush(self) -> None:
        """Wait for the designs (if they still compile) and add the deferred shares."""
        if self.data is None:
            t0 = _time.perf_counter()
            self._wait()
            self.wait += _time.perf_counter() - t0
            self.data = self._data()
        for args in self._deferred:
            self._apply(args)
        self._deferred, self._deferred_bytes = [], 0

    def finish(self) -> None:
        """:meth:`_flush` and wait for the shares' thread: ``grad`` is complete."""
        self._flush()
        try:
            while self._pending:
                for f in self._pending.popleft():
                    f.result()
        finally:
            self.close()

    def close(self) -> None:
        """End the shares' threads (after the shares handed to them)."""
        for pool in self._shares:
            pool.shutdown(wait=True)

    def segment(self, steps: list, prev) -> None:
        """Sweep one segment of steps (in time order; ``prev`` the state before them): runs
        of steps whose factors a compiled kernel solves, stacked without a copy, and that
        share coefficients in one call each (:func:`~morphlab.kernels.adjoint.adjoint_block`),
        SuperLU's from Python."""
        runs = [(key, len(list(g))) for key, g in
                groupby(steps, key=lambda st: (st[2].group, id(st[4]), st[2].chunk))]
        end = len(steps)
        for (group, _, _), count in reversed(runs):
            start = end - count
            if group is None:
                for j in range(end - 1, start - 1, -1):
                    self.step(steps[j], steps[j - 1][1] if j > 0 else prev)
            else:  # sub-blocks whose stacked copies of the factors take ~1/8 of the budget
                size = max(1, int(self.block_bytes // max(self.step_bytes, 1.0)))
                for j1 in range(end, start, -size):
                    j0 = max(start, j1 - size)
                    self._block(steps, j0, j1, steps[j0 - 1][1] if j0 > 0 else prev)
            end = start

    def _block(self, steps: list, j0: int, j1: int, prev) -> None:
        """Steps ``j0 .. j1-1`` (one factor group and coefficients) in one compiled call."""
        sys0, stp, bar = self.sys0, self.stp, self.bar
        block = steps[j0:j1]
        K, m = len(block), len(self.vjps)
        coef = block[0][4]
        first = block[0][1]
        old = (first.q, first.v, np.zeros(sys0.n_dof), np.zeros(sys0.n_con)) if prev is None \
            else (prev.q, prev.v, prev.a, prev.lam)
        Q, V, A, L = (np.stack([old[c]] + [(st.q, st.v, st.a, st.lam)[c] for _, st, *_ in
                                           block]) for c in range(4))
        k_new = np.array([b[0] for b in block], dtype=np.int64)
        H = self._terms(k_new)
        refine = np.array([self.refine > 0 and n > 0 and last > self.refine_tol
                           for n, _, _, last, _ in block])
        MU = np.zeros((K, sys0.n, m))
        refined = np.full(K, np.nan)
        nnz = sys0.nnz
        initial = adjoint_block(
            stp.S, Q, V, A, L, coef.arrays.w_new, coef.old is not None, coef.arrays.w_old,
            self.F, k_new, stp.scale, stp.b0, stp.b1, coef.bh2, coef.gh, sys0.indices,
            sys0.indptr, sys0.n_dof, coef.arrays.pc, coef.arrays.upd, *H, bar["q"], bar["v"],
            bar["a"], bar["g"], bar["lam"], np.zeros((3, nnz)), np.zeros(nnz),
            *stacked_arrays([b[2] for b in block]), refine, self.refine, MU, refined)
        self.stats["refinement_residual"] += refined[refine].tolist()
        self._design(Q, V, A, L, coef, k_new, MU)
        if initial >= 0:
            self._design("initial", bar["q"].copy(), bar["v"].copy())

    def _terms(self, k_new: np.ndarray) -> tuple:
        """The responses' own derivatives at the times ``k_new``: ``(Hq, Hv, Ha, Hl)``
        (K, width, m), empty (0, width, m) for a history no response reads here."""
        sys0, m = self.sys0, len(self.vjps)
        widths = {"q": sys0.n_dof, "v": sys0.n_dof, "a": sys0.n_dof, "lam": sys0.n_con}
        H = {}
        for r, vj in enumerate(self.vjps):
            for name, g in vj.over(k_new).items():
                if name not in H:
                    H[name] = np.zeros((k_new.size, widths[name], m))
                H[name][:, :, r] += g
        return tuple(H.get(k, np.zeros((0, widths[k], m))) for k in ("q", "v", "a", "lam"))

    def step(self, step, prev) -> None:
        """Step ``n`` of the sweep: ``bar`` from the adjoint of ``x_n`` to that of
        ``x_n-1`` (at the initial solve, the terms of ``dq0``, ``dv0`` into ``grad``)."""
        sys0, stp, bar, s = self.sys0, self.stp, self.bar, self.stp.scale
        n_dof, n_con = sys0.n_dof, sys0.n_con
        n, st, lu, last, coef = step
        for r, vj in enumerate(self.vjps):
            for name, g in vj.at(n).items():
                bar[name][:, r] += g
        h, cqa, cqg, cva, cvg, bh2, gh = coef.arrays.pc
        ga, gan, ggn = coef.arrays.upd
        zb = np.concatenate([bar["a"] + bh2 * bar["q"] + gh * bar["v"] + ga * bar["g"],
                             s * bar["lam"]])
        D0, Dq, Dv = _split(stp, st, coef.arrays.w_new, self.F[n], n_dof)
        mu = lu.solve_transposed(zb)
        if self.refine and n > 0 and last > self.refine_tol:
            mu = self._refined(mu, zb, D0 + bh2 * Dq + gh * Dv, lu)
        qhb = bar["q"] + _tproduct(sys0, Dq, mu, n_dof)
        vhb = bar["v"] + _tproduct(sys0, Dv, mu, n_dof)
        old = (st.q, st.v, np.zeros(n_dof), np.zeros(n_con)) if prev is None else (
            prev.q, prev.v, prev.a, prev.lam)
        Q, V, A, L = (np.stack([old[c], (st.q, st.v, st.a, st.lam)[c]]) for c in range(4))
        self._design(Q, V, A, L, coef, np.array([n]), mu[None])
        if n == 0:
            self._design("initial", qhb, vhb)
            return
        gb = bar["g"]
        bar["q"] = qhb
        bar["v"] = h * qhb + vhb
        bar["a"] = cqa * qhb + cva * vhb + gan * gb
        bar["g"] = cqg * qhb + cvg * vhb + ggn * gb
        bar["lam"] = np.zeros((n_con, gb.shape[1]))
        if coef.old is not None:  # the paper's weighting: the old level's share
            D0o, Dqo, Dvo = _split(stp, prev, coef.arrays.w_old, self.F[n - 1], n_dof)
            bar["q"] += _tproduct(sys0, Dqo, mu, n_dof)
            bar["v"] += _tproduct(sys0, Dvo, mu, n_dof)
            wz = _tproduct(sys0, D0o, mu, sys0.n)
            bar["a"] += wz[:n_dof]
            bar["lam"] += wz[n_dof:] / s

    def _refined(self, mu, zb, J, lu):
        """``refine`` sweeps of iterative refinement of ``J^T mu = zb`` (the factorization is
        one Newton iterate behind the exact matrix ``J``)."""
        sys0 = self.sys0
        r = np.empty_like(zb)
        for _ in range(self.refine):
            csc_residual_transposed(J, sys0.indices, sys0.indptr, mu, zb, r)
            mu = mu + lu.solve_transposed(r)
        rr, bb = csc_residual_transposed(J, sys0.indices, sys0.indptr, mu, zb, r)
        self.stats["refinement_residual"].append(rr / max(bb, 1e-300))
        return mu


def _data_terms(vjps: list[ResponseVJP], sys0: System, complex_systems: list) -> np.ndarray:
    """The responses' own derivatives through the system data they read, mapped to the
    variables with the data's complex-step derivatives (n_x, m)."""
    out = np.zeros((len(complex_systems), len(vjps)))
    for r, vj in enumerate(vjps):
        for key, g in vj.data.items():
            for i, cs in enumerate(complex_systems):
                out[i, r] += np.sum(np.real(g) * np.imag(system_data(cs, key))) / CS_STEP
    return out


def adjoint_run(sys0: System, settings: Settings, responses: dict, designs: ComplexDesigns,
                data: Callable[[], PseudoLoadData], *, refine: int = 1,
                refine_tol: float = 1e-12, memory: int = 2**30, progress=False):
    """The primal run, the responses' gradients and the backward sweep.

    ``designs``: the complex-step systems of the variables, which may still be compiling on a
    thread while the primal runs (their error, if any, stops the primal at the next step) and
    while the backward sweep solves for the adjoint states, which need none of them (the
    design's share of each block waits meanwhile, within ``memory / 8`` bytes);
    ``data()``: the pseudo-load data formed from them, called once they are compiled. ``memory``:
    bytes of states and factorizations kept for the sweep; beyond them the run keeps
    checkpoints and the sweep recomputes segments (:class:`_Recorder`). The primal keeps only
    the histories the responses read. Returns ``(result, values, gradients, timing, stats)``
    with ``values[name]`` and ``gradients[name]`` (n_x,) in the order of the variables."""
    rec = _Recorder(memory, settings.n_steps, check=designs.check)
    t0 = _time.perf_counter()
    kept = to_store("auto", responses, sys0, settings)
    try:
        res0 = integrate(sys0, settings, observer=rec, progress=progress, store=kept)
    except BaseException:
        designs.stop()
        raise
    t_primal = _time.perf_counter() - t0
    names = list(responses)
    vjps = [response_vjp(k, responses[k], res0) for k in names]
    stats = {"refinement_residual": [], "n_factorizations": res0.n_factorizations,
             "segment_steps": rec.K, "designs_in_background": designs.background,
             "deferred_shares": 0}
    sweep = _Sweep(sys0, rec.stepper, vjps, data, designs.n_variables, refine, refine_tol,
                   rec.table.F, stats, block_bytes=memory / 8, step_bytes=rec.per_step,
                   ready=designs.done, wait=designs.result)
    try:
        for steps, prev in _segments(rec, settings, sys0.q0, sys0.v0):
            sweep.segment(steps, prev)
        sweep.finish()
    finally:
        sweep.close()
    t_wait = sweep.wait
    grad = sweep.grad + _data_terms(vjps, sys0, designs.result())
    total = _time.perf_counter() - t0
    timing = {"primal": t_primal, "sensitivity": total - t_primal, "run": total,
              "designs": designs.seconds, "designs_wait": t_wait}
    values = {k: vj.value for k, vj in zip(names, vjps)}
    gradients = {k: grad[:, r] for r, k in enumerate(names)}
    return res0, values, gradients, timing, stats
