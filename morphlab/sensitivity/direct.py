"""Direct differentiation of a run (``method="direct"`` and ``"direct-fd"`` of
:func:`morphlab.sensitivities`; the method is described in :mod:`morphlab.sensitivity`).

Built once per run here: the perturbed designs' arrays stacked over the variables, the parts of
the model each variable changes, the time tables, the initial sensitivities and the histories
to keep (``store``); then one primal run whose step observer (:class:`_DirectPass`) keeps the
converged steps and their factorizations and solves their sensitivities in blocks, with the
primal's factorizations and a few compiled calls (:mod:`morphlab.kernels.direct`).
Afterwards each variable's complex history ``x + i h dx/dp`` is formed on demand for the
responses (:class:`_PerturbedResult`).
"""

from __future__ import annotations

import time as _time
from collections.abc import Mapping
from itertools import groupby

import numpy as np

from ..compile import System, compile_model
from ..compile.system import kernel_arrays, time_table
from ..errors import SensitivityError
from ..kernels.direct import (
    block_recursion,
    csc_residual,
    explicit_block,
    state_loads,
    update_sensitivities,
)
from ..kernels.system import DESIGN_FIELDS, DesignArrays
from ..results.result import Result
from ..solve.linalg import DenseLU, SparseLU, no_sparse_arrays
from ..solve.stepper import Settings
from ..solve.timeloop import StepInfo, integrate

CS_STEP = 1e-30
HISTORIES = ("q", "v", "a", "lam")
# Refine the direct solve against the exact converged matrix only when the last Newton
# correction (relative to the model size) exceeds this: below it, the lagged LU's relative
# error O(|dz|) is already under the 1e-8 accuracy the sensitivities are verified to.
REFINE_TOL = 1e-12


def _lazy_history(name: str) -> property:
    """A history of :class:`_PerturbedResult`, formed on first access."""

    def get(self):
        arr = self._histories.get(name)
        if arr is None:
            base, d, col = self._source
            if name not in d:
                raise SensitivityError(
                    f"the sensitivity history of {name!r} was not kept (kept: {sorted(d)}); "
                    f"run sensitivities(..., store='all') or store=(..., {name!r})")
            arr = getattr(base, name) + 1j * CS_STEP * d[name][col]
            self._histories[name] = arr
        return arr

    def set(self, value):
        if value is not None:
            self._histories[name] = value

    return property(get, set)


class _PerturbedResult(Result):
    """A complex Result of one design variable: histories ``x + i h dx/dp_col`` on the complex
    system. Each history is formed when a response first reads it (a response of the
    positions needs neither velocities, accelerations nor multipliers: with many variables
    the other complex copies cost more than the response)."""

    q = _lazy_history("q")
    v = _lazy_history("v")
    a = _lazy_history("a")
    lam = _lazy_history("lam")

    def __init__(self, base: Result, system: System, d: dict, col: int):
        self._histories: dict = {}
        self._source = (base, d, col)
        super().__init__(
            system=system, settings=base.settings, t=base.t, q=None, v=None, a=None, lam=None,
            newton_iterations=base.newton_iterations,
            constraint_violation=base.constraint_violation,
            velocity_violation=base.velocity_violation, status=base.status,
            message=base.message, scale=base.scale)


def _perturbed_result(base: Result, system: System, d: dict, col: int) -> Result:
    """A complex Result: histories ``x + i h dx/dp_col`` on the complex system ``system``
    (``d[name]`` of layout (n_x, n_t, width))."""
    return _PerturbedResult(base, system, d, col)


def check_same_layout(a: System, b: System, name: str) -> None:
    same = (a.n_dof == b.n_dof and a.n_con == b.n_con and a.nnz == b.nnz
            and np.array_equal(a.indices, b.indices) and np.array_equal(a.indptr, b.indptr))
    if not same:
        raise SensitivityError(
            f"changing design variable {name!r} changes the model's structure (DOFs, "
            "constraints or sparsity pattern); build(p) must keep the topology fixed")


# Column blocks for the multi-right-hand-side solve (None: all columns in one call). An
# earlier session measured SuperLU's solve ~15x slower with more than about a dozen columns
# (OpenBLAS threading on this 2-core machine, 3 ms instead of 0.2 ms at n_x = 15) and solved in
# blocks of 8; re-measured 2026-11-21 (SciPy 1.17, OpenBLAS 0.3.31), also with the second
# core busy, one call is faster at every width: 12 columns 30 vs 45 us, 50 columns at 60
# elements 153 vs 259 us. Set an int here if the slowdown shows up again.
SOLVE_BLOCK: int | None = None


