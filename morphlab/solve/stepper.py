"""One generalized-alpha step: the step equations of a state, solved by Newton.

The unknowns of a step are ``z = (a, lam/scale)`` with ``a = q''_{n+1}``; positions and
velocities follow from the Newmark update ``q_{n+1} = q_hat + bh2 a``,
``q'_{n+1} = v_hat + gh a`` whose coefficients are the data of :mod:`morphlab.solve.scheme`.
The residual is ``E(s_{n+1}; new weights) + E(s_n; old weights)`` with ``E`` the kernel
:func:`morphlab.kernels.assemble.residual` (the default scheme has no old-level share); the
step matrix ``dR/dz`` is exact, so Newton (:mod:`morphlab.solve.newton`) converges
quadratically and the sensitivities are exact (``docs/theory.md`` §5).

The acceleration-level (index-1) constraints drift at position level. A Baumgarte-type term,
``F_c -> F_c - b1 Phi' - b0 Phi`` with ``b1 = 2 xi omega`` and ``b0 = omega²``, is part of the
residual (and so of its derivatives); ``omega = stabilization / h``, 0 switches it off.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from ..compile.system import System, real_parts, time_table
from ..errors import ConvergenceError, NonFiniteError
from ..kernels import newmark
from ..kernels.assemble import Step, residual
from ..kernels.system import Times
from ..kernels.types import Level
from .linalg import Factor, csc_matrix
from .newton import NewtonSolver, StepProblem
from .scheme import INITIAL, GeneralizedAlpha, StepCoefficients, kernel_scheme, weights
from .scheme import step_coefficients as _step_coefficients
from .settings import Settings, State

#: Coefficients of a static equilibrium as a step: no inertia (``w_m = 0``), the constraint
#: rows at position level (``b0 = 1``, ``b1 = 0``, ``F_c = -Phi``) and ``a`` standing for the
#: Newton correction of ``q`` (``bh2 = 1``, ``gh = 0``).
STATIC = StepCoefficients(1.0, (0.0, 1.0, 1.0, 0.0, 1.0), None, 1.0, 0.0)


class StepOutcome(NamedTuple):
    """A converged step: the new state, the factorization of its last Newton iteration (at the
    iterate before the final correction), the iterations, the unknowns ``z``, the predictors,
    the old level's share and the Newton history ((iterations, 2): ``|R|``, correction)."""

    state: State
    factor: Factor
    iterations: int
    z: np.ndarray
    qh: np.ndarray
    vh: np.ndarray
    R_hist: np.ndarray
    newton: np.ndarray


