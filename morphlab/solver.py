"""Generalized-alpha time integration with Newton–Raphson on the sparse saddle-point system.

Unknowns of a step are ``z = (a, lam/scale)`` with ``a = q''_{n+1}``; positions and velocities
follow from the Newmark update (paper eq. 10–11)::

    q_{n+1} = q_n + h q'_n + (1/2 - beta) h² a_n + beta h² a
    q'_{n+1} = q'_n + (1 - gamma) h a_n + gamma h a

The residual (paper eq. 25–26) is the weighted sum of one state's terms at ``n+1`` and at ``n``::

    R = E(s_{n+1}; 1-alpha_m, 1-alpha_f, 1-w_m, 1-w_f) + E(s_n; alpha_m, alpha_f, w_m, w_f)

with ``E`` the kernel :func:`morphlab.kernels.assemble.add_residual`. The paper weights the
constraint rows with ``(w_m, w_f) = (alpha_m, alpha_f)`` (``constraint_form="paper"``); the
alternative ``"endpoint"`` enforces the acceleration constraint at ``t_{n+1}`` exactly
(``w_m = w_f = 0``). The Newton matrix ``dR/dz`` is exact (eq. 30–33 with every derivative
term), so Newton converges quadratically and the direct sensitivities are exact.

The acceleration-level (index-1) constraints drift at position level. A Baumgarte-type term,
``F_c -> F_c - b1 Phi' - b0 Phi`` with ``b1 = 2 xi omega`` and ``b0 = omega²``, is part of the
residual (and so of its derivatives). ``omega = stabilization / h``; 0 switches it off.
"""

from __future__ import annotations

import numbers
import time as _time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np
import scipy.sparse as sp
from scipy.sparse.linalg import splu

from .compile import System, compile_model
from .errors import ConvergenceError, ModelError, NonFiniteError, SingularMatrixError
from .integrator import (
    INITIAL,
    SCHEMES,
    GeneralizedAlpha,
    StepCoefficients,
    _is_real,
    newmark_predict,
    newmark_update,
    step_coefficients,
)
from .kernels.assemble import add_residual, fill_matrix
from .kernels.joints import constraint_violation_history
from .model import Model


class State(NamedTuple):
    """Solution at one time: ``t``, ``q`` (n_dof), ``v`` = q', ``a`` = q'' and ``lam``
    (n_con); ``g`` is the algorithmic acceleration of the generalized-alpha recurrence (equal
    to ``a`` for the paper's form)."""

    t: float
    q: np.ndarray
    v: np.ndarray
    a: np.ndarray
    lam: np.ndarray
    g: np.ndarray | None = None


@dataclass(frozen=True)
class Settings:
    """Solver settings (all keyword arguments of :func:`simulate`)."""

    t_end: float
    dt: float
    rho_inf: float = 0.8
    tol: float = 1e-10
    max_iter: int = 12
    stabilization: float = 0.5
    stabilization_damping: float = 1.0
    constraint_form: str = "paper"
    t_start: float = 0.0
    scheme: str = "arnold-bruls"
    newton: str = "full"

    def validate(self) -> None:
        """Raise :class:`ModelError` naming the first invalid setting."""
        for name in ("t_end", "dt"):
            v = getattr(self, name)
            if not _is_real(v) or not np.isfinite(v) or not v > 0:
                raise ModelError(f"{name} must be a finite positive number, got {v!r}")
        if self.dt > self.t_end - self.t_start:
            raise ModelError(f"dt={self.dt} is larger than the simulated span "
                             f"{self.t_end - self.t_start}")
        if not _is_real(self.rho_inf):
            raise ModelError(f"rho_inf must be a number in [0, 1], got {self.rho_inf!r}")
        GeneralizedAlpha(float(self.rho_inf))
        if not (_is_real(self.tol) and 0 < self.tol < 1):
            raise ModelError(f"tol must be a number in (0, 1), got {self.tol!r}")
        if not (isinstance(self.max_iter, numbers.Integral)
                and not isinstance(self.max_iter, (bool, np.bool_)) and self.max_iter >= 1):
            raise ModelError(f"max_iter must be an integer >= 1, got {self.max_iter!r}")
        for name in ("stabilization", "stabilization_damping"):
            v = getattr(self, name)
            if not (_is_real(v) and np.isfinite(v) and v >= 0):
                raise ModelError(f"{name} must be a finite number >= 0, got {v!r}")
        if self.newton not in ("full", "modified"):
            raise ModelError(f"newton must be 'full' or 'modified', got {self.newton!r}")
        if self.scheme not in SCHEMES:
            raise ModelError(f"scheme must be one of {', '.join(map(repr, SCHEMES))}, got "
                             f"{self.scheme!r}")
        if self.constraint_form not in ("paper", "endpoint"):
            raise ModelError(f"constraint_form must be 'paper' or 'endpoint', got "
                             f"{self.constraint_form!r}")

    @property
    def n_steps(self) -> int:
        """Number of steps: ``ceil((t_end - t_start)/dt)`` (the step is then shortened to fit)."""
        return int(np.ceil((self.t_end - self.t_start) / self.dt - 1e-9))

    @property
    def h(self) -> float:
        """The step actually used, ``(t_end - t_start) / n_steps``."""
        return (self.t_end - self.t_start) / self.n_steps


