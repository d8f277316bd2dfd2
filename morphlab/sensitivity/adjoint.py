"""The discrete adjoint of the time loop (``docs/theory.md`` §7).

The direct method carries ``dx_n/dp`` forward, one column per design variable. The adjoint
carries ``x̄_n = dψ/dx_n`` backward, one column per response ``ψ``: it is the exact transpose
of the direct recursion (:mod:`morphlab.sensitivity.direct`), so both agree to round-off in
the exact variant (:mod:`morphlab.kernels.adjoint` has the step). The primal run records what
the backward sweep reads of each step (:mod:`morphlab.sensitivity.adjoint_record`): its
factors, the ``Dq``, ``Dv`` of its last Newton fill and its state — the compiled steps in a
:class:`~morphlab.kernels.adjoint.Keep`, the steps solved from Python (the initial solve, the
steps SuperLU chooses a row order on) one by one. When the record of the whole run would not
fit ``memory`` bytes, the run keeps checkpoints instead (the state at the start of every
segment of steps) and the sweep recomputes each segment once more, last segment first. The
design variables enter through the explicit parts of the pseudo-loads only, contracted with
each step's adjoint vector ``μ`` in a compiled kernel of their own, block by block of swept
steps, in the worker thread beside the sweep of the next block where a core is free
(:class:`_SharesBeside`); those that change the bodies' linear data alone (sections,
materials, rigid bodies' masses) through the data gradient of the bodies' kinds, formed once
a step for all of them and contracted with their ``dD/dp`` after the sweep
(:mod:`morphlab.kernels.ffrf_adjoint`).
"""

from __future__ import annotations

import time as _time
from collections.abc import Callable

import numpy as np

from ..compile import System
from ..kernels import adjoint as kadj
from ..kernels.ffrf import scratch
from ..kernels.ffrf_adjoint import FIELDS, STIFFNESS
from ..kernels.pseudo import Column
from ..kernels.system import KIND_NAMES
from ..kernels.types import Level
from ..results.gradients import ResponseVJP, response_vjp
from ..solve.record import release, solved_step, template
from ..solve.scheme import kernel_scheme, old_weights
from ..solve.settings import Settings
from ..solve.timeloop import integrate
from .adjoint_record import AdjointHook, _PythonStep, _Replay
from .beside import Beside
from .designs import data_terms, system_read
from .histories import to_store
from .units import BODY_KINDS, bodies_linear, share_units


def _terms(vjps: list[ResponseVJP], ns: np.ndarray, s: System) -> tuple:
    """The responses' own derivatives at the time indices ``ns``: ``(Hq, Hv, Ha, Hl)`` with a
    leading axis over ``ns``."""
    m = len(vjps)
    out = [np.zeros((ns.size, s.n_dof, m)), np.zeros((ns.size, s.n_dof, m)),
           np.zeros((ns.size, s.n_dof, m)), np.zeros((ns.size, s.n_con, m))]
    for r, vj in enumerate(vjps):
        for name, g in vj.over(ns).items():
            out[("q", "v", "a", "lam").index(name)][:, :, r] += g
    return tuple(out)


