"""The time loop: :func:`simulate` (the public entry point) and :func:`integrate`.

Each step is solved by :class:`morphlab.solve.stepper.Stepper` (generalized-alpha + Newton on
the sparse saddle-point system); this module runs the steps, stores the histories, computes the
diagnostics, reports progress, calls observers (the sensitivity strategies) and turns a failure
into an error that carries the results up to the last converged step.
"""

from __future__ import annotations

import time as _time
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from ..compile import System, compile_model
from ..compile.system import TimeTable, table_at, time_table
from ..errors import ModelError, SolverError
from ..kernels.joints import constraint_violation_history
from ..model.model import Model
from ..results.result import Result
from .linalg import Factor
from .scheme import StepCoefficients
from .settings import Settings, State
from .stepper import Stepper


@dataclass
class StepInfo:
    """What a step observer receives after each converged step (and once for the initial
    solve, with ``n == 0`` and ``prev is None``)."""

    n: int
    prev: State | None
    state: State
    lu: Factor
    z: np.ndarray
    qh: np.ndarray
    vh: np.ndarray
    coef: StepCoefficients
    stepper: Stepper
    newton_history: list = field(default_factory=list)
    table: TimeTable | None = None


def integrate(system: System, settings: Settings, *, observer: Callable | None = None,
              progress: bool | Callable = False, scale: float | None = None, q0=None, v0=None,
              polish: int = 0, max_halvings: int = 0):
    """Run the time loop on a compiled system; returns a :class:`morphlab.results.result.Result`.

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
    settings.validate()
    stepper = Stepper.dynamic(system, settings, scale=scale, polish=polish)
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


def simulate(model: Model | System, *, settings: Settings | None = None,
             progress: bool | Callable = False, observer: Callable | None = None,
             max_halvings: int = 0, q0=None, v0=None, **options):
    """Simulate ``model`` from ``t_start`` (0) to ``t_end`` with the generalized-alpha method.

    Parameters
    ----------
    model : Model or System
        The mechanism (compiled here if needed).
    settings : Settings, optional
        The run's options in one object; ``options`` replace its fields.
    **options
        The fields of :class:`~morphlab.solve.settings.Settings` (``t_end``, ``dt`` [s]
        required without ``settings``; ``rho_inf`` 0.8, ``tol`` 1e-10, ``max_iter`` 12,
        ``scheme`` "arnold-bruls" or "paper", ``newton`` "full" or "modified",
        ``stabilization``, ``stabilization_damping``, ``constraint_form``, ``t_start``,
        ``dense_max``, ``compiled_newton``).
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
    ModelError
        Invalid model or settings.
    ConvergenceError, NonFiniteError, SingularMatrixError
        With ``error.result`` holding the steps completed before the failure.
    """
    settings = Settings.of(settings, **options)
    system = model if isinstance(model, System) else compile_model(model)
    for name, x in (("q0", q0), ("v0", v0)):
        if x is not None and (np.shape(x) != (system.n_dof,) or not np.all(np.isfinite(x))):
            raise ModelError(f"{name} must be a finite array of shape ({system.n_dof},), got "
                             f"shape {np.shape(x)}")
    return integrate(system, settings, observer=observer, progress=progress,
                     max_halvings=max_halvings, q0=None if q0 is None else np.asarray(q0),
                     v0=None if v0 is None else np.asarray(v0))
