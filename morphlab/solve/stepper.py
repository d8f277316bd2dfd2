"""One generalized-alpha step: the step equations of a state, solved by Newton.

The unknowns of a step are ``z = (a, lam/scale)`` with ``a = q''_{n+1}``; positions and
velocities follow from the Newmark update ``q_{n+1} = q_hat + bh2 a``,
``q'_{n+1} = v_hat + gh a`` whose coefficients are the data of :mod:`morphlab.solve.scheme`.
The residual is ``E(s_{n+1}; new weights) + E(s_n; old weights)`` with ``E`` the kernel
:func:`morphlab.kernels.assemble.add_residual` (the default scheme has no old-level share); the
step matrix ``dR/dz`` is exact, so Newton (:mod:`morphlab.solve.newton`) converges
quadratically and the sensitivities are exact (``docs/theory.md`` §5).

The acceleration-level (index-1) constraints drift at position level. A Baumgarte-type term,
``F_c -> F_c - b1 Phi' - b0 Phi`` with ``b1 = 2 xi omega`` and ``b0 = omega²``, is part of the
residual (and so of its derivatives); ``omega = stabilization / h``, 0 switches it off.
"""

from __future__ import annotations

import numpy as np

from ..compile.system import System, TimeArrays, kernel_arrays
from ..errors import ConvergenceError, NonFiniteError
from ..kernels import newmark
from ..kernels.assemble import add_residual
from .linalg import Factor, csc_matrix
from .newton import NewtonSolver, StepProblem
from .scheme import INITIAL, GeneralizedAlpha, StepCoefficients
from .scheme import step_coefficients as _step_coefficients
from .settings import Settings, State

#: Coefficients of a static equilibrium as a step: no inertia (``w_m = 0``), the constraint
#: rows at position level (``b0 = 1``, ``b1 = 0``, ``F_c = -Phi``) and ``a`` standing for the
#: Newton correction of ``q`` (``bh2 = 1``, ``gh = 0``).
STATIC = StepCoefficients(1.0, (0.0, 1.0, 1.0, 0.0, 1.0), None, 1.0, 0.0)


