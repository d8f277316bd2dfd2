"""The time loop: :func:`simulate` (the public entry point) and :func:`integrate`.

Each step is solved by :class:`morphlab.solve.stepper.Stepper` (generalized-alpha + Newton on
the sparse saddle-point system); this module runs the steps, stores the histories, computes the
diagnostics, reports progress, calls observers (the sensitivity strategies) and turns a failure
into an error that carries the results up to the last converged step.
"""

from __future__ import annotations

import signal
import threading
import time as _time
from collections.abc import Callable
from dataclasses import dataclass, field
from functools import partial

import numpy as np

from ..compile import System, compile_model
from ..compile.system import TimeTable, table_at, time_table
from ..errors import Interrupted, ModelError, ProfileError, SolverError
from ..model import Model
from ..results.checks import assess, report_findings
from ..results.result import Result
from . import precompile
from .cache import announce_compilation
from .linalg import Factor
from .scheme import StepCoefficients
from .settings import Settings, State
from .stepper import Stepper
from .store import HISTORIES, HistoryStore, check_memory


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
    newton_history: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))
    table: TimeTable | None = None


def _check_options(settings: Settings, observer, max_halvings) -> None:
    """Refuse the options that contradict each other or an observer; validate ``settings``."""
    if settings.newton == "modified" and observer is not None:
        raise ModelError("newton='modified' cannot be combined with an observer: the "
                         "sensitivities need the exact Newton matrix of every step")
    if max_halvings and observer is not None:
        raise ModelError("automatic step reduction cannot be combined with an observer "
                         "(sensitivity runs need one fixed step sequence)")
    if not (isinstance(max_halvings, int) and 0 <= max_halvings <= 20):
        raise ModelError(f"max_halvings must be an integer in [0, 20], got {max_halvings!r}")
    settings.validate()


def _time_table(system: System, settings: Settings, t: np.ndarray,
                hist: HistoryStore) -> tuple[TimeTable, ProfileError | None]:
    """The time table of the run, and None; when a time profile fails at step ``k > 0``, the
    table of the steps before it and that error (raised at once, with an empty result, at
    step 0)."""
    try:
        return time_table(system, t), None
    except ProfileError as err:
        if err.step == 0:
            err.result = Result(system=system, settings=settings, status="failed",
                                message=str(err), **hist.result_fields(None))
            raise
        return time_table(system, t[:err.step]), err


def integrate(system: System, settings: Settings, *, observer: Callable | None = None,
              progress: bool | Callable = False, scale: float | None = None, q0=None, v0=None,
              polish: int = 0, max_halvings: int = 0, store=HISTORIES, memmap=None) -> Result:
    """Run the time loop on a compiled system; returns a :class:`morphlab.results.Result`.

    ``observer(info: StepInfo)`` is called after the initial solve and after every converged
    step; the sensitivity strategies use it. On failure the raised :class:`SolverError` carries
    the results up to the last converged step as ``error.result``; an interrupt (Ctrl-C, or a
    KeyboardInterrupt from the observer or the progress callback) raises
    :class:`~morphlab.errors.Interrupted` (a KeyboardInterrupt) carrying them the same way.
    ``max_halvings > 0`` retries a failed step with up to ``2**max_halvings`` sub-steps (not
    with an observer: sensitivity runs need the same step sequence for every design); the
    results stay on the regular grid and ``result.step_reductions`` lists ``(t, n_substeps)``
    of each retried step. ``store``, ``memmap``: :class:`~morphlab.solve.store.HistoryStore`.
    """
    _check_options(settings, observer, max_halvings)
    announce_compilation()
    n_steps = settings.n_steps
    check_memory(system, n_steps + 1, store, memmap)
    t = settings.t_start + settings.h * np.arange(n_steps + 1)
    hist = HistoryStore(system, t, store, memmap)
    table, failure = _time_table(system, settings, t, hist)
    if observer is None:  # a sensitivity run compiles other signatures of the same kernels
        precompile.start(system, table, settings.dense_max)
    return _run(system, settings, t, hist, table, failure, observer=observer,
                progress=progress, scale=scale, q0=q0, v0=v0, polish=polish,
                max_halvings=max_halvings)


