"""Static equilibrium of a model under its loads and drives at a given time."""

from __future__ import annotations

import numbers
import time as _time
from functools import partial

import numpy as np

from ..compile import System, compile_model
from ..errors import ConvergenceError, ModelError, SolverError
from ..model import Model
from ..results.checks import check_kinematic_tol, kinematic_findings, report_findings
from ..results.result import Result
from . import precompile
from .linalg import DENSE_MAX
from .scheme import _is_real
from .settings import Settings
from .stepper import Stepper


def _check_args(steps, t, tol) -> None:
    if not (isinstance(steps, numbers.Integral) and not isinstance(steps, (bool, np.bool_))
            and steps >= 1):
        raise ModelError(f"steps must be an integer >= 1, got {steps!r}")
    if not (_is_real(t) and np.isfinite(t)):
        raise ModelError(f"t must be a finite number, got {t!r}")
    if not (_is_real(tol) and 0 < tol < 1):
        raise ModelError(f"tol must be a number in (0, 1), got {tol!r}")


def static(model: Model | System, *, t: float = 0.0, steps: int = 1, tol: float = 1e-10,
           max_iter: int = 30, q_start=None, dense_max: int = DENSE_MAX,
           kinematic_tol: float | None = 1e-4):
    """Static equilibrium at time ``t`` (loads and drives evaluated at ``t``), by Newton on
    ``(q, lam)``: ``K q + J^T lam - Q_g - Q_ext = 0``, ``Phi(q, t) = 0``.

    Parameters
    ----------
    model : Model or System
    t : float
        Time at which loads and driving constraints are evaluated [s].
    steps : int
        Continuation steps: equilibria are solved at ``t_k = k t / steps`` in turn, each
        starting from the previous one (load control along the model's own profiles).
    tol : float
        Newton stops when the position correction is below ``tol`` times the model size.
    max_iter : int
        Newton iteration limit per continuation step.
    q_start : (n_dof,), optional
        Starting configuration (default: the initial configuration).
    dense_max : int
        Linear solver: see :class:`~morphlab.solve.settings.Settings`.
    kinematic_tol : float or None
        Largest estimated kinematic error of a beam's floating frames, relative to its length
        (:mod:`morphlab.results.kinematics`): above it the result's status is ``"warning"``
        with a :class:`~morphlab.errors.KinematicAccuracyWarning`; None: not checked.

    Returns
    -------
    Result
        The equilibrium path (``n_t = steps + 1``), velocities and accelerations zero.

    Notes
    -----
    The same residual and matrix kernels and the same Newton solver as the dynamic steps, with
    the coefficients :data:`morphlab.solve.stepper.STATIC`: inertia weight 0, the constraint
    rows at position level (``b0 = 1``, ``b1 = 0``, ``F_c = -Phi``) and ``a`` standing for the
    displacement from the previous equilibrium (``beta h² = 1``).

    (Long for its documentation: the code is the continuation loop and the path's result.)
    """
    _check_args(steps, t, tol)
    kinematic_tol = check_kinematic_tol(kinematic_tol)
    system = (model if isinstance(model, System)
              else compile_model(model, on_built=partial(precompile.start,
                                                         dense_max=dense_max)))
    dt = system.dtype
    q = (system.q0 if q_start is None else np.asarray(q_start)).astype(dt)
    stp = Stepper.static(system, q, tol=tol, max_iter=max_iter, dense_max=dense_max)
    n_dof = system.n_dof
    zero_v = np.zeros(n_dof, dtype=dt)
    lam = np.zeros(system.n_con, dtype=dt)
    times = np.linspace(0.0, float(t), steps + 1) if steps > 1 else np.array([0.0, float(t)])
    Q = np.zeros((len(times), n_dof), dtype=dt)
    LAM = np.zeros((len(times), system.n_con), dtype=dt)
    iters = np.zeros(len(times), dtype=np.int64)
    Q[0] = q
    t_wall = _time.perf_counter()
    settings = Settings(t_end=max(float(t), 1.0), dt=max(float(t), 1.0), tol=tol,
                        max_iter=max_iter, stabilization=0.0, dense_max=dense_max,
                        kinematic_tol=kinematic_tol)

    def result(k, status, message):
        sl = slice(0, k + 1)
        viol = np.array([np.max(np.abs(system.constraint_violation(Q[i], zero_v, times[i])[0]),
                                initial=0.0) for i in range(k + 1)])
        return Result(system=system, settings=settings, t=times[sl].copy(), q=Q[sl].copy(),
                      v=np.zeros_like(Q[sl]), a=np.zeros_like(Q[sl]), lam=LAM[sl].copy(),
                      newton_iterations=iters[sl].copy(), constraint_violation=viol,
                      velocity_violation=np.zeros(k + 1), status=status, message=message,
                      n_factorizations=stp.n_factorizations,
                      wall_time=_time.perf_counter() - t_wall, scale=stp.scale,
                      analysis="static")

    for k in range(1, len(times)):
        try:
            q, lam, iters[k], _ = stp.equilibrium(q, lam, float(times[k]), k)
        except SolverError as e:
            if isinstance(e, ConvergenceError):
                e.args = (f"static solve: {e}; try more continuation steps",)
            e.result = result(k - 1, "failed", str(e))
            if kinematic_tol is not None:  # what the path showed before it failed
                e.result.findings = kinematic_findings(e.result, kinematic_tol)
            raise
        Q[k], LAM[k] = q, lam
    out = result(len(times) - 1, "ok", f"static equilibrium at t={t:.6g}")
    if kinematic_tol is not None:
        report_findings(out, kinematic_findings(out, kinematic_tol), "warn")
    return out
