"""Static equilibrium of a model under its loads and drives at a given time."""

from __future__ import annotations

import numbers
import time as _time

import numpy as np

from ..compile import System, compile_model
from ..errors import ConvergenceError, ModelError, NonFiniteError
from ..model.model import Model
from .scheme import StepCoefficients, _is_real
from .stepper import Settings, Stepper


def static(model: Model | System, *, t: float = 0.0, steps: int = 1, tol: float = 1e-10,
           max_iter: int = 30, q_start=None):
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

    Returns
    -------
    Result
        The equilibrium path (``n_t = steps + 1``), velocities and accelerations zero.

    Notes
    -----
    Uses the residual and matrix kernels of the dynamic solver with the inertia weight 0, the
    constraint rows at position level (``b0 = 1``, ``b1 = 0``, ``F_c = -Phi``) and ``a`` standing
    for the Newton correction of ``q`` (``beta h² = 1``).
    """
    from ..errors import SolverError
    from ..results.result import Result

    if not (isinstance(steps, numbers.Integral) and not isinstance(steps, (bool, np.bool_))
            and steps >= 1):
        raise ModelError(f"steps must be an integer >= 1, got {steps!r}")
    if not (_is_real(t) and np.isfinite(t)):
        raise ModelError(f"t must be a finite number, got {t!r}")
    if not (_is_real(tol) and 0 < tol < 1):
        raise ModelError(f"tol must be a number in (0, 1), got {tol!r}")
    system = model if isinstance(model, System) else compile_model(model)
    settings = Settings(t_end=max(float(t), 1.0), dt=max(float(t), 1.0), tol=tol,
                        max_iter=max_iter, stabilization=0.0)
    stp = Stepper(system, settings, scale=1.0)
    stp.b0, stp.b1 = 1.0, 0.0
    coef = StepCoefficients(1.0, (0.0, 1.0, 1.0, 0.0, 1.0), None, 1.0, 0.0)
    n_dof = system.n_dof
    L = system.length_scale
    dt = system.dtype
    zero_v = np.zeros(n_dof, dtype=dt)
    R0 = np.zeros(system.n, dtype=dt)
    q = (system.q0 if q_start is None else np.asarray(q_start)).astype(dt)
    lam = np.zeros(system.n_con, dtype=dt)
    # scale the constraint rows like the stiffness diagonal
    stp._fill(np.zeros(system.n, dtype=dt), q, zero_v, 0.0, coef, scale=1.0)
    d = np.abs(np.real(stp.matrix().diagonal()[:n_dof]))
    stp.scale = float(np.median(d[d > 0])) if np.any(d > 0) else 1.0
    times = np.linspace(0.0, float(t), steps + 1) if steps > 1 else np.array([0.0, float(t)])
    Q = np.zeros((len(times), n_dof), dtype=dt)
    LAM = np.zeros((len(times), system.n_con), dtype=dt)
    iters = np.zeros(len(times), dtype=np.int64)
    Q[0] = q
    t_wall = _time.perf_counter()

    def result(k, status, message):
        sl = slice(0, k + 1)
        viol = np.array([np.max(np.abs(system.constraint_violation(Q[i], zero_v, times[i])[0]),
                                initial=0.0) for i in range(k + 1)])
        return Result(system=system, settings=settings, t=times[sl].copy(), q=Q[sl].copy(),
                      v=np.zeros_like(Q[sl]), a=np.zeros_like(Q[sl]), lam=LAM[sl].copy(),
                      newton_iterations=iters[sl].copy(), constraint_violation=viol,
                      velocity_violation=np.zeros(k + 1), status=status, message=message,
                      n_factorizations=stp.n_factorizations,
                      wall_time=_time.perf_counter() - t_wall, scale=stp.scale)

    for k in range(1, len(times)):
        tk = float(times[k])
        c, cd, cdd, F, T = stp.time_arrays(tk)
        ta = (c, cd * 0, cdd * 0, F, T)
        err = np.inf
        it = 0
        for it in range(1, max_iter + 1):  # noqa: B007 - it is recorded after the loop
            z = np.concatenate([np.zeros(n_dof, dtype=dt), lam / stp.scale])
            R = stp.residual(z, q, zero_v, tk, coef, R0, time_arrays=ta)
            if not np.all(np.isfinite(R)):
                e = NonFiniteError(f"static solve: non-finite residual at t={tk:.6g}", time=tk,
                                   step=k, residual=float("nan"))
                e.result = result(k - 1, "failed", str(e))
                raise e
            try:
                lu = stp.factor(z, q, zero_v, tk, coef)
            except SolverError as e:
                e.step = k
                e.result = result(k - 1, "failed", str(e))
                raise
            dz = lu.solve(-R)
            q = q + dz[:n_dof]
            lam = (z[n_dof:] + dz[n_dof:]) * stp.scale
            err = float(np.max(np.abs(dz[:n_dof]))) / L
            if err <= tol:
                break
        else:
            e = ConvergenceError(
                f"static solve did not converge at t={tk:.6g} (continuation step {k}) in "
                f"{max_iter} iterations: position correction {err:.3g} of the model size; "
                f"dominant equations: {', '.join(stp.dominant(R))}; try more steps",
                time=tk, step=k, residual=float(np.linalg.norm(R)), dominant=stp.dominant(R))
            e.result = result(k - 1, "failed", str(e))
            raise e
        Q[k], LAM[k], iters[k] = q, lam, it
    return result(len(times) - 1, "ok", f"static equilibrium at t={t:.6g}")