def _run(system, settings, t, hist, table, failure, *, observer, progress, scale, q0, v0,
         polish, max_halvings) -> Result:
    """The time loop of :func:`integrate`."""
    n_steps = settings.n_steps
    stepper = Stepper.dynamic(system, settings, scale=scale, polish=polish)
    if failure is not None:  # run the steps before the failing time, then raise it
        n_steps = failure.step - 1
    reductions: list = []
    t_wall = _time.perf_counter()

    def make_result(status, message):
        return Result(system=system, settings=settings, status=status, message=message,
                      n_factorizations=stepper.n_factorizations,
                      wall_time=_time.perf_counter() - t_wall, scale=stepper.scale,
                      step_reductions=list(reductions), **hist.result_fields(table))

    dt = system.dtype
    q_init = (system.q0 if q0 is None else q0).astype(dt)
    v_init = (system.v0 if v0 is None else v0).astype(dt)
    report = progress if callable(progress) else (_print_progress if progress else None)
    with _Interrupts() as interrupts:
        try:
            st, lu, z = stepper.initial(t[0], q_init, v_init, ta=table_at(table, 0))
            hist.record(0, st, 1, (), table_at(table, 0))
            if observer is not None:
                observer(StepInfo(0, None, st, lu, z, st.q, st.v, stepper.init_coef, stepper,
                                  table=table))
            ta_old = table_at(table, 0)
            for n in range(1, n_steps + 1):
                interrupts.check()
                ta = table_at(table, n)
                new, lu, it, z, qh, vh, R_hist, newton = stepper.advance(
                    st, float(t[n]), n, ta_old, ta, max_halvings, reductions)
                hist.record(n, new, it, newton, ta)
                if observer is not None:
                    observer(StepInfo(n, st, new, lu, z, qh, vh, stepper.step_coef, stepper,
                                      newton, table=table))
                st, ta_old = new, ta
                if report is not None:
                    report(n, n_steps, float(t[n]))
        except SolverError as err:
            err.result = make_result("failed", str(err))
            err.result.findings = assess(err.result, settings.constraint_tol,
                                         settings.kinematic_tol)
            if err.result.findings:  # what the run showed before it failed
                err.args = (f"{err}; before it: " + "; ".join(
                    f.message for f in err.result.findings),)
            raise
        except KeyboardInterrupt as err:
            k = hist.n_done
            stop = Interrupted(f"interrupted after step {k} (t={t[max(k, 0)]:.6g})",
                               time=float(t[k]) if k >= 0 else None, step=k,
                               result=make_result("interrupted", "interrupted by the user"))
            raise stop from err
    if failure is not None:
        failure.result = make_result("failed", str(failure))
        raise failure
    result = make_result("ok", f"completed {n_steps} steps")
    report_findings(result, assess(result, settings.constraint_tol, settings.kinematic_tol),
                    settings.checks)
    return result


class _Interrupts:
    """Ctrl-C during a run: while the default SIGINT handler is installed (main thread), a
    first SIGINT only sets a flag, which the loop checks between steps (so it never arrives
    inside a compiled call, whose result would then be lost); a second one interrupts at
    once."""

    def __init__(self):
        self.flag = False
        self.previous = None

    def _handler(self, signum, frame):
        if self.flag:
            raise KeyboardInterrupt
        self.flag = True

    def check(self) -> None:
        if self.flag:
            raise KeyboardInterrupt

    def __enter__(self):
        if (threading.current_thread() is threading.main_thread()
                and signal.getsignal(signal.SIGINT) is signal.default_int_handler):
            self.previous = signal.signal(signal.SIGINT, self._handler)
        return self

    def __exit__(self, *exc):
        if self.previous is not None:
            signal.signal(signal.SIGINT, self.previous)
        return False


def _print_progress(n, n_steps, t):
    width = 30
    if n == n_steps or n % max(1, n_steps // 50) == 0:
        done = int(width * n / n_steps)
        end = "\n" if n == n_steps else "\r"
        print(f"[{'#' * done}{'.' * (width - done)}] step {n}/{n_steps} t={t:.4g}", end=end,
              flush=True)


def simulate(model: Model | System, *, settings: Settings | None = None,
             progress: bool | Callable = False, observer: Callable | None = None,
             max_halvings: int = 0, q0=None, v0=None, store=HISTORIES, memmap=None,
             **options):
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
    store : tuple of {"q", "v", "a", "lam"}
        The histories kept (default all four); the others are ``None`` in the Result. Each
        takes ``n_t x width x 8`` bytes (16 for a complex run).
    memmap : path, optional
        Keep the histories in memory-mapped ``.npy`` files in this folder instead of memory.

    Returns
    -------
    Result
        Stacked histories and statistics.

    Raises
    ------
    ModelError
        Invalid model or settings.
    ResourceError
        The histories asked for do not fit the memory available (the message gives the size).
    Interrupted
        Ctrl-C (a KeyboardInterrupt) with ``error.result`` holding the completed steps.
    ConvergenceError, NonFiniteError, SingularMatrixError
        With ``error.result`` holding the steps completed before the failure.
    """
    settings = Settings.of(settings, **options)
    helper = partial(precompile.start, dense_max=settings.dense_max)
    system = model if isinstance(model, System) else compile_model(
        model, on_built=helper if observer is None else None)
    for name, x in (("q0", q0), ("v0", v0)):
        if x is not None and (np.shape(x) != (system.n_dof,) or not np.all(np.isfinite(x))):
            raise ModelError(f"{name} must be a finite array of shape ({system.n_dof},), got "
                             f"shape {np.shape(x)}")
    return integrate(system, settings, observer=observer, progress=progress,
                     max_halvings=max_halvings, q0=None if q0 is None else np.asarray(q0),
                     v0=None if v0 is None else np.asarray(v0), store=store, memmap=memmap)