def adjoint_run(sys0: System, settings: Settings, responses: dict, design: Callable[[], tuple],
                *, overlap: bool = False, reuse: bool = True, refine: int = 1,
                memory: int = 2**30, progress=False):
    """The primal run, the responses' gradients and the backward sweep (module docstring).

    ``design()``: what the sweep reads of the variables, ``(ps, dq0, dv0, changes)`` — the
    pseudo-load data (:class:`~morphlab.kernels.pseudo.Pseudo`) with the residual rows each
    variable touches, the derivatives of the initial state (n_dof, n_x) each and the
    variables' complex-step changes (:class:`~morphlab.sensitivity.designs.Change`; their
    systems for the responses' data terms). With ``overlap`` it is called, and the bodies'
    data gradient laid out, in a worker thread while the primal's compiled steps run
    (:class:`~morphlab.sensitivity.beside.Beside`, started after the first compiled chunk);
    else after the primal run. Returns ``(result, values, gradients, timing, stats)`` with
    ``values[name]`` and ``gradients[name]`` (n_x,) in the order of the variables."""
    m = len(responses)

    def prepared():  # the design data and what follows from them alone
        ps, dq0, dv0, changes = design()
        lumped = bodies_linear(ps, dq0.shape[1])
        return ps, dq0, dv0, changes, lumped, _data_gradient(sys0, ps, lumped, m)

    hook = AdjointHook(sys0, settings.n_steps, memory, reuse, Beside(prepared, overlap))
    t0 = _time.perf_counter()
    kept = to_store("auto", responses, sys0, settings)
    res0 = integrate(sys0, settings, hook=hook, progress=progress, store=kept)
    t_primal = _time.perf_counter() - t0
    names = list(responses)
    vjps = [response_vjp(k, responses[k], res0) for k in names]
    ps, dq0, dv0, changes, lumped, (GD, GO, KS) = hook.beside.result()
    exact = None if reuse else refine  # the sweep's ``refine`` (None: the reuse variant)
    stp = hook.stepper
    # a record and factor arrays the sweep takes (its types for the steps solved from Python)
    like = ((hook.records[-1], hook.patterns[-1]) if hook.records else
            template(sys0, stp.newton.factorization, hook.rows == 3))
    RO, RI = _touched(sys0, ps, lumped, stp, like, exact)
    PO, PP, PV = ps.PO, ps.PP, ps.PV
    ps, UO, UI, UV = share_units(ps, RO, RI, skip=lumped)
    sc = stp.scheme_of()
    w_old = old_weights(sc)
    M, T = system_read(stp, exact, w_old)
    a = _sweep_state(sys0, m, settings.n_steps + 1, M is not None)
    sh = _shares_state(sys0, ps, m, (RO, RI), (UO, UI, UV), (GD, GO, KS))
    sc0 = kernel_scheme(stp.init_coef, stp.scale, stp.b0, stp.b1, split=hook.rows == 3)
    N = settings.n_steps
    pipe = _SharesBeside(sh, stp, sys0.n_dof + sys0.n_con, m, _block(N, sys0, m), overlap)

    def sweep(K, F, hi: int, lo: int) -> None:  # steps hi down to lo of K, block by block
        while hi >= lo:
            b = max(lo, hi - pipe.block + 1)
            MU = pipe.buffer()
            kadj.sweep(M, T, sc, stp.newton.csc, F, K, a, MU, hi, b, exact, -1, -1, w_old)
            pipe.submit(sc, K, MU, hi, b)
            hi = b - 1

    starts = sorted(hook.checkpoints)
    replay = _Replay(hook, settings) if hook.segment is not None else None
    k = N
    while k >= 0:
        if k in hook.python:
            a = _with_terms(a, vjps, sys0, k, k)
            sck = sc0 if k == 0 else sc
            MU = pipe.buffer()
            K = _python_step(a, hook.python[k], stp, sck, k, exact, like, w_old, MU)
            pipe.submit(sck, K, MU, k, k)
            k -= 1
            continue
        lo = k
        while lo - 1 >= 0 and lo - 1 not in hook.python:
            lo -= 1
        K, F = hook.record_of(k)
        first_checkpoint = min(starts) if starts else N + 1
        if K is not None and k < first_checkpoint:
            lo = max(lo, int(K.k0[0]))
            a = _with_terms(a, vjps, sys0, lo, k)
            sweep(K, F, k, lo)
        else:
            c = max(c for c in starts if c <= k)
            lo = max(lo, c)
            pieces = replay.segment(c, k + 1)
            for K, F in reversed(pieces):
                if k < lo:
                    break
                k0 = max(lo, int(K.k0[0]))
                a = _with_terms(a, vjps, sys0, k0, k)
                sweep(K, F, k, k0)
                like = K, F
                k = k0 - 1
            # the next segment's record is made of them, once the shares have read them
            pipe.wait()
            release([K for K, _ in pieces], "adjoint")
        k = lo - 1
    pipe.wait()
    if hook.records:  # the next run's record is made of them (``solve/record.py``)
        release(hook.records, "adjoint")
    for i in np.flatnonzero(lumped):  # their shares <G, dD/dp_i> (the stiffness's: in shares)
        sh.grad[i] -= PV[PO[i]:PO[i + 1]] @ GD[PP[PO[i]:PO[i + 1]]]
    grad = sh.grad + dq0.T @ a.Bq + dv0.T @ a.Bv + data_terms(vjps, sys0, changes)
    total = _time.perf_counter() - t0
    refined = a.refined[np.isfinite(a.refined)]
    stats = {"n_factorizations": res0.n_factorizations, "segment_steps": hook.segment,
             "reuse": reuse, "refinement_residual": refined.tolist()}
    timing = {"primal": t_primal, "sensitivity": total - t_primal, "run": total}
    values = {k: vj.value for k, vj in zip(names, vjps)}
    gradients = {k: grad[:, r] for r, k in enumerate(names)}
    return res0, values, gradients, timing, stats