def kernel_arrays(system: System, dtype=None) -> tuple:
    """The tuple ``S`` of system arrays for :mod:`morphlab.kernels.assemble` (cast to dtype)."""
    dt = np.dtype(dtype) if dtype is not None else system.dtype

    def f(x):
        return np.ascontiguousarray(x, dtype=dt)

    s = system
    return (f(s.gravity), s.body_ref, f(s.body_scal), f(s.body_damp), s.flex_off, s.flex_dof,
            f(s.flex_IS), f(s.flex_I0S), f(s.flex_I0IS), s.elem_body, s.elem_fdof, f(s.elem_M),
            f(s.elem_St), f(s.elem_K), s.con_kind, s.con_dofs, f(s.con_u0), s.load_dofs,
            f(s.load_u0), s.torque_dofs, s.border_off, s.border_map, s.elem_map, s.con_map_row,
            s.con_map_col, s.con_map_H, s.load_map)


# SuperLU settings for the saddle-point matrix. The matrix is structurally nearly symmetric
# (mass/stiffness blocks plus J and J^T), so a minimum-degree ordering of A^T + A in
# SymmetricMode with threshold pivoting (prefer the diagonal unless it is < 0.1 of the column
# maximum) keeps the sparsity; the default COLAMD with partial pivoting filled the LU almost
# densely on long skins. Measured on the morphing model (n = 123 / 333 / 933 unknowns):
# 0.20 / 0.36 / 1.3 ms per factorization against 0.23 / 1.2 / 9.2 ms with COLAMD (also with
# its column order computed once and reused); L+U nonzeros 18k against 410k at n = 933.
# The order is computed once per run and reused (Stepper._lu).
SPLU_OPTIONS = dict(permc_spec="MMD_AT_PLUS_A", diag_pivot_thresh=0.1,
                    options=dict(SymmetricMode=True))