class Stepper:
    """The steps of one compiled system: predictors, old-level share, Newton, update.

    Stateless with respect to the time history: every method takes the states it needs.
    Build it with :meth:`dynamic` (a time integration) or :meth:`static` (load continuation).

    Attributes
    ----------
    system, S : the compiled system and its kernel arrays
    step_coef : StepCoefficients
        Coefficients of a regular step (``init_coef``: the initial solve).
    scale : float
        Scale of the constraint rows and multiplier columns (fixed for the run and every
        sensitivity of it).
    b0, b1 : float
        Stabilization of the constraint rows.
    newton : NewtonSolver
    """

    def __init__(self, system: System, step_coef: StepCoefficients, newton: NewtonSolver, *,
                 b0: float, b1: float, scale: float | None, scale_at: tuple | None = None,
                 modified: bool = False, method: GeneralizedAlpha | None = None,
                 constraint_form: str = "paper", scheme: str = "arnold-bruls"):
        self.system = system
        self.S = kernel_arrays(system)
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
    def dynamic(cls, system: System, settings: Settings, *, scale: float | None = None,
                polish: int = 0) -> Stepper:
        """A time integration with ``settings``; ``scale`` of a run to share it with
        (sensitivities), ``polish`` Newton iterations after convergence (complex-step runs)."""
        method = GeneralizedAlpha(settings.rho_inf)
        h = settings.h
        om = settings.stabilization / h if settings.stabilization > 0 else 0.0
        coef = _step_coefficients(settings.scheme, method, h, settings.constraint_form)
        newton = NewtonSolver(system, system.dtype, tol=settings.tol, max_iter=settings.max_iter,
                              dense_max=settings.dense_max, compiled=settings.compiled_newton,
                              polish=polish)
        return cls(system, coef, newton, b0=om * om, b1=2.0 * settings.stabilization_damping * om,
                   scale=scale, modified=settings.newton == "modified", method=method,
                   constraint_form=settings.constraint_form, scheme=settings.scheme)

    @classmethod
    def static(cls, system: System, q_start, *, tol: float, max_iter: int, dense_max: int,
               compiled: bool = True) -> Stepper:
        """Static equilibria (:data:`STATIC` coefficients); the constraint rows scaled like
        the stiffness diagonal at ``q_start``."""
        newton = NewtonSolver(system, system.dtype, tol=tol, max_iter=max_iter,
                              dense_max=dense_max, compiled=compiled)
        zero_v = np.zeros(system.n_dof, dtype=system.dtype)
        return cls(system, STATIC, newton, b0=1.0, b1=0.0, scale=None,
                   scale_at=(q_start, zero_v))

    @property
    def n_factorizations(self) -> int:
        return self.newton.n_factorizations

    # ---- building blocks
    def _choose_scale(self, coef: StepCoefficients, q, v) -> float:
        """The median magnitude of the diagonal of the equation block of the step matrix at
        ``(q, v)`` with ``a = 0`` (real part)."""
        p = self.problem(q, v, coef, None, self.time_arrays(0.0), 0.0, 0, scale=1.0)
        p.fill(np.zeros(self.n, dtype=self.dtype), self.newton.data)
        A = csc_matrix(self.newton.data, self.system.indices, self.system.indptr, self.n)
        d = np.abs(np.real(A.diagonal()[: self.n_dof]))
        d = d[d > 0]
        return float(np.median(d)) if d.size else 1.0

    def problem(self, qh, vh, coef: StepCoefficients, R_hist, ta: TimeArrays, t: float,
                step: int, scale: float | None = None) -> StepProblem:
        """The step equations at the predictors ``qh, vh`` (``R_hist`` None: no old level)."""
        if R_hist is None:
            R_hist = np.zeros(self.n, dtype=self.dtype)
        return StepProblem(self.system, self.S, qh, vh, coef, R_hist, ta,
                           self.scale if scale is None else scale, self.b0, self.b1, t, step)

    def time_arrays(self, t) -> TimeArrays:
        """The system's time-dependent arrays at ``t`` in the run's dtype."""
        return TimeArrays(*(np.ascontiguousarray(x, dtype=self.dtype)
                            for x in self.system.time_arrays(t)))

    def history(self, st: State, coef: StepCoefficients, ta: TimeArrays | None = None):
        """The old-level share ``E(s_n; old weights)`` of the residual (constant in a step;
        zero for schemes without one); ``ta``: the time arrays at ``st.t`` when known."""
        R = np.zeros(self.n, dtype=self.dtype)
        if coef.old is None:
            return R
        ta = ta if ta is not None else self.time_arrays(st.t)
        add_residual(self.S, st.q, st.v, st.a, st.lam, *coef.old, self.scale, self.b0,
                     self.b1, *ta, self.n_dof, R)
        return R

    def solve(self, p: StepProblem, z) -> tuple:
        """Newton on ``p`` from ``z`` (modified Newton for regular steps when asked):
        ``(z, factor, iterations, history)``."""
        if self.modified and p.coef is self.step_coef:
            return self.newton.solve_modified(p, z)
        return self.newton.solve(p, z)

    # ---- steps
    def initial(self, t0, q0, v0, ta: TimeArrays | None = None):
        """Consistent initial accelerations and multipliers: one saddle-point solve at ``t0``.
        Returns ``(state, factor, z)``."""
        ta = ta if ta is not None else self.time_arrays(t0)
        p = self.problem(q0, v0, self.init_coef, None, ta, t0, 0)
        z, lu, _, _ = self.solve(p, np.zeros(self.n, dtype=self.dtype))
        a = z[: self.n_dof]
        return State(t0, q0.copy(), v0.copy(), a, z[self.n_dof:] * self.scale, a.copy()), lu, z

    def step(self, st: State, t1: float, step: int, ta_old=None, ta_new=None, coef=None):
        """Advance one step from ``st`` to ``t1`` (``ta_old``, ``ta_new``: time arrays at both
        ends, when precomputed; ``coef``: coefficients of a shorter sub-step). Returns
        ``(state, factor, n_iter, z, qh, vh, R_hist, history)``."""
        coef = self.step_coef if coef is None else coef
        pc, upd = coef.arrays.pc, coef.arrays.upd
        qh, vh = np.empty_like(st.q), np.empty_like(st.q)
        newmark.predict(pc, st.q, st.v, st.a, st.g, qh, vh)
        R_hist = self.history(st, coef, ta=ta_old)
        ta_new = ta_new if ta_new is not None else self.time_arrays(t1)
        p = self.problem(qh, vh, coef, R_hist, ta_new, t1, step)
        z0 = np.concatenate([st.a, st.lam / self.scale])
        z, lu, it, hist = self.solve(p, z0)
        a = z[: self.n_dof]
        q1, v1, g1 = np.empty_like(qh), np.empty_like(qh), np.empty_like(qh)
        newmark.update(pc, upd, qh, vh, a, st.a, st.g, q1, v1, g1)
        new = State(t1, q1, v1, a, z[self.n_dof:] * self.scale, g1)
        return new, lu, it, z, qh, vh, R_hist, hist

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
            coef = _step_coefficients(self.scheme, self.method, h, self.constraint_form)
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

    def equilibrium(self, q_start, lam, t: float, step: int) -> tuple:
        """A static equilibrium at ``t`` from ``(q_start, lam)`` (:meth:`static` steppers):
        ``(q, lam, iterations, factor)``."""
        c, _, _, F, T = self.time_arrays(t)
        ta = TimeArrays(c, np.zeros_like(c), np.zeros_like(c), F, T)
        zero_v = np.zeros(self.n_dof, dtype=self.dtype)
        p = self.problem(q_start, zero_v, self.step_coef, None, ta, t, step)
        z0 = np.concatenate([np.zeros(self.n_dof, dtype=self.dtype), lam / self.scale])
        z, lu, it, _ = self.solve(p, z0)
        return q_start + z[: self.n_dof], z[self.n_dof:] * self.scale, it, lu


__all__ = ["STATIC", "Factor", "Settings", "State", "Stepper"]
