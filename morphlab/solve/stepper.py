"""One generalized-alpha step: residual, exact Newton matrix, sparse LU and Newton–Raphson.

Unknowns of a step are ``z = (a, lam/scale)`` with ``a = q''_{n+1}``; positions and velocities
follow from the Newmark update ``q_{n+1} = q_hat + bh2 a``, ``q'_{n+1} = v_hat + gh a`` whose
coefficients (for the default Arnold–Brüls form and for the paper's eq. 25–26) are the data of
:mod:`morphlab.integrator`. The residual is ``E(s_{n+1}; new weights) + E(s_n; old weights)``
with ``E`` the kernel :func:`morphlab.kernels.assemble.add_residual` (the default scheme has no
old-level share). The Newton matrix ``dR/dz`` is exact (eq. 30–33 with every derivative term),
so Newton converges quadratically and the direct sensitivities are exact. The time loop that
calls :class:`Stepper` is :mod:`morphlab.timeloop`.

The acceleration-level (index-1) constraints drift at position level. A Baumgarte-type term,
``F_c -> F_c - b1 Phi' - b0 Phi`` with ``b1 = 2 xi omega`` and ``b0 = omega²``, is part of the
residual (and so of its derivatives). ``omega = stabilization / h``; 0 switches it off.
"""

from __future__ import annotations

import numbers
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np
import scipy.sparse as sp

from ..compile.system import System, kernel_arrays
from ..errors import ConvergenceError, ModelError, NonFiniteError, SingularMatrixError
from ..kernels.assemble import add_residual, apply_correction, step_matrix, step_residual
from ..kernels.newton import (
    CONVERGED,
    NONFINITE_CORRECTION,
    NONFINITE_RESIDUAL,
    NOT_CONVERGED,
    PIVOT_REFUSED,
    SINGULAR,
    newton_loop,
)
from .linalg import SPLU_OPTIONS, DenseLU, SparseLU, StepFactorization, no_sparse_arrays
from .scheme import (
    INITIAL,
    SCHEMES,
    GeneralizedAlpha,
    StepCoefficients,
    _is_real,
    newmark_predict,
    newmark_update,
    step_coefficients,
)


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