class Stepper:
    """Residual, Newton matrix and Newton iteration of one compiled system.

    Stateless with respect to the time history: every method takes the states it needs. The
    sensitivity strategies call :meth:`residual` with perturbed inputs (complex step or finite
    differences): one residual, one set of kernels.
    """

    def __init__(self, system: System, settings: Settings, scale: float | None = None):
        self.system = system
        self.settings = settings
        self.method = GeneralizedAlpha(settings.rho_inf)
        self.S = kernel_arrays(system)
        self.dtype = system.dtype
        self.n_dof = system.n_dof
        self.n = system.n
        h = settings.h
        om = settings.stabilization / h if settings.stabilization > 0 else 0.0
        self.b1 = 2.0 * settings.stabilization_damping * om
        self.b0 = om * om
        self.step_coef = step_coefficients(settings.scheme, self.method, h,
                                           settings.constraint_form)
        self.init_coef = INITIAL
        self.data = np.zeros(system.nnz, dtype=self.dtype)
        self._A = None
        self.scale = scale if scale is not None else self._choose_scale()
        self.n_factorizations = 0
        self._kept = None  # factorization kept by modified Newton
        self._perm = None
        self._B = None
        self.polish = 0  # extra Newton updates after convergence (complex-step reference runs)

    # ---- building blocks
    def _choose_scale(self) -> float:
        """Scale of constraint rows / multiplier columns: the median magnitude of the diagonal
        of the equation block of the step matrix at the initial state (real part, fixed for the
        run and every sensitivity of it)."""
        s = self.system
        z0 = np.zeros(self.n, dtype=self.dtype)
        self._fill(z0, s.q0, s.v0, 0.0, self.step_coef, scale=1.0)
        A = self.matrix()
        d = np.abs(np.real(A.diagonal()[: self.n_dof]))
        d = d[d > 0]
        return float(np.median(d)) if d.size else 1.0

    def predict(self, st: State, coef: StepCoefficients):
        """Newmark predictors ``(q_hat, v_hat)`` with ``q = q_hat + bh2 a``."""
        return newmark_predict(coef, st.q, st.v, st.a, st.g)

    def history(self, st: State, coef: StepCoefficients, ta=None):
        """The old-level share ``E(s_n; alpha...)`` of the residual (constant in a step; zero
        for schemes without one); ``ta``: the time arrays at ``st.t`` when already known."""
        R = np.zeros(self.n, dtype=self.dtype)
        if coef.old is None:
            return R
        c, cd, cdd, F, T = ta if ta is not None else self.time_arrays(st.t)
        wm, wl, wf, wcm, wcf = coef.old
        add_residual(self.S, st.q, st.v, st.a, st.lam, wm, wl, wf, wcm, wcf, self.scale,
                     self.b0, self.b1, c, cd, cdd, F, T, self.n_dof, R)
        return R

    def time_arrays(self, t):
        """The system's time-dependent arrays at ``t`` in the run's dtype."""
        return tuple(np.ascontiguousarray(x, dtype=self.dtype)
                     for x in self.system.time_arrays(t))

    def residual(self, z, qh, vh, t1, coef: StepCoefficients, R_hist, time_arrays=None):
        """Residual of the step at ``z = (a, lam/scale)`` (n,)."""
        dt = np.result_type(z.dtype, qh.dtype, R_hist.dtype)
        a = z[: self.n_dof]
        lam = z[self.n_dof:] * self.scale
        q = qh + coef.bh2 * a
        v = vh + coef.gh * a
        c, cd, cdd, F, T = time_arrays if time_arrays is not None else self.time_arrays(t1)
        R = R_hist.astype(dt, copy=True)
        wm, wl, wf, wcm, wcf = coef.new
        # copy=False: no copies in the Newton loop when the dtypes already agree
        add_residual(self.S, q.astype(dt, copy=False), v.astype(dt, copy=False),
                     np.ascontiguousarray(a, dtype=dt), lam.astype(dt, copy=False), wm, wl, wf,
                     wcm, wcf, self.scale, self.b0, self.b1, c, cd, cdd, F, T, self.n_dof, R)
        return R

    def _fill(self, z, qh, vh, t1, coef, scale=None, F=None):
        a = z[: self.n_dof]
        sc = self.scale if scale is None else scale
        lam = z[self.n_dof:] * sc
        q = qh + coef.bh2 * a
        v = vh + coef.gh * a
        if F is None:
            F = np.ascontiguousarray(self.system.time_arrays(t1)[3], dtype=self.dtype)
        wm, wl, wf, wcm, wcf = coef.new
        fill_matrix(self.S, q, v, a, lam, wm, wl, wf, wcm, wcf, coef.bh2, coef.gh, sc, self.b0,
                    self.b1, F, self.data)

    def matrix(self) -> sp.csc_matrix:
        """The Newton matrix last filled, as a CSC matrix sharing ``data`` (built once: the
        pattern is fixed, and constructing a SciPy matrix costs ~70 µs)."""
        if self._A is None or self._A.data is not self.data:
            self._A = sp.csc_matrix((self.data, self.system.indices, self.system.indptr),
                                    shape=(self.n, self.n))
        return self._A

    def _lu(self):
        """Factor the filled matrix (SuperLU, see :data:`SPLU_OPTIONS`).

        The first factorization computes the fill-reducing order ``q`` (minimum degree on
        A^T + A). The pattern is fixed, so later matrices are permuted symmetrically,
        ``B = A[q][:, q]``, by a precomputed gather of the CSC data and factored with
        ``permc_spec="NATURAL"``: same fill, without recomputing the ordering (measured 9.3 ms
        against 61 ms per factorization at 9033 unknowns, 0.9 against 1.9 ms at 933)."""
        if self._perm is None:
            lu = splu(self.matrix(), **SPLU_OPTIONS)
            q = np.argsort(lu.perm_c)  # position j of the factored matrix holds column q[j]
            s = self.system
            tag = sp.csc_matrix((np.arange(1, s.nnz + 1, dtype=np.float64), s.indices,
                                 s.indptr), shape=(self.n, self.n))
            B = tag[q][:, q].tocsc()
            B.sort_indices()
            gather = (B.data - 1).astype(np.int64)
            self._perm = (q, gather)
            self._B = sp.csc_matrix((self.data[gather], B.indices, B.indptr),
                                    shape=(self.n, self.n))
            return _PermutedLU(lu, None)
        q, gather = self._perm
        np.take(self.data, gather, out=self._B.data)
        return _PermutedLU(splu(self._B, permc_spec="NATURAL",
                                diag_pivot_thresh=SPLU_OPTIONS["diag_pivot_thresh"],
                                options=SPLU_OPTIONS["options"]), q)

    def factor(self, z, qh, vh, t1, coef, F=None):
        """Fill and factor the exact Newton matrix at ``z``."""
        self._fill(z, qh, vh, t1, coef, F=F)
        try:
            lu = self._lu()
        except RuntimeError as exc:
            raise SingularMatrixError(
                f"singular saddle-point matrix at t={t1:.6g}: {exc}. Look for redundant joints, "
                "a body without mass in its free directions, or a mechanism locked in a "
                "singular position",
                time=t1,
            ) from None
        self.n_factorizations += 1
        return lu

    def non_finite(self, x, k=8) -> list[str]:
        """Names of the first ``k`` equations/unknowns with a NaN or Inf entry."""
        names = self.system.dof_names + [f"constraint {c}" for c in self.system.con_names]
        return [names[i] for i in np.flatnonzero(~np.isfinite(x))[:k]]

    def dominant(self, R, k=3) -> list[str]:
        """Names of the ``k`` equations with the largest residual entries."""
        names = self.system.dof_names + [f"constraint {c}" for c in self.system.con_names]
        idx = np.argsort(-np.abs(R))[:k]
        return [f"{names[i]} ({abs(R[i]):.3g})" for i in idx]

    def newton(self, z, qh, vh, t1, coef, R_hist, step, ta=None):
        """Newton–Raphson from ``z``. Returns ``(z, lu, n_iter, history)``; ``lu`` is the last
        factorization (taken at the iterate before the final correction)."""
        s = self.settings
        L = self.system.length_scale
        hist = []
        lu = None
        if ta is None:
            ta = self.time_arrays(t1)
        F = ta[3]
        if s.newton == "modified" and coef is self.step_coef:
            return self._modified_newton(z, qh, vh, t1, coef, R_hist, step, ta)
        for it in range(1, s.max_iter + 1):
            R = self._finite_residual(z, qh, vh, t1, coef, R_hist, ta, step, it)
            try:
                lu = self.factor(z, qh, vh, t1, coef, F=F)
            except SingularMatrixError as err:
                err.step = step
                err.residual = float(np.linalg.norm(R))
                err.dominant = self.dominant(R)
                raise
            dz = lu.solve(-R)
            if not np.all(np.isfinite(dz)):
                bad = self.non_finite(dz)
                raise NonFiniteError(
                    f"non-finite Newton correction at t={t1:.6g} (step {step}) in "
                    f"{', '.join(bad)}", time=t1, step=step,
                    residual=float(np.linalg.norm(R)), dominant=bad)
            z = z + dz
            if coef.h == 0.0:
                # linear in z (consistent initial accelerations): one solve is exact
                err = 0.0
            else:
                err = coef.bh2 * float(np.max(np.abs(dz[: self.n_dof]))) / L
            hist.append((float(np.linalg.norm(R)), err))
            if err <= s.tol:
                # A complex-step run's imaginary part (the derivative) converges one Newton
                # iteration behind the real part: polish removes that lag.
                for _ in range(self.polish):
                    R = self.residual(z, qh, vh, t1, coef, R_hist, time_arrays=ta)
                    lu = self.factor(z, qh, vh, t1, coef, F=F)
                    z = z + lu.solve(-R)
                return z, lu, it, hist
        R = self.residual(z, qh, vh, t1, coef, R_hist, time_arrays=ta)
        raise ConvergenceError(
            f"Newton did not converge at t={t1:.6g} (step {step}) in {s.max_iter} iterations: "
            f"position correction {err:.3g} of the model size (tol {s.tol:.1g}), residual norm "
            f"{np.linalg.norm(R):.3g}; dominant equations: {', '.join(self.dominant(R))}",
            time=t1, step=step, residual=float(np.linalg.norm(R)), dominant=self.dominant(R))

    def _finite_residual(self, z, qh, vh, t1, coef, R_hist, ta, step, it):
        """The step residual; a NaN or Inf raises :class:`NonFiniteError` naming where."""
        R = self.residual(z, qh, vh, t1, coef, R_hist, time_arrays=ta)
        if not np.all(np.isfinite(R)):
            bad = self.non_finite(R)
            raise NonFiniteError(
                f"non-finite residual at t={t1:.6g} (step {step}, iteration {it}) in "
                f"{', '.join(bad)}", time=t1, step=step, residual=float("nan"), dominant=bad)
        return R

    def _modified_newton(self, z, qh, vh, t1, coef, R_hist, step, ta):
        """Newton with the factorization kept over iterations and steps (``newton="modified"``,
        primal runs only): refactor when the contraction rate of the corrections exceeds 0.3
        or they grow. Converged when the estimated remaining error ``err theta/(1 - theta)``
        is below ``tol`` (first iteration with a kept matrix: ``err <= tol/100``), the usual
        test of simplified Newton methods (Hairer & Wanner, Solving ODEs II, §IV.8)."""
        s = self.settings
        L = self.system.length_scale
        hist = []
        err_prev = None
        for it in range(1, s.max_iter + 1):
            R = self._finite_residual(z, qh, vh, t1, coef, R_hist, ta, step, it)
            fresh = self._kept is None
            if fresh:
                try:
                    self._kept = self.factor(z, qh, vh, t1, coef, F=ta[3])
                except SingularMatrixError as err:
                    err.step, err.residual = step, float(np.linalg.norm(R))
                    err.dominant = self.dominant(R)
                    raise
            dz = self._kept.solve(-R)
            err = coef.bh2 * float(np.max(np.abs(dz[: self.n_dof]))) / L
            hist.append((float(np.linalg.norm(R)), err))
            if not np.isfinite(err):
                self._kept = None
                continue
            theta = err / err_prev if err_prev else None
            if theta is not None and theta >= 1.0 and not fresh:
                self._kept = None  # diverging with an old matrix: refactor and retry
                err_prev = None
                continue
            z = z + dz
            if theta is None:
                done = err <= (s.tol if fresh else 1e-2 * s.tol)
            else:
                done = err * theta / max(1.0 - theta, 1e-12) <= s.tol
            if done:
                return z, self._kept, it, hist
            if theta is not None and theta > 0.3:
                self._kept = None
            err_prev = err
        R = self.residual(z, qh, vh, t1, coef, R_hist, time_arrays=ta)
        raise ConvergenceError(
            f"modified Newton did not converge at t={t1:.6g} (step {step}) in {s.max_iter} "
            f"iterations (residual norm {np.linalg.norm(R):.3g}); dominant equations: "
            f"{', '.join(self.dominant(R))}", time=t1, step=step,
            residual=float(np.linalg.norm(R)), dominant=self.dominant(R))

    # ---- the two kinds of solve
    def substep_coefficients(self, h: float) -> StepCoefficients:
        """Coefficients of a step of length ``h`` (same method and weights)."""
        s = self.settings
        return step_coefficients(s.scheme, self.method, h, s.constraint_form)

    def advance(self, st: State, t1: float, step: int, ta_old, ta_new, max_halvings: int,
                reductions: list):
        """:meth:`step`, retried on ``[st.t, t1]`` with 2, 4, ... equal sub-steps (up to
        ``2**max_halvings``) when Newton fails; each success with sub-steps is recorded in
        ``reductions`` as ``(t1, n_substeps)``. Returns the same tuple as :meth:`step`."""
        try:
            return self.step(st, t1, step, ta_old, ta_new)
        except (ConvergenceError, NonFiniteError):
            if max_halvings <= 0:
                raise
        t0 = st.t
        for level in range(1, max_halvings + 1):
            m = 2**level
            h = (t1 - t0) / m
            coef = self.substep_coefficients(h)
            cur = st
            try:
                for k in range(1, m + 1):
                    tk = t1 if k == m else t0 + k * h
                    ta_k = ta_new if k == m else self.time_arrays(tk)
                    ta_p = ta_old if k == 1 else self.time_arrays(cur.t)
                    out = self.step(cur, tk, step, ta_p, ta_k, coef=coef)
                    cur = out[0]
            except (ConvergenceError, NonFiniteError):
                if level == max_halvings:
                    raise
                continue
            reductions.append((float(t1), m))
            return out
        raise AssertionError("unreachable")  # pragma: no cover

    def initial(self, t0, q0, v0, ta=None):
        """Consistent initial accelerations and multipliers: one saddle-point solve at ``t0``."""
        n0 = np.zeros(self.n, dtype=self.dtype)
        R_hist = np.zeros(self.n, dtype=self.dtype)
        z, lu, it, hist = self.newton(n0, q0, v0, t0, self.init_coef, R_hist, 0, ta=ta)
        a = z[: self.n_dof]
        return State(t0, q0.copy(), v0.copy(), a, z[self.n_dof:] * self.scale, a.copy()), lu, z

    def step(self, st: State, t1: float, step: int, ta_old=None, ta_new=None, coef=None):
        """Advance one step from ``st`` to ``t1`` (``ta_old``, ``ta_new``: time arrays at both
        ends, when precomputed; ``coef``: coefficients of a shorter sub-step). Returns
        ``(state, lu, n_iter, z, qh, vh, R_hist, history)``."""
        coef = self.step_coef if coef is None else coef
        qh, vh = self.predict(st, coef)
        R_hist = self.history(st, coef, ta=ta_old)
        z0 = np.concatenate([st.a, st.lam / self.scale])
        z, lu, it, hist = self.newton(z0, qh, vh, t1, coef, R_hist, step, ta=ta_new)
        a = z[: self.n_dof]
        q1, v1, g1 = newmark_update(coef, qh, vh, a, st.a, st.g)
        new = State(t1, q1, v1, a, z[self.n_dof:] * self.scale, g1)
        return new, lu, it, z, qh, vh, R_hist, hist