def _solve(lu, b):
    """``lu.solve`` for many right-hand sides (in column blocks of SOLVE_BLOCK if set)."""
    if SOLVE_BLOCK is None or b.ndim == 1 or b.shape[1] <= SOLVE_BLOCK:
        return lu.solve(b)
    return np.concatenate([lu.solve(np.ascontiguousarray(b[:, k:k + SOLVE_BLOCK]))
                           for k in range(0, b.shape[1], SOLVE_BLOCK)], axis=1)


def _changed(a, b, axis_keep: int = 0) -> np.ndarray:
    """Per entry along axis ``axis_keep``: does any value of ``a`` differ from ``b``?"""
    d = np.asarray(a) != np.asarray(b)
    if d.ndim == 0:
        return d
    d = np.moveaxis(d, axis_keep, 0)
    return d.reshape(d.shape[0], -1).any(axis=1) if d.size else np.zeros(d.shape[0], bool)


def _variable_parts(sys0: System, S0: tuple, Si: tuple, tab0: tuple, tabi: tuple) -> tuple:
    """The bodies, elements, flexible coordinates, constraint rows, loads and torques whose
    data differ between the nominal arrays ``S0`` / time table ``tab0`` and a perturbed
    design's ``Si`` / ``tabi``: the parts its explicit pseudo-load must evaluate
    (:mod:`morphlab.kernels.direct`). A changed element brings its body and its coordinates."""
    n_body, n_elem = len(sys0.body_ref), len(sys0.elem_body)
    def changed(name):
        return _changed(getattr(Si, name), getattr(S0, name))

    damp = changed("body_damp")
    elem = (changed("elem_M") | changed("elem_St") | changed("elem_K")
            | damp[sys0.elem_body]) if n_elem else np.zeros(0, bool)
    flex = changed("flex_IS") | changed("flex_I0S") | changed("flex_I0IS")
    fdof = sys0.elem_fdof[elem]
    flex[fdof[fdof >= 0]] = True
    body = changed("body_scal") | damp
    if np.any(Si.gravity != S0.gravity):  # gravity acts on every body and every coordinate
        body[:] = True
        flex[:] = True
    for b in range(n_body):
        lo, hi = sys0.flex_off[b], sys0.flex_off[b + 1]
        body[b] |= bool(flex[lo:hi].any())
        if damp[b]:
            flex[lo:hi] = True
    body[sys0.elem_body[elem]] = True
    # time tables (n_t, ...): a row changes if it changes at any time
    rows = (changed("con_u0") | _changed(tabi.C, tab0.C, 1) | _changed(tabi.CD, tab0.CD, 1)
            | _changed(tabi.CDD, tab0.CDD, 1))
    loads = changed("load_u0") | _changed(tabi.F, tab0.F, 1)
    torques = _changed(tabi.T, tab0.T, 1)
    return tuple(np.flatnonzero(m).astype(np.int64)
                 for m in (body, elem, flex, rows, loads, torques))


def _pack_parts(parts: list) -> tuple:
    """Per-variable index lists as ``(offsets, indices)`` pairs (CSR over the variables)."""
    out = []
    for kind in range(6):
        lists = [p[kind] for p in parts]
        off = np.zeros(len(lists) + 1, dtype=np.int64)
        off[1:] = np.cumsum([len(x) for x in lists])
        idx = np.concatenate(lists).astype(np.int64) if lists else np.zeros(0, np.int64)
        out += [off, idx]
    return tuple(out)


class _ProbeResult(Result):
    """A two-step Result of the nominal model (initial state, zero rates) that records which
    histories are read: what a direct run must keep for the responses."""

    def __init__(self, system: System, settings: Settings):
        self.read: set = set()
        n_dof, n_con = system.n_dof, system.n_con
        q = np.repeat(np.real(system.q0)[None, :], 2, axis=0)
        zeros = np.zeros((2, n_dof))
        self._h = {"q": q, "v": zeros, "a": zeros, "lam": np.zeros((2, n_con))}
        super().__init__(system=system, settings=settings,
                         t=settings.t_start + settings.h * np.arange(2.0), q=None, v=None,
                         a=None, lam=None, newton_iterations=np.ones(2, dtype=np.int64),
                         constraint_violation=np.zeros(2), velocity_violation=np.zeros(2))

    def _get(self, name):
        self.read.add(name)
        return self._h[name]

    q = property(lambda self: self._get("q"), lambda self, value: None)
    v = property(lambda self: self._get("v"), lambda self, value: None)
    a = property(lambda self: self._get("a"), lambda self, value: None)
    lam = property(lambda self: self._get("lam"), lambda self, value: None)