class Stepper:
    """Residual, Newton matrix and Newton iteration of one compiled system.

    Stateless with respect to the time history: every method takes the states it needs. The
    sensitivity strategies call :meth:`residual` with perturbed inputs (complex step or finite
    differences): one residual, one set of kernels.
    """

    #: Run the Newton loop in one compiled call once the factorization has settled (see
    #: :meth:`newton`). False keeps every iteration in Python, where each factorization can be
    #: seen (tests count them); the iterates are the same.
    compiled: bool = True

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
        self._factorization = StepFactorization(system.indices, system.indptr, self.n,
                                                self.dtype)
        self.polish = 0  # extra Newton updates after convergence (complex-step reference runs)
        self._loop_scratch = None  # buffers of _compiled_newton, allocated on first use

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
        return self._residual(z, qh, vh, t1, coef, R_hist, time_arrays)[0]

    def _residual(self, z, qh, vh, t1, coef, R_hist, time_arrays=None):
        """``(R, |R|)`` of the step at ``z`` (``|R|`` is NaN or Inf if an entry is)."""
        dt = np.result_type(z.dtype, qh.dtype, R_hist.dtype)
        c, cd, cdd, F, T = time_arrays if time_arrays is not None else self.time_arrays(t1)
        R = np.empty(self.n, dtype=dt)
        # astype(copy=False): no copies in the Newton loop when the dtypes already agree
        ssq = step_residual(self.S, z.astype(dt, copy=False), qh.astype(dt, copy=False),
                            vh.astype(dt, copy=False), coef.bh2, coef.gh, self.scale,
                            coef.arrays[3], self.b0, self.b1, c, cd, cdd, F, T,
                            self.n_dof, R_hist.astype(dt, copy=False), R)
        return R, float(np.sqrt(ssq))

    def _fill(self, z, qh, vh, t1, coef, scale=None, F=None):
        sc = self.scale if scale is None else scale
        if F is None:
            F = np.ascontiguousarray(self.system.time_arrays(t1)[3], dtype=self.dtype)
        step_matrix(self.S, z, qh, vh, coef.bh2, coef.gh, sc, coef.arrays[3], self.b0,
                    self.b1, F, self.data)

    def matrix(self) -> sp.csc_matrix:
        """The Newton matrix last filled, as a CSC matrix sharing ``data`` (built once: the
        pattern is fixed, and constructing a SciPy matrix costs ~70 µs)."""
        if self._A is None or self._A.data is not self.data:
            self._A = sp.csc_matrix((self.data, self.system.indices, self.system.indptr),
                                    shape=(self.n, self.n))
        return self._A

    def _lu(self):
        """Factor the filled matrix (:class:`morphlab.factorization.StepFactorization`)."""
        return self._factorization(self.data)

    def factor(self, z, qh, vh, t1, coef, F=None):
        """Fill and factor the exact Newton matrix at ``z``."""
        self._fill(z, qh, vh, t1, coef, F=F)
        try:
            lu = self._lu()
        except RuntimeError as exc:
            raise self._singular(t1, str(exc)) from None
        self.n_factorizations += 1
        return lu

    @property
    def unknown_names(self) -> list[str]:
        """Name of each equation / unknown of a step: the DOFs, then ``"constraint <row>"``."""
        return self.system.dof_names + [f"constraint {c}" for c in self.system.con_names]

    def non_finite(self, x, k=8) -> list[str]:
        """Names of the first ``k`` equations/unknowns with a NaN or Inf entry."""
        names = self.unknown_names
        return [names[i] for i in np.flatnonzero(~np.isfinite(x))[:k]]

    def dominant(self, R, k=3) -> list[str]:
        """Names of the ``k`` equations with the largest residual entries."""
        names = self.unknown_names
        idx = np.argsort(-np.abs(R))[:k]
        return [f"{names[i]} ({abs(R[i]):.3g})" for i in idx]

    def newton(self, z, qh, vh, t1, coef, R_hist, step, ta=None):
        """Newton–Raphson from ``z``. Returns ``(z, lu, n_iter, history)``; ``lu`` is the last
        factorization (taken at the iterate before the final correction).

        Once the factorization has settled (:attr:`StepFactorization.settled`) the whole loop
        runs in one compiled call (:meth:`_compiled_newton`); where a sparse pivot fails the
        threshold there, it goes on from Python at that iteration (SuperLU chooses a new row
        order), with the same iterates either way."""
        s = self.settings
        L = self.system.length_scale
        if ta is None:
            ta = self.time_arrays(t1)
        F = ta[3]
        if s.newton == "modified" and coef is self.step_coef:
            return self._modified_newton(z, qh, vh, t1, coef, R_hist, step, ta)
        first, hist = 1, []
        fac = self._factorization
        if (self.compiled and fac.settled and (fac.dense or self.polish == 0)
                and z.dtype == qh.dtype == vh.dtype == R_hist.dtype == self.dtype):
            z, lu, it, hist = self._compiled_newton(z, qh, vh, t1, coef, R_hist, step, ta)
            if lu is not None:
                return z, lu, it, hist
            first = it  # a sparse pivot failed at iteration ``it``: redo it from here
        for it in range(first, s.max_iter + 1):
            z, lu, r_norm, dz_max = self._iteration(z, qh, vh, t1, coef, R_hist, ta, step, it)
            # linear in z for the initial accelerations (h = 0): one solve is exact
            err = 0.0 if coef.h == 0.0 else coef.bh2 * dz_max / L
            hist.append((r_norm, err))
            if err <= s.tol:
                # A complex-step run's imaginary part (the derivative) converges one Newton
                # iteration behind the real part: polish removes that lag.
                for _ in range(self.polish):
                    R = self.residual(z, qh, vh, t1, coef, R_hist, time_arrays=ta)
                    lu = self.factor(z, qh, vh, t1, coef, F=F)
                    z = z + lu.solve(-R)
                return z, lu, it, hist
        raise self._not_converged(z, qh, vh, t1, coef, R_hist, ta, step, err)

    def _compiled_newton(self, z, qh, vh, t1, coef, R_hist, step, ta):
        """:meth:`newton` in one compiled call (:func:`morphlab.kernels.newton.newton_loop`, the
        same kernels and arithmetic as the step-by-step loop, so the same iterates), on the
        dense LU or on the sparse refactorization with the kept row order; the errors raised
        here as there. Returns :meth:`newton`'s tuple, or ``(z, None, it, history)`` when a
        sparse pivot failed the threshold at iteration ``it`` (``z`` the iterate whose matrix
        it was, ``history`` the iterations before).

        Measured on the 8-element pendulum of the Exudyn comparison (29 unknowns, dense, 1000
        steps, 2 iterations per step): 55 ms per run, against 60 ms with one compiled call per
        iteration and 73 ms with the five calls per iteration of the step-by-step loop. On the
        morphing model (123 unknowns, sparse, 300 steps): 31.8 ms against 36.2 ms per run
        (medians of 40 interleaved pairs)."""
        s = self.settings
        n, dt = self.n, self.dtype
        if self._loop_scratch is None:  # residual (read on failure), (|R|, err) rows, empties
            self._loop_scratch = (np.empty(n, dtype=dt), np.zeros((s.max_iter, 2)),
                                  np.zeros((0, 0), dtype=dt), np.zeros(0, dtype=np.int64),
                                  np.zeros(0, dtype=dt), *no_sparse_arrays(dt))
        R, hist, no_lu, no_piv, no_values, no_order, no_pattern = self._loop_scratch
        # fresh factors every step: a sensitivity run keeps them (sensitivity_direct)
        fac = self._factorization
        if fac.dense:
            LU, piv = np.empty((n, n), dtype=dt), np.empty(n, dtype=np.int64)
            Lx = Ux = Ud = no_values
            order, pattern = no_order, no_pattern
        else:
            pivots = fac.pivots
            LU, piv = no_lu, no_piv
            Lx, Ux, Ud = pivots.empty_factors()
            order, pattern = pivots.order_arrays, pivots.solve_arrays
        z, it, status, bad = newton_loop(
            self.S, z, qh, vh, coef.bh2, coef.gh, self.scale, coef.arrays[3], self.b0,
            self.b1, *ta, self.n_dof, R_hist, self.system.indices, self.system.indptr,
            coef.h == 0.0, self.system.length_scale, s.tol, s.max_iter, self.polish, R,
            self.data, LU, piv, Lx, Ux, Ud, order, pattern, SPLU_OPTIONS["diag_pivot_thresh"],
            hist)
        if status == CONVERGED:
            self.n_factorizations += it + self.polish
            lu = DenseLU(LU, piv) if fac.dense else SparseLU(pivots, Lx, Ux, Ud)
            return z, lu, it, [tuple(h) for h in hist[:it].tolist()]
        # no complete factorization at `it` unless the failure came after it
        self.n_factorizations += it if status in (NONFINITE_CORRECTION, NOT_CONVERGED) else it - 1
        if status == PIVOT_REFUSED:
            return z, None, it, [tuple(h) for h in hist[:it - 1].tolist()]
        r_norm = float(hist[it - 1, 0])
        if status == NONFINITE_RESIDUAL:
            raise self._non_finite_residual(R, t1, step, it)
        if status == SINGULAR:
            raise self._singular(t1, "no nonzero pivot left for the column of "
                                 f"{self.unknown_names[bad]}", step, r_norm, R)
        if status == NONFINITE_CORRECTION:
            raise self._non_finite_correction(z, t1, step, r_norm)
        raise self._not_converged(z, qh, vh, t1, coef, R_hist, ta, step, float(hist[it - 1, 1]))

    def _iteration(self, z, qh, vh, t1, coef, R_hist, ta, step, it):
        """One full Newton iteration from ``z``: ``(z + dz, lu, |R(z)|, |dz_a|_max)`` with
        ``lu`` the factorization of the matrix at ``z``. Raises :class:`NonFiniteError` for a
        non-finite residual or correction and :class:`SingularMatrixError`, naming where."""
        R, r_norm = self._finite_residual(z, qh, vh, t1, coef, R_hist, ta, step, it)
        try:
            lu = self.factor(z, qh, vh, t1, coef, F=ta[3])
        except SingularMatrixError as err:
            err.step = step
            err.residual = r_norm
            err.dominant = self.dominant(R)
            raise
        z1, dz_max, finite = apply_correction(z, lu.solve(-R), self.n_dof)
        if not finite:
            raise self._non_finite_correction(z1, t1, step, r_norm)
        return z1, lu, r_norm, dz_max

    def _not_converged(self, z, qh, vh, t1, coef, R_hist, ta, step, err) -> ConvergenceError:
        s = self.settings
        R = self.residual(z, qh, vh, t1, coef, R_hist, time_arrays=ta)
        return ConvergenceError(
            f"Newton did not converge at t={t1:.6g} (step {step}) in {s.max_iter} iterations: "
            f"position correction {err:.3g} of the model size (tol {s.tol:.1g}), residual norm "
            f"{np.linalg.norm(R):.3g}; dominant equations: {', '.join(self.dominant(R))}",
            time=t1, step=step, residual=float(np.linalg.norm(R)), dominant=self.dominant(R))

    def _non_finite_correction(self, z1, t1, step, r_norm) -> NonFiniteError:
        bad = self.non_finite(z1)
        return NonFiniteError(
            f"non-finite Newton correction at t={t1:.6g} (step {step}) in {', '.join(bad)}",
            time=t1, step=step, residual=r_norm, dominant=bad)

    def _singular(self, t1, detail, step=None, r_norm=None, R=None) -> SingularMatrixError:
        err = SingularMatrixError(
            f"singular saddle-point matrix at t={t1:.6g}: {detail}. Look for redundant joints, "
            "a body without mass in its free directions, or a mechanism locked in a singular "
            "position", time=t1)
        if step is not None:
            err.step, err.residual, err.dominant = step, r_norm, self.dominant(R)
        return err

    def _non_finite_residual(self, R, t1, step, it) -> NonFiniteError:
        bad = self.non_finite(R)
        return NonFiniteError(
            f"non-finite residual at t={t1:.6g} (step {step}, iteration {it}) in "
            f"{', '.join(bad)}", time=t1, step=step, residual=float("nan"), dominant=bad)

    def _finite_residual(self, z, qh, vh, t1, coef, R_hist, ta, step, it):
        """``(R, |R|)`` of the step; a NaN or Inf raises :class:`NonFiniteError` naming where."""
        R, r_norm = self._residual(z, qh, vh, t1, coef, R_hist, ta)
        if not np.isfinite(r_norm):
            raise self._non_finite_residual(R, t1, step, it)
        return R, r_norm

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
            R, r_norm = self._finite_residual(z, qh, vh, t1, coef, R_hist, ta, step, it)
            fresh = self._kept is None
            if fresh:
                try:
                    self._kept = self.factor(z, qh, vh, t1, coef, F=ta[3])
                except SingularMatrixError as err:
                    err.step, err.residual = step, r_norm
                    err.dominant = self.dominant(R)
                    raise
            dz = self._kept.solve(-R)
            err = coef.bh2 * float(np.max(np.abs(dz[: self.n_dof]))) / L
            hist.append((r_norm, err))
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