class Stepper:
    """The steps of one compiled system: predictors, old-level share, Newton, update.

    Stateless with respect to the time history: every method takes the states it needs.
    Build it with :meth:`dynamic` (a time integration) or :meth:`static` (load continuation).

    Attributes
    ----------
    system : System
    T : Times
        The time values of the run (:func:`~morphlab.compile.system.time_table`).
    step_coef : StepCoefficients
        Coefficients of a regular step (``init_coef``: the initial solve).
    scale : float
        Scale of the constraint rows and multiplier columns (fixed for the run and every
        sensitivity of it).
    b0, b1 : float
        Stabilization of the constraint rows.
    newton : NewtonSolver
    """

    def __init__(self, system: System, step_coef: StepCoefficients, newton: NewtonSolver,
                 T: Times, *, b0: float, b1: float, scale: float | None,
                 scale_at: tuple | None = None, modified: bool = False,
                 method: GeneralizedAlpha | None = None, constraint_form: str = "paper",
                 scheme: str = "arnold-bruls"):
        self.system = system
        self.M = system.arrays
        # the real parts of a complex system, for its real step matrix (NewtonSolver)
        self.M_real = real_parts(self.M) if system.dtype.kind == "c" else None
        self._T_real = (None, None)  # the last time table and its real parts
        self.P = system.parts()
        self.T = T
        self.dtype = system.dtype
        self.n_dof = system.n_dof
        self.n = system.n
        self.step_coef = step_coef
        self.init_coef = INITIAL
        self.newton = newton
        self.b0, self.b1 = b0, b1
        self.modified = modified
        self.method, self.constraint_form, self.scheme = method, constraint_form, scheme
        if scale is None:
            scale = self._choose_scale(step_coef, *(scale_at or (system.q0, system.v0)))
        self.scale = scale

    @classmethod
    def dynamic(cls, system: System, settings: Settings, T: Times, *,
                scale: float | None = None, polish: int = 0, rows: int = 1) -> Stepper:
        """A time integration with ``settings`` over the time values ``T``; ``scale`` of a run
        to share it with (sensitivities), ``polish`` Newton iterations after convergence
        (complex-step runs), ``rows`` of the Newton fill (3: with ``Dq``, ``Dv``)."""
        method = GeneralizedAlpha(settings.rho_inf)
        h = settings.h
        om = settings.stabilization / h if settings.stabilization > 0 else 0.0
        coef = _step_coefficients(settings.scheme, method, h, settings.constraint_form)
        newton = NewtonSolver(system, system.dtype, tol=settings.tol, max_iter=settings.max_iter,
                              dense_max=settings.dense_max, compiled=settings.compiled_newton,
                              polish=polish, rows=rows)
        return cls(system, coef, newton, T, b0=om * om,
                   b1=2.0 * settings.stabilization_damping * om, scale=scale,
                   modified=settings.newton == "modified", method=method,
                   constraint_form=settings.constraint_form, scheme=settings.scheme)

    @classmethod
    def static(cls, system: System, q_start, T: Times, *, tol: float, max_iter: int,
               dense_max: int, compiled: bool = True) -> Stepper:
        """Static equilibria (:data:`STATIC` coefficients) at the times of ``T``; the
        constraint rows scaled like the stiffness diagonal at ``q_start``."""
        newton = NewtonSolver(system, system.dtype, tol=tol, max_iter=max_iter,
                              dense_max=dense_max, compiled=compiled)
        zero_v = np.zeros(system.n_dof, dtype=system.dtype)
        return cls(system, STATIC, newton, T, b0=1.0, b1=0.0, scale=None,
                   scale_at=(q_start, zero_v))

    @property
    def n_factorizations(self) -> int:
        return self.newton.n_factorizations

    def scheme_of(self, coef: StepCoefficients | None = None):
        """The kernels' :class:`~morphlab.kernels.steps.Scheme` of a regular step (or
        ``coef``), with as many fill rows as the Newton solver's."""
        return kernel_scheme(coef or self.step_coef, self.scale, self.b0, self.b1,
                             split=self.newton.data.shape[0] == 3)

    # ---- building blocks
    def _choose_scale(self, coef: StepCoefficients, q, v) -> float:
        """The median magnitude of the diagonal of the equation block of the step matrix at
        ``(q, v)`` with ``a = 0`` (real part)."""
        p = self.problem(q, v, coef, None, self.T, 0, 0.0, 0, scale=1.0)
        p.fill(np.zeros(self.n, dtype=self.dtype), self.newton.data, self.newton.W_fill)
        A = csc_matrix(self.newton.data[0], self.system.indices, self.system.indptr, self.n)
        d = np.abs(np.real(A.diagonal()[: self.n_dof]))
        d = d[d > 0]
        return float(np.median(d)) if d.size else 1.0

    def problem(self, qh, vh, coef: StepCoefficients, R_hist, T: Times, k: int, t: float,
                step: int, scale: float | None = None) -> StepProblem:
        """The step equations at the predictors ``qh, vh`` with the time values of ``T`` at
        index ``k`` (``R_hist`` None: no old level)."""
        if R_hist is None:
            R_hist = np.zeros(self.n, dtype=self.dtype)
        scale = self.scale if scale is None else scale
        C = np.array([[1.0, coef.bh2, coef.gh], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]])
        s = Step(qh, vh, R_hist, float(coef.bh2), float(coef.gh),
                 weights(coef.new, scale, self.b0, self.b1), C[:self.newton.data.shape[0]],
                 0, k)
        return StepProblem(self.system, self.M, T, self.P, s, coef.h == 0.0, t, step,
                           None if self.M_real is None else (self.M_real, self._real_times(T)))

    def _real_times(self, T: Times) -> Times:
        """The real parts of the time values ``T`` (kept for the last table asked for)."""
        if self._T_real[0] is not T:
            self._T_real = (T, real_parts(T))
        return self._T_real[1]

    def history(self, st: State, coef: StepCoefficients, T: Times, k: int):
        """The old-level share ``E(s_n; old weights)`` of the residual (constant in a step;
        zero for schemes without one) at the state ``st`` of time index ``k`` of ``T``."""
        R = np.zeros(self.n, dtype=self.dtype)
        if coef.old is None:
            return R
        residual(self.M, Level(st.q, st.v, st.a, st.lam), weights(coef.old, self.scale,
                 self.b0, self.b1), T, 0, k, self.P, self.n_dof, R, self.newton.W)
        return R

    def solve(self, p: StepProblem, z) -> tuple:
        """Newton on ``p`` from ``z`` (modified Newton for regular steps when asked):
        ``(z, factor, iterations, history)``."""
        if self.modified and not p.linear and p.s.bh2 == self.step_coef.bh2:
            return self.newton.solve_modified(p, z)
        return self.newton.solve(p, z)

    # ---- steps
    def initial(self, t0, q0, v0):
        """Consistent initial accelerations and multipliers: one saddle-point solve at ``t0``
        (time index 0). Returns ``(state, factor, z)``."""
        p = self.problem(q0, v0, self.init_coef, None, self.T, 0, t0, 0)
        z, lu, _, _ = self.solve(p, np.zeros(self.n, dtype=self.dtype))
        a = z[: self.n_dof]
        return State(t0, q0.copy(), v0.copy(), a, z[self.n_dof:] * self.scale, a.copy()), lu, z

    def step(self, st: State, t1: float, step: int, T: Times | None = None, k: int | None = None,
             coef: StepCoefficients | None = None) -> StepOutcome:
        """Advance one step from ``st`` (time index ``k - 1`` of ``T``) to ``t1`` (index ``k``;
        by default the run's table and ``step``); ``coef``: coefficients of a shorter
        sub-step."""
        coef = self.step_coef if coef is None else coef
        T = self.T if T is None else T
        k = step if k is None else k
        pc, upd = coef.arrays.pc, coef.arrays.upd
        qh, vh = np.empty_like(st.q), np.empty_like(st.q)
        newmark.predict(pc, st.q, st.v, st.a, st.g, qh, vh)
        R_hist = self.history(st, coef, T, k - 1)
        p = self.problem(qh, vh, coef, R_hist, T, k, t1, step)
        z0 = np.concatenate([st.a, st.lam / self.scale])
        z, lu, it, hist = self.solve(p, z0)
        a = z[: self.n_dof]
        q1, v1, g1 = np.empty_like(qh), np.empty_like(qh), np.empty_like(qh)
        newmark.update(pc, upd, qh, vh, a, st.a, st.g, q1, v1, g1)
        new = State(t1, q1, v1, a, z[self.n_dof:] * self.scale, g1)
        return StepOutcome(new, lu, it, z, qh, vh, R_hist, hist)

    def advance(self, st: State, t1: float, step: int, max_halvings: int,
                reductions: list) -> StepOutcome:
        """:meth:`step`, retried on ``[st.t, t1]`` with 2, 4, ... equal sub-steps (up to
        ``2**max_halvings``) when Newton fails; each success with sub-steps is recorded in
        ``reductions`` as ``(t1, n_substeps)``."""
        try:
            return self.step(st, t1, step)
        except (ConvergenceError, NonFiniteError):
            if max_halvings <= 0:
                raise
        t0 = st.t
        for level in range(1, max_halvings + 1):
            m = 2**level
            h = (t1 - t0) / m
            coef = _step_coefficients(self.scheme, self.method, h, self.constraint_form)
            times = np.array([t1 if k == m else t0 + k * h for k in range(m + 1)])
            T = time_table(self.system, times, self.dtype)
            cur = st
            try:
                for k in range(1, m + 1):
                    out = self.step(cur, float(times[k]), step, T, k, coef=coef)
                    cur = out.state
            except (ConvergenceError, NonFiniteError):
                if level == max_halvings:
                    raise
                continue
            reductions.append((float(t1), m))
            return out
        raise AssertionError("unreachable")  # pragma: no cover

    def equilibrium(self, q_start, lam, k: int, t: float) -> tuple:
        """A static equilibrium at time index ``k`` of the table (time ``t``) from
        ``(q_start, lam)`` (:meth:`static` steppers): ``(q, lam, iterations, factor)``."""
        zero_v = np.zeros(self.n_dof, dtype=self.dtype)
        p = self.problem(q_start, zero_v, self.step_coef, None, self.T, k, t, k)
        z0 = np.concatenate([np.zeros(self.n_dof, dtype=self.dtype), lam / self.scale])
        z, lu, it, _ = self.solve(p, z0)
        return q_start + z[: self.n_dof], z[self.n_dof:] * self.scale, it, lu


__all__ = ["STATIC", "StepOutcome", "Stepper"]