class _PermutedLU:
    """The LU of ``B = A[q][:, q]`` solving ``A x = b`` (``q is None``: the LU of ``A``)."""

    __slots__ = ("lu", "q")

    def __init__(self, lu, q):
        self.lu = lu
        self.q = q

    def solve(self, b):
        if self.q is None:
            return self.lu.solve(b)
        y = self.lu.solve(b[self.q])
        x = np.empty_like(y)
        x[self.q] = y
        return x


def time_table(system: System, times: np.ndarray, dtype=None, cache: dict | None = None
               ) -> tuple:
    """Time-dependent data at every time of ``times``: ``(C, CD, CDD, F, T)`` with a leading
    axis ``len(times)`` — profiles are evaluated once per run (vectorized where the profile
    allows), not inside the Newton loop. ``cache`` shares profile tables between systems with
    equal profiles (the perturbed designs of a sensitivity run)."""
    dt = system.dtype if dtype is None else np.dtype(dtype)
    times = np.asarray(times, dtype=float)
    cache = {} if cache is None else cache

    def tab(prof):
        try:
            key = (prof, times.size, float(times[0]), float(times[-1]))
            hit = cache.get(key)
        except TypeError:  # unhashable profile
            key, hit = None, None
        if hit is None:
            hit = prof.table(times)
            if key is not None:
                cache[key] = hit
        return hit

    n_t = times.size
    C = np.repeat(system.con_c0[None, :].astype(dt), n_t, axis=0)
    CD = np.zeros_like(C)
    CDD = np.zeros_like(C)
    for row, prof in system.con_drive:
        f, f1, f2 = tab(prof)
        C[:, row] += f
        CD[:, row] = f1
        CDD[:, row] = f2
    F = np.repeat(system.load_F0[None].astype(dt), n_t, axis=0)
    for i, prof in enumerate(system.load_prof):
        F[:, i, :] *= tab(prof)[0][:, None]
    T = np.repeat(system.torque_T0[None].astype(dt), n_t, axis=0)
    for i, prof in enumerate(system.torque_prof):
        T[:, i] *= tab(prof)[0]
    return tuple(np.ascontiguousarray(x) for x in (C, CD, CDD, F, T))