def histories_to_store(store, responses: Mapping, system: System, settings: Settings) -> tuple:
    """The sensitivity histories a direct run keeps in full (see ``store`` of
    :func:`sensitivities`)."""
    if store == "all":
        return HISTORIES
    if store != "auto":
        return tuple(h for h in HISTORIES if h in store)
    probe = _ProbeResult(system, settings)
    try:
        with np.errstate(all="ignore"):
            for fn in responses.values():
                fn(probe)
    except Exception:  # a response that cannot run on the probe: keep everything
        return HISTORIES
    return tuple(h for h in HISTORIES if h in probe.read)


def _pseudo_load_data(sys0, settings, names, perturbed_cs, build, p0, steps, method):
    """What the pseudo-load kernels read, built once per run: the perturbed designs' arrays
    stacked over the variables (``P``), the parts each changes (``parts``), the time tables
    (``TAB`` per design, ``tab0`` nominal), the nominal arrays in the perturbation's dtype
    (``S_nom``), the perturbations (``pert``) and the initial sensitivities ``dq_0, dv_0``."""
    n_x = len(names)
    times = settings.t_start + settings.h * np.arange(settings.n_steps + 1)
    if method == "direct":
        psys = perturbed_cs
        pert = np.full(n_x, 1j * CS_STEP)
    else:
        psys = []
        for v in names:
            pv = dict(p0)
            pv[v] = p0[v] + steps[v]
            sp_ = compile_model(build(pv), dtype=np.float64, like=sys0)
            check_same_layout(sys0, sp_, v)
            psys.append(sp_)
        pert = np.array([steps[v] for v in names])
    dt_ = np.complex128 if method == "direct" else np.float64
    S_nom = kernel_arrays(sys0, dt_)  # integer tables shared with the primal's
    S_all = [kernel_arrays(s, dt_) for s in psys]
    P = DesignArrays(*(np.ascontiguousarray(np.stack([getattr(Sk, k) for Sk in S_all]))
                       for k in DESIGN_FIELDS))
    shared: dict = {}
    tab0 = time_table(sys0, times, dt_, cache=shared)
    tables = [time_table(s, times, dt_, cache=shared) for s in psys]
    parts = _pack_parts([_variable_parts(sys0, S_nom, Sk, tab0, tb)
                         for Sk, tb in zip(S_all, tables)])
    TAB = tuple(np.ascontiguousarray(np.stack([tb[k] for tb in tables], axis=1))
                for k in range(5))  # (n_t, n_x, ...)
    if method == "direct":
        dq0 = np.stack([np.imag(s.q0) / CS_STEP for s in psys], axis=1)
        dv0 = np.stack([np.imag(s.v0) / CS_STEP for s in psys], axis=1)
    else:
        dq0 = np.stack([(s.q0 - sys0.q0) / e for s, e in zip(psys, pert)], axis=1)
        dv0 = np.stack([(s.v0 - sys0.v0) / e for s, e in zip(psys, pert)], axis=1)
    return dict(S_nom=S_nom, P=P, parts=parts, TAB=TAB, tab0=tab0, pert=pert, dtype=dt_,
                dq0=dq0, dv0=dv0)


# A direct run keeps the converged states and factorizations of the steps whose sensitivity
# solve is pending, up to about this many bytes, and then solves them as one block: the
# partial derivatives of the whole block in one compiled call, the recursion afterwards (for a
# dense LU also in one call). The morphing model's 300 steps fit in one block; a 3000-element
# skin keeps a few dozen. Measured on the 8-element pendulum of the Exudyn comparison (1000
# steps, two variables): 97 ms per direct run against 127 ms with one step per block.
BLOCK_BYTES = 64 * 2**20


def _lu_bytes(lu) -> int:
    """Approximate memory of a factorization from :mod:`morphlab.factorization`: its arrays
    (``nbytes``: a sparse LU shares its patterns with every factor of its row order; SuperLU's
    is an estimate) and ~0.5 kB for the Python objects and array headers."""
    return lu.nbytes + 500


