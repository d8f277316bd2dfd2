"""Static equilibrium of a model under its loads and drives at a given time."""

from __future__ import annotations

import numbers
import time as _time

import numpy as np

from ..compile import System, compile_model
from ..compile.system import time_table
from ..errors import ConvergenceError, ModelError, SolverError
from ..model import Model
from ..results.checks import check_kinematic_tol, kinematic_findings, report_findings
from ..results.result import Result
from .scheme import _is_real
from .settings import StaticSettings
from .stepper import Stepper


def _check(s: StaticSettings) -> None:
    if not (isinstance(s.steps, numbers.Integral) and not isinstance(s.steps, (bool, np.bool_))
            and s.steps >= 1):
        raise ModelError(f"steps must be an integer >= 1, got {s.steps!r}")
    if not (_is_real(s.t) and np.isfinite(s.t)):
        raise ModelError(f"t must be a finite number, got {s.t!r}")
    if not (_is_real(s.tol) and 0 < s.tol < 1):
        raise ModelError(f"tol must be a number in (0, 1), got {s.tol!r}")


def _static_times(system: System, times: np.ndarray):
    """The time values of the continuation, with the drives' rates zero (a static target)."""
    T = time_table(system, times)
    return T._replace(**{name: tt._replace(cd=np.zeros_like(tt.cd), cdd=np.zeros_like(tt.cdd))
                         for name, tt in zip(T._fields, T)
                         if tt is not None and hasattr(tt, "cd")})


def static(model: Model | System, *, settings: StaticSettings | None = None, q_start=None,
           **options) -> Result:
    """Static equilibrium at time ``t`` (loads and drives evaluated at ``t``), by Newton on
    ``(q, lam)``: ``K q + J^T lam - Q_g - Q_ext = 0``, ``Phi(q, t) = 0``.

    Parameters
    ----------
    model : Model or System
    settings : StaticSettings, optional; **options
        Its fields: ``t`` (0), ``steps`` (1), ``tol`` (1e-10), ``max_iter`` (30),
        ``dense_max``, ``kinematic_tol`` (1e-4).
    q_start : (n_dof,), optional
        Starting configuration (default: the initial configuration).

    Returns
    -------
    Result
        The equilibrium path (``n_t = steps + 1``), velocities and accelerations zero; its
        ``settings`` the :class:`StaticSettings`.

    Notes
    -----
    The same residual and matrix kernels and the same Newton solver as the dynamic steps, with
    the coefficients :data:`morphlab.solve.stepper.STATIC`: inertia weight 0, the constraint
    rows at position level (``b0 = 1``, ``b1 = 0``, ``F_c = -Phi``) and ``a`` standing for the
    displacement from the previous equilibrium (``beta h² = 1``).
    """
    st = StaticSettings.of(settings, **options)
    _check(st)
    kinematic_tol = check_kinematic_tol(st.kinematic_tol)
    system = model if isinstance(model, System) else compile_model(model)
    dt = system.dtype
    q = (system.q0 if q_start is None else np.asarray(q_start)).astype(dt)
    times = (np.linspace(0.0, float(st.t), st.steps + 1) if st.steps > 1
             else np.array([0.0, float(st.t)]))
    T = _static_times(system, times)
    stp = Stepper.static(system, q, T, tol=st.tol, max_iter=st.max_iter,
                         dense_max=st.dense_max)
    n_dof = system.n_dof
    zero_v = np.zeros(n_dof, dtype=dt)
    lam = np.zeros(system.n_con, dtype=dt)
    Q = np.zeros((len(times), n_dof), dtype=dt)
    LAM = np.zeros((len(times), system.n_con), dtype=dt)
    iters = np.zeros(len(times), dtype=np.int64)
    Q[0] = q
    t_wall = _time.perf_counter()

    def result(k, status, message):
        sl = slice(0, k + 1)
        viol = np.array([np.max(np.abs(system.constraint_violation(Q[i], zero_v, times[i])[0]),
                                initial=0.0) for i in range(k + 1)])
        return Result(system=system, settings=st, t=times[sl].copy(), q=Q[sl].copy(),
                      v=np.zeros_like(Q[sl]), a=np.zeros_like(Q[sl]), lam=LAM[sl].copy(),
                      newton_iterations=iters[sl].copy(), constraint_violation=viol,
                      velocity_violation=np.zeros(k + 1), status=status, message=message,
                      n_factorizations=stp.n_factorizations,
                      wall_time=_time.perf_counter() - t_wall, scale=stp.scale,
                      analysis="static")

    for k in range(1, len(times)):
        try:
            q, lam, iters[k], _ = stp.equilibrium(q, lam, k, float(times[k]))
        except SolverError as e:
            if isinstance(e, ConvergenceError):
                e.args = (f"static solve: {e}; try more continuation steps",)
            e.result = result(k - 1, "failed", str(e))
            if kinematic_tol is not None:  # what the path showed before it failed
                e.result.findings = kinematic_findings(e.result, kinematic_tol)
            raise
        Q[k], LAM[k] = q, lam
    out = result(len(times) - 1, "ok", f"static equilibrium at t={st.t:.6g}")
    if kinematic_tol is not None:
        report_findings(out, kinematic_findings(out, kinematic_tol), "warn")
    return out