def table_at(table: tuple, k: int) -> tuple:
    """The time arrays of entry ``k`` of a :func:`time_table`."""
    return tuple(x[k] for x in table)


@dataclass
class StepInfo:
    """What a step observer receives after each converged step (and once for the initial
    solve, with ``n == 0`` and ``prev is None``)."""

    n: int
    prev: State | None
    state: State
    lu: object
    z: np.ndarray
    qh: np.ndarray
    vh: np.ndarray
    coef: StepCoefficients
    stepper: Stepper
    newton_history: list = field(default_factory=list)
    table: tuple | None = None


def integrate(system: System, settings: Settings, *, observer: Callable | None = None,
              progress: bool | Callable = False, scale: float | None = None, q0=None, v0=None,
              polish: int = 0, max_halvings: int = 0):
    """Run the time loop on a compiled system; returns a :class:`morphlab.results.Result`.

    ``observer(info: StepInfo)`` is called after the initial solve and after every converged
    step; the sensitivity strategies use it. On failure the raised :class:`SolverError` carries
    the results up to the last converged step as ``error.result``. ``max_halvings > 0`` retries
    a failed step with up to ``2**max_halvings`` sub-steps (not with an observer: sensitivity
    runs need the same step sequence for every design); the results stay on the regular grid
    and ``result.step_reductions`` lists ``(t, n_substeps)`` of each retried step.
    """
    if settings.newton == "modified" and observer is not None:
        raise ModelError("newton='modified' cannot be combined with an observer: the "
                         "sensitivities need the exact Newton matrix of every step")
    if max_halvings and observer is not None:
        raise ModelError("automatic step reduction cannot be combined with an observer "
                         "(sensitivity runs need one fixed step sequence)")
    if not (isinstance(max_halvings, int) and 0 <= max_halvings <= 20):
        raise ModelError(f"max_halvings must be an integer in [0, 20], got {max_halvings!r}")
    from .results import Result

    settings.validate()
    stepper = Stepper(system, settings, scale=scale)
    stepper.polish = polish
    n_steps = settings.n_steps
    h = settings.h
    n_dof, n_con = system.n_dof, system.n_con
    dt = system.dtype
    t = settings.t_start + h * np.arange(n_steps + 1)
    Q = np.zeros((n_steps + 1, n_dof), dtype=dt)
    V = np.zeros_like(Q)
    A = np.zeros_like(Q)
    LAM = np.zeros((n_steps + 1, n_con), dtype=dt)
    iters = np.zeros(n_steps + 1, dtype=np.int64)
    viol = np.zeros(n_steps + 1)
    vviol = np.zeros(n_steps + 1)
    histories: list = []
    reductions: list = []
    t_wall = _time.perf_counter()

    def make_result(n_done, status, message):
        sl = slice(0, n_done + 1)
        if n_con and n_done >= 0:
            constraint_violation_history(
                Q[sl], V[sl], np.ascontiguousarray(table[0][sl]),
                np.ascontiguousarray(table[1][sl]), system.con_kind, system.con_dofs,
                np.ascontiguousarray(system.con_u0, dtype=dt), viol[sl], vviol[sl])
        return Result(system=system, settings=settings, t=t[sl].copy(), q=Q[sl].copy(),
                      v=V[sl].copy(), a=A[sl].copy(), lam=LAM[sl].copy(),
                      newton_iterations=iters[sl].copy(), constraint_violation=viol[sl].copy(),
                      velocity_violation=vviol[sl].copy(), status=status, message=message,
                      n_factorizations=stepper.n_factorizations,
                      wall_time=_time.perf_counter() - t_wall, newton_history=histories,
                      scale=stepper.scale, step_reductions=list(reductions))

    def record(n, st, it):
        Q[n], V[n], A[n], LAM[n] = st.q, st.v, st.a, st.lam
        iters[n] = it

    from .errors import SolverError

    q_init = system.q0 if q0 is None else q0
    v_init = system.v0 if v0 is None else v0
    table = time_table(system, t)
    try:
        st, lu, z = stepper.initial(t[0], q_init.astype(dt), v_init.astype(dt),
                                    ta=table_at(table, 0))
    except SolverError as err:
        err.result = make_result(-1, "failed", str(err))
        raise
    record(0, st, 1)
    if observer is not None:
        observer(StepInfo(0, None, st, lu, z, st.q, st.v, stepper.init_coef, stepper,
                          table=table))
    report = progress if callable(progress) else (_print_progress if progress else None)
    for n in range(1, n_steps + 1):
        try:
            new, lu, it, z, qh, vh, R_hist, hist = stepper.advance(
                st, float(t[n]), n, table_at(table, n - 1), table_at(table, n), max_halvings,
                reductions)
        except SolverError as err:
            err.result = make_result(n - 1, "failed", str(err))
            raise
        histories.append(hist)
        record(n, new, it)
        if observer is not None:
            observer(StepInfo(n, st, new, lu, z, qh, vh, stepper.step_coef, stepper, hist,
                              table=table))
        st = new
        if report is not None:
            report(n, n_steps, float(t[n]))
    return make_result(n_steps, "ok", f"completed {n_steps} steps")