def _factor_kind(lu):
    """What a block of factors can be solved with in one compiled call: ``"dense"``, the row
    order (:class:`morphlab.factorization._Pivots`) all sparse factors of a run share, or None
    (SuperLU's own factors: solved from Python)."""
    if isinstance(lu, DenseLU):
        return "dense"
    if isinstance(lu, SparseLU):
        return lu.pivots
    return None


def _stacked_factors(lus, kind):
    """``(LU, piv, Lx, Ux, Ud, pattern)`` of :func:`block_recursion` for factors of one kind:
    the stacks of that kind, and K empty factors of the other."""
    K = len(lus)
    if kind == "dense":
        dt = lus[0].LU.dtype
        empty = np.zeros((K, 0), dt)
        return (np.stack([f.LU for f in lus]), np.stack([f.piv for f in lus]), empty, empty,
                empty, no_sparse_arrays(dt)[1])
    dt = lus[0].Lx.dtype
    p = kind
    return (np.zeros((K, 0, 0), dt), np.zeros((K, 0), dtype=np.int64),
            np.stack([f.Lx for f in lus]), np.stack([f.Ux for f in lus]),
            np.stack([f.Ud for f in lus]),
            p.solve_arrays)


class _DirectPass:
    """The step observer of a direct run (see :func:`direct_run`).

    The partial derivatives ``dR/dp_i`` depend only on the converged primal states, the
    recursion ``J dz_{n+1} = -D_i R`` on the previous step's sensitivities. So each step's
    state and factorization are kept until a block is full (:data:`BLOCK_BYTES`), the
    coefficients change (the initial solve) or the run ends; then the block's partial
    derivatives are formed in one compiled call (:func:`explicit_block`) and the recursion
    runs over its steps: state part (:func:`state_loads`), one solve for all columns,
    refinement, Newmark update. The results do not depend on the block size.
    """

    def __init__(self, sys0, settings, data, hist, refine, block_bytes):
        self.sys0 = sys0
        self.n_steps = settings.n_steps
        self.data = data
        self.hist = hist
        self.refine = refine
        self.block_bytes = block_bytes
        n_x = data["dq0"].shape[1]
        n, nnz = sys0.n, sys0.nnz
        self.work = np.zeros((2, n), dtype=data["dtype"])
        self.mats = np.zeros((6, nnz))
        self.zmat = np.zeros(nnz, dtype=np.complex128)
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
        last = info.newton_history[-1][1] if info.newton_history else 0.0
        self.pending.append((info.n, info.state, info.lu, last))
        self.pending_bytes += _lu_bytes(info.lu) + 8 * self.sys0.n * (self.r.shape[1] + 4)
        if self.pending_bytes >= self.block_bytes or info.n == self.n_steps:
            self.flush()
        self.stats["sensitivity_time"] += _time.perf_counter() - t0

    def flush(self) -> None:
        """Solve the sensitivities of the pending steps."""
        sys0, d, info, hist = self.sys0, self.data, self.info, self.hist
        stp, coef = info.stepper, info.coef
        pc, upd, w_old, w_new = coef.arrays
        has_old = coef.old is not None
        steps = self.pending
        K = len(steps)
        k_new = np.array([s[0] for s in steps], dtype=np.int64)
        k_old = np.maximum(k_new - 1, 0)
        Q, V, A, L = (np.stack([self.first_old[c]] + [s[1][c + 1] for s in steps])
                      for c in range(4))  # State = (t, q, v, a, lam, g)
        E = np.zeros((K, sys0.n, self.r.shape[1]))
        explicit_block(d["S_nom"], d["P"], d["parts"], Q, V, A, L, w_new, has_old, w_old,
                       stp.scale, stp.b0, stp.b1, d["TAB"], d["tab0"], k_old, k_new,
                       sys0.n_dof, d["pert"], self.work, E)
        F = info.table[3]
        # The LU is one Newton iterate behind (taken at z_k, z* = z_k + dz): its relative error
        # is O(|dz|). Where the last position correction exceeds REFINE_TOL of the model size,
        # the solve is refined against the exact matrix J at z* (from state_loads).
        refine = np.array([self.refine > 0 and k > 0 and last > REFINE_TOL
                           for k, _st, _lu, last in steps])
        refined = np.full(K, np.nan)
        coefs = (stp.scale, stp.b0, stp.b1, coef.bh2, coef.gh, sys0.indices, sys0.indptr,
                 sys0.n_dof)
        scratch = (self.r, np.empty_like(self.r), np.empty_like(self.r))
        j0 = 0
        for kind, run in groupby(steps, key=lambda s: _factor_kind(s[2])):
            j1 = j0 + len(list(run))
            sl, sl1 = slice(j0, j1), slice(j0, j1 + 1)
            if kind is not None:  # these steps' recursion in one compiled call
                lus = [s[2] for s in steps[sl]]
                arrays = _stacked_factors(lus, kind)
                block_recursion(stp.S, Q[sl1], V[sl1], A[sl1], L[sl1], w_new, has_old, w_old,
                                F, k_old[sl], k_new[sl], *coefs, *hist, pc, upd, self.mats,
                                self.zmat, self.J, E[sl], *arrays, refine[sl], self.refine,
                                *scratch, refined[sl])
            else:  # SuperLU's factors: the same sequence, the solves from Python
                for j in range(j0, j1):
                    k, lu, rhs = steps[j][0], steps[j][2], E[j]
                    state_loads(stp.S, Q[j + 1], V[j + 1], A[j + 1], L[j + 1], w_new, has_old,
                                Q[j], V[j], A[j], L[j], w_old, F, k, *coefs, *hist, k_old[j],
                                pc, self.mats, self.zmat, self.J, rhs)
                    x = _solve(lu, rhs)
                    if refine[j]:
                        for _ in range(self.refine):
                            csc_residual(self.J, sys0.indices, sys0.indptr, x, rhs, self.r)
                            x = x + _solve(lu, self.r)
                        rr, bb = csc_residual(self.J, sys0.indices, sys0.indptr, x, rhs, self.r)
                        refined[j] = rr / max(bb, 1e-300)
                    update_sensitivities(*hist, k, x, stp.scale, sys0.n_dof, pc, upd)
            j0 = j1
        self.stats["refined_steps"] += int(refine.sum())
        self.stats["refinement_residual"] += refined[refine].tolist()
        self.pending = []
        self.pending_bytes = 0
        self.stats["blocks"] += 1