def _sweep_state(sys0: System, m: int, n_t: int, matrices: bool):
    """A :class:`~morphlab.kernels.adjoint.Sweep` at zero for ``m`` responses over ``n_t``
    time indices; the bodies' scratch only where the sweep forms ``matrices``."""
    n_dof, n_con = sys0.n_dof, sys0.n_con
    n = n_dof + n_con
    return kadj.Sweep(*(np.zeros((n_dof, m)) for _ in range(4)), np.zeros((n_con, m)),
                      *(np.zeros((0, n_dof, m)) for _ in range(3)), np.zeros((0, n_con, m)),
                      np.zeros(1, dtype=np.int64), *(np.zeros((n, m)) for _ in range(4)),
                      np.zeros((n_dof, m)), np.zeros((6, sys0.nnz)), np.full(n_t, np.nan),
                      scratch(sys0.count("flex"), np.zeros(1)) if matrices else None)


def _shares_state(sys0: System, ps, m: int, rows: tuple, units: tuple, data: tuple,
                  probe: int = 0):
    """The :class:`~morphlab.kernels.adjoint.Shares` at zero for ``m`` responses: the
    pseudo-load data ``ps``, the rows its variables touch ``(RO, RI)``, its units ``(UO, UI,
    UV)`` and its data gradient ``(GD, GO, KS)`` (:func:`_data_gradient`); ``probe``: units
    of a probe (:func:`_touched`), none for a run's shares."""
    n_dof, n_con = sys0.n_dof, sys0.n_con
    n = n_dof + n_con
    n_x = ps.PO.size - 1
    GD, GO, KS = data
    return kadj.Shares(ps, *rows, *units, np.zeros((n_x, m)), GD, GO, *KS,
                       Column.zeros(n_dof, n_con, sys0.count("flex"), ps),
                       np.zeros((probe, n if probe else 0)))


def _share_inputs(ps, M, T, K) -> tuple:
    """``(M, T, K)`` as the design's shares (:func:`~morphlab.kernels.adjoint.shares`) take
    them: with the pseudo-load data ``ps`` on the linear path alone, the system ``M`` with the
    bodies' kinds alone and no time values ``T`` (the nominal residual the rest would serve is
    the perturbed path's); of the record ``K`` (:class:`~morphlab.kernels.adjoint.Keep`) its
    states alone. What is None the kernel's Python entry does not unbox: its compile grows
    with every array it does (about 6 ms an array)."""
    if ps.MN is None:
        M = M._replace(**{k: None for k in KIND_NAMES if k not in BODY_KINDS})
        T = None
    return M, T, K._replace(LU=None, piv=None, Lx=None, Ux=None, Ud=None, D=None)