def _print_progress(n, n_steps, t):
    width = 30
    if n == n_steps or n % max(1, n_steps // 50) == 0:
        done = int(width * n / n_steps)
        end = "\n" if n == n_steps else "\r"
        print(f"[{'#' * done}{'.' * (width - done)}] step {n}/{n_steps} t={t:.4g}", end=end,
              flush=True)


def simulate(model: Model | System, *, t_end: float, dt: float, rho_inf: float = 0.8,
             tol: float = 1e-10, max_iter: int = 12, stabilization: float = 0.5,
             stabilization_damping: float = 1.0, constraint_form: str = "paper",
             scheme: str = "arnold-bruls", progress: bool | Callable = False,
             observer: Callable | None = None, max_halvings: int = 0, q0=None, v0=None,
             newton: str = "full"):
    """Simulate ``model`` from 0 to ``t_end`` with the generalized-alpha method.

    Parameters
    ----------
    model : Model or System
        The mechanism (compiled here if needed).
    t_end, dt : float
        End time and time step [s]; ``t_end/dt`` is rounded up to whole steps.
    rho_inf : float
        Spectral radius at infinite frequency, in [0, 1] (1: no numerical dissipation).
    tol : float
        Newton stops when the position correction is below ``tol`` times the model size.
    max_iter : int
        Newton iteration limit per step.
    newton : {"full", "modified"}
        ``"full"``: the exact Newton matrix is factored at every iteration (quadratic
        convergence; what the sensitivities reuse). ``"modified"``: a factorization is kept
        over iterations and steps while the corrections contract fast (a faster primal when
        the matrix changes slowly; not for sensitivity runs).
    stabilization : float
        ``omega h`` of the Baumgarte term (0 switches it off).
    stabilization_damping : float
        Damping ratio ``xi`` of the Baumgarte term.
    scheme : {"arnold-bruls", "paper"}
        Generalized-alpha form (:func:`step_coefficients`): ``"arnold-bruls"`` is second order
        for every ``rho_inf``; ``"paper"`` is eq. 25–26 of the paper as printed (first order for
        ``rho_inf < 1`` on nonlinear systems; identical at ``rho_inf = 1``).
    constraint_form : {"paper", "endpoint"}
        With ``scheme="paper"``: weighting of the acceleration constraint rows (module
        docstring).
    q0, v0 : (n_dof,), optional
        Start from these coordinates/velocities instead of the model's initial state (they
        must satisfy the constraints, e.g. a static solution: ``ml.static(m).q[-1]``).
    progress : bool or callable
        Print a progress bar, or call ``progress(step, n_steps, t)``.
    observer : callable, optional
        ``observer(StepInfo)`` after every converged step.
    max_halvings : int
        Automatic step reduction: a step whose Newton iteration fails is retried with 2, 4,
        ... sub-steps, up to ``2**max_halvings`` (0: off, the default). Retried steps are
        listed in ``result.step_reductions``.

    Returns
    -------
    Result
        Stacked histories and statistics.

    Raises
    ------
    ConvergenceError, NonFiniteError, SingularMatrixError
        With ``error.result`` holding the steps completed before the failure.
    """
    system = model if isinstance(model, System) else compile_model(model)
    settings = Settings(t_end=t_end, dt=dt, rho_inf=rho_inf, tol=tol, max_iter=max_iter,
                        stabilization=stabilization, stabilization_damping=stabilization_damping,
                        constraint_form=constraint_form, scheme=scheme, newton=newton)
    for name, x in (("q0", q0), ("v0", v0)):
        if x is not None and (np.shape(x) != (system.n_dof,) or not np.all(np.isfinite(x))):
            raise ModelError(f"{name} must be a finite array of shape ({system.n_dof},), got "
                             f"shape {np.shape(x)}")
    return integrate(system, settings, observer=observer, progress=progress,
                     max_halvings=max_halvings, q0=None if q0 is None else np.asarray(q0),
                     v0=None if v0 is None else np.asarray(v0))