def direct_run(sys0, settings, names, perturbed_cs, build, p0, steps, method, refine, progress,
               kept=HISTORIES):
    """Primal run with the direct-differentiation observer :class:`_DirectPass`: per block of
    steps one compiled call for the partial derivatives, then per step the state part of the
    pseudo-loads and the exact converged matrix, one multi-right-hand-side solve, an optional
    refinement sweep and the Newmark update (dense LU: the whole block in one compiled call;
    :mod:`morphlab.kernels.direct`)."""
    n_x = len(names)
    n_steps = settings.n_steps
    n_dof, n_con = sys0.n_dof, sys0.n_con
    data = _pseudo_load_data(sys0, settings, names, perturbed_cs, build, p0, steps, method)

    # histories kept in full: those in ``kept``; the others (and the algorithmic
    # acceleration) hold the last two levels, all the time stepping reads
    # layout (n_x, levels, width): one variable's history is contiguous
    def history(name, width):
        return np.zeros((n_x, (n_steps + 1) if name in kept else 2, width))

    full = {"q": history("q", n_dof), "v": history("v", n_dof), "a": history("a", n_dof),
            "lam": history("lam", n_con)}
    full["q"][:, 0], full["v"][:, 0] = data["dq0"].T, data["dv0"].T
    dg = np.zeros((n_x, 2, n_dof))
    by_variable = {k: full[k] for k in HISTORIES if k in kept}
    hist = (full["q"], full["v"], full["a"], dg, full["lam"])
    observer = _DirectPass(sys0, settings, data, hist, refine, BLOCK_BYTES)

    t0 = _time.perf_counter()
    res0 = integrate(sys0, settings, observer=observer, progress=progress)
    total = _time.perf_counter() - t0
    stats = observer.stats
    stats["n_factorizations"] = res0.n_factorizations
    perturbed = [_perturbed_result(res0, s, by_variable, i) for i, s in enumerate(perturbed_cs)]
    timing = {"primal": total - stats["sensitivity_time"],
              "sensitivity": stats["sensitivity_time"], "run": total}
    state = {k: np.moveaxis(v, 0, -1) for k, v in by_variable.items()}  # (n_t, width, n_x)
    return res0, perturbed, state, timing, stats
