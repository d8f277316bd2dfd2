"""Static equilibrium of a model under its loads and drives at a given time."""

from __future__ import annotations

import numbers
import time as _time

import numpy as np

from ..compile import System, compile_model
from ..compile.checks import check_units
from ..compile.system import time_table
from ..errors import ConvergenceError, ModelError, SingularMatrixError, SolverError
from ..jit.progress import CompileProgress
from ..jit.threads import one_blas_thread
from ..model import Model
from ..results.checks import check_kinematic_tol, kinematic_findings, report_findings
from ..results.result import Result
from .linalg import csc_matrix
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


@one_blas_thread()
def static(model: Model | System, *, settings: StaticSettings | None = None, q_start=None,
           **options) -> Result:
    """Static equilibrium at time ``t`` (loads and drives evaluated at ``t``), by Newton on
    ``(q, lam)``: ``K q + J^T lam - Q_g - Q_ext = 0``, ``Phi(q, t) = 0``.

    Parameters
    ----------
    model : Model or System
    settings : StaticSettings, optional; **options
        Its fields: ``t`` (0), ``steps`` (1), ``tol`` (1e-10), ``max_iter`` (30),
        ``dense_max``, ``kinematic_tol`` (1e-3).
    q_start : (n_dof,), optional
        Starting configuration (default: the initial configuration).

    Returns
    -------
    Result
        The equilibrium path (``n_t = steps + 1``), velocities and accelerations zero; its
        ``settings`` the :class:`StaticSettings`.

    Raises
    ------
    SingularMatrixError
        A body that nothing holds in place (no joint, fix, drive, spring or stiffness resists
        one of its motions): the message names the bodies and their free coordinates.
    ConvergenceError
        No equilibrium within ``max_iter`` iterations (try more ``steps``).

    Notes
    -----
    The same residual and matrix kernels and the same Newton solver as the dynamic steps, with
    the coefficients :data:`morphlab.solve.stepper.STATIC`: inertia weight 0, the constraint
    rows at position level (``b0 = 1``, ``b1 = 0``, ``F_c = -Phi``) and ``a`` standing for the
    displacement from the previous equilibrium (``beta h² = 1``).

    A model with complex data (a complex step ``p + i h`` of a design variable) is solved with
    the real step matrix and one Newton iteration beyond convergence, so the imaginary part of
    the equilibrium is ``h`` times its exact derivative, also from a ``q_start`` that is
    already an equilibrium (``docs/theory.md`` §6.7).
    """
    st = StaticSettings.of(settings, **options)
    with CompileProgress("statics"):  # a notice and progress while kernels compile
        return _static(model, st, q_start)


def _static(model, st: StaticSettings, q_start) -> Result:
    """:func:`static` with its settings normalized."""
    _check(st)
    kinematic_tol = check_kinematic_tol(st.kinematic_tol)
    system = model if isinstance(model, System) else compile_model(model)
    check_units(system, float(st.t))  # warns (or raises) before anything runs
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
            elif isinstance(e, SingularMatrixError):
                free = _unsupported(stp, q, lam, k, float(times[k]))
                if free:
                    e.args = (f"static solve: {free}; ({e})",)
            e.result = result(k - 1, "failed", str(e))
            if kinematic_tol is not None:  # what the path showed before it failed
                e.result.findings = kinematic_findings(e.result, kinematic_tol)
            raise
        Q[k], LAM[k] = q, lam
    out = result(len(times) - 1, "ok", f"static equilibrium at t={st.t:.6g}")
    if kinematic_tol is not None:
        report_findings(out, kinematic_findings(out, kinematic_tol), "warn")
    return out


#: Largest number of unknowns whose singular equilibrium matrix is searched for its free
#: bodies (a dense SVD: ~1 s at this size).
UNSUPPORTED_MAX = 3000


def _unsupported(stp: Stepper, q, lam, k: int, t: float) -> str:
    """The bodies a singular equilibrium matrix leaves free, as a sentence naming them and
    their free coordinates ("" when there are none or the model is too large to search).

    The null space of the matrix at ``(q, lam)``, after scaling its rows and columns to unit
    largest entry (lengths, angles and multipliers on one footing), by a dense SVD: the
    coordinates with a component above 1e-3 in it, grouped by the body that owns them
    (``system.bodies``)."""
    system = stp.system
    n, n_dof = system.n, system.n_dof
    if n > UNSUPPORTED_MAX:
        return ""
    zero_v = np.zeros(n_dof, dtype=system.dtype)
    p = stp.problem(q, zero_v, stp.step_coef, None, stp.T, k, t, k)
    p.fill(np.concatenate([zero_v, lam / stp.scale]), stp.newton.data,
           stp.newton.W_fill)
    A = np.real(csc_matrix(stp.newton.data[0], system.indices, system.indptr, n).toarray())
    for axis in (1, 0):  # rows, then columns, to a largest entry of 1
        m = np.max(np.abs(A), axis=axis, keepdims=True)
        A = A / np.where(m > 0, m, 1.0)
    _, sigma, Vt = np.linalg.svd(A)
    null = Vt[sigma <= 1e-10 * max(sigma[0], 1e-300)]
    weight = np.sqrt(np.sum(null[:, :n_dof] ** 2, axis=0))
    owner = {}
    for name, info in system.bodies.items():
        dofs = [info.ref.ravel()]
        for extra in (info.frame_ref, info.node_dofs):
            if extra is not None:
                dofs.append(np.asarray(extra).ravel())
        for d in np.concatenate(dofs):
            if d >= 0:
                owner.setdefault(int(d), name)
    free: dict[str, list[str]] = {}
    for d in np.flatnonzero(weight > 1e-3):
        free.setdefault(owner.get(int(d), "?"), []).append(system.dof_names[d])
    if not free:
        return ""
    parts = [f"body {b!r} ({', '.join(ds[:4])}{', ...' if len(ds) > 4 else ''})"
             for b, ds in free.items()]
    return (f"nothing holds {' and '.join(parts)} in place at t={t:.6g}: a static "
            "equilibrium needs every motion of every body resisted by a joint, fix, drive, "
            "spring or a connected beam's stiffness; support the body, or simulate the "
            "mechanism")