def _block(n_steps: int, sys0: System, m: int) -> int:
    """Steps per block of the sweep, whose design's shares run beside the next block's
    sweep (:class:`_SharesBeside`): an eighth of the run, at least 16 steps, and at most
    what 16 MiB of adjoint vectors hold."""
    per = (sys0.n_dof + sys0.n_con) * m * 8
    return max(1, min(max(16, -(-(n_steps + 1) // 8)), (16 << 20) // per))


class _SharesBeside:
    """The design's shares of the swept blocks (:func:`~morphlab.kernels.adjoint.shares`),
    computed in the worker thread while the sweep goes on (``overlap``), else at once in the
    caller's: block after block in the order of the sweep, so the gradient adds the same
    terms in the same order either way. Two buffers of adjoint vectors (``block`` steps each)
    alternate: the sweep fills one while the shares read the other."""

    def __init__(self, sh, stp, n: int, m: int, block: int, overlap: bool):
        self.sh, self.stp, self.block, self.overlap = sh, stp, block, overlap
        self.buffers = [np.zeros((block, n, m)) for _ in range(2)]
        self.pending: list = [None, None]
        self.turn = 0

    def buffer(self) -> np.ndarray:
        """The buffer the sweep fills next, once the shares that read it are done."""
        work = self.pending[self.turn]
        if work is not None:
            work.result()
            self.pending[self.turn] = None
        return self.buffers[self.turn]

    def submit(self, sc, K, MU, hi: int, lo: int) -> None:
        """The shares of steps ``hi`` down to ``lo`` of the record ``K``, whose adjoint
        vectors the sweep wrote into ``MU`` (the buffer :meth:`buffer` gave)."""
        M, T, K = _share_inputs(self.sh.ps, self.stp.M, self.stp.T, K)
        work = Beside(lambda: kadj.shares(self.sh, M, T, sc, K, MU, hi, lo), self.overlap)
        work.start()
        if not work.started:
            work.result()
        self.pending[self.turn] = work
        self.turn ^= 1

    def wait(self) -> None:
        """Every submitted share done (their errors raised)."""
        for i, work in enumerate(self.pending):
            if work is not None:
                work.result()
                self.pending[i] = None


def _data_gradient(sys0: System, ps, lumped: np.ndarray, m: int) -> tuple:
    """``(GD, GO, (KO, KX, KE, KV))``: the bodies' data gradient for ``m`` responses, zero, in
    the layout of the flat design data (n_design, m; no rows when no variable is ``lumped``)
    and the offsets of its fields (:func:`~morphlab.kernels.ffrf_adjoint.data_gradient`); the
    stiffness derivatives of each lumped variable, element by element, for its share of them
    (:func:`~morphlab.kernels.ffrf_adjoint.stiffness_share`)."""
    slots = {(s.kind, s.field): s for s in sys0.slots}
    GO = np.array([slots[f].start for f in FIELDS], dtype=np.int64)
    k = slots[STIFFNESS]  # k.size = 36 entries an element
    KX, KE, KV = [], [np.zeros(0, np.int64)], [np.zeros((0, k.size))]
    for i in np.flatnonzero(lumped):
        pos, val = ps.PP[ps.PO[i]:ps.PO[i + 1]], ps.PV[ps.PO[i]:ps.PO[i + 1]]
        sel = (pos >= k.start) & (pos < k.start + k.n * k.size)
        if sel.any():
            elements, at = np.unique((pos[sel] - k.start) // k.size, return_inverse=True)
            dK = np.zeros((elements.size, k.size))
            dK[at, (pos[sel] - k.start) % k.size] = val[sel]
            KX.append(i)
            KE.append(elements)
            KV.append(dK)
    KO = np.zeros(len(KX) + 1, dtype=np.int64)
    KO[1:] = np.cumsum([e.size for e in KE[1:]])
    K = (KO, np.array(KX, dtype=np.int64), np.concatenate(KE).astype(np.int64),
         np.concatenate(KV))
    return np.zeros((sys0.design.size if lumped.any() else 0, m)), GO, K


def _with_terms(a, vjps, sys0, lo: int, hi: int):
    """The sweep state ``a`` with the responses' terms of the time indices ``lo .. hi``."""
    H = _terms(vjps, np.arange(lo, hi + 1), sys0)
    return a._replace(Hq=H[0], Hv=H[1], Ha=H[2], Hl=H[3], h0=np.array([lo], dtype=np.int64))


def _python_step(a, step: _PythonStep, stp, sc, k: int, refine: int | None, like,
                 w_old, MU) -> kadj.Keep:
    """Step ``k`` of the sweep with a factor from Python, on a record of this step
    (:func:`~morphlab.solve.record.solved_step` with the types of ``like``, a record and
    factor arrays of the run or None; ``refine``, ``w_old`` as for the sweep). A compiled
    factor of the kind of the run's goes into the record, and the sweep takes the whole step;
    another (SuperLU's) is solved here between two calls of the sweep, which begins the step
    (``stop``) and takes the rest of it (``solved``). Neither compiles a kernel of its own to
    be called from Python (the exact variant's matrices and refinement with SuperLU's factor
    aside). The step's ``μ`` goes into ``MU[0]``; returns the record, for its design's
    share."""
    lu = step.factor
    M, T = system_read(stp, refine, w_old)
    if like is not None and lu.compiled:
        F = lu.arrays()
        if (F.pattern is None) == (like[1].pattern is None):
            K, F = solved_step(like, step.new, step.old, step.Dq, step.Dv, k, F)
            kadj.sweep(M, T, sc, stp.newton.csc, F, K, a, MU, k, k, refine, -1, -1, w_old)
            return K
    K, F = solved_step(like, step.new, step.old, step.Dq, step.Dv, k)
    kadj.sweep(M, T, sc, stp.newton.csc, F, K, a, MU, k, k, refine, -1, k, w_old)
    a.mu[:] = np.asarray(lu.solve_transposed(a.mu), dtype=float)
    if refine is not None:
        kadj.exact_matrices(a, stp.M, stp.T, sc, step.new, k)
        if refine > 0:
            for _ in range(refine):
                kadj.refinement_residual(a, stp.newton.csc)
                a.mu[:] += np.asarray(lu.solve_transposed(a.r), dtype=float)
            rr, bb = kadj.refinement_residual(a, stp.newton.csc)
            a.refined[k] = rr / max(bb, 1e-300)
    kadj.sweep(M, T, sc, stp.newton.csc, F, K, a, MU, k, k, refine, k, -1, w_old)
    return K


def _touched(sys0: System, ps, skip: np.ndarray | None, stp, like, refine) -> tuple:
    """The residual rows each variable's explicit part can write (``(RO (n_x + 1,), RI)``):
    found by evaluating it once at a random state with random time values and unit weights,
    where every row its parts write is nonzero; none for the variables set in ``skip``
    (their shares come from the data gradient). The evaluation is a probe in the shares' own
    kernel (``probe`` rows, :func:`~morphlab.kernels.adjoint._design_share`: one step at time
    index 0, on a record of that step), which takes the types of the run (``stp`` its
    stepper, ``like`` a record and factor arrays of it, ``refine`` the sweep's): the probe
    compiles nothing of its own."""
    from ..compile.system import time_table
    from ..kernels.types import Weights

    n_x = ps.PO.size - 1
    probed = np.arange(n_x) if skip is None else np.flatnonzero(~np.asarray(skip, bool))
    rows = [np.zeros(0, np.int64) for _ in range(n_x)]
    if not probed.size:  # every variable's share comes from the data gradient
        return _offsets(rows)
    rng = np.random.default_rng(12345)
    n_dof, n_con = sys0.n_dof, sys0.n_con
    x = Level(*(rng.standard_normal(k) + 1.0 for k in (n_dof, n_dof, n_dof, n_con)))
    T = time_table(sys0, np.zeros(1))

    def random(x):  # complex tables (the perturbed path's) with a random imaginary part too
        r = rng.standard_normal(x.shape) + 1.0
        if np.iscomplexobj(x):
            r = r + 1j * (rng.standard_normal(x.shape) + 1.0)
        return r.astype(x.dtype)

    def noise(times):  # random values at the one time index the probe reads (k = 0)
        if times is None:
            return None
        return type(times)(*(None if t is None else type(t)(*(random(x[:, :1]) for x in t))
                             for t in times))

    T, ps = noise(T), ps._replace(TL=noise(ps.TL), TN=noise(ps.TN))
    none = _data_gradient(sys0, ps, np.zeros(n_x, dtype=bool), 1)
    sh = _shares_state(sys0, ps, 1, (np.zeros(n_x + 1, np.int64), np.zeros(0, np.int64)),
                       (np.arange(probed.size + 1), probed, probed), none,
                       probe=probed.size)
    sc = stp.scheme_of()._replace(w_new=Weights(*([1.0] * 8)), has_old=False)
    D = np.zeros(sys0.nnz) if refine is None else None
    K, _ = solved_step(like, x, x, D, D, 0)
    M, T, K = _share_inputs(sh.ps, stp.M, T, K)
    kadj.shares(sh, M, T, sc, K, np.zeros((1, n_dof + n_con, 1)), 0, 0)
    for j, i in enumerate(probed):
        rows[i] = np.flatnonzero(sh.probe[j] != 0.0)
    return _offsets(rows)


def _offsets(rows: list) -> tuple:
    """``(RO (n + 1,), RI)``: the index lists ``rows`` in one array with offsets."""
    RO = np.zeros(len(rows) + 1, dtype=np.int64)
    RO[1:] = np.cumsum([r.size for r in rows])
    return RO, np.concatenate(rows + [np.zeros(0, np.int64)]).astype(np.int64)
