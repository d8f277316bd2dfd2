"""The time loop: :func:`simulate` (the public entry point) and :func:`integrate`.

The first steps of a run (the initial solve, and the step whose matrix SuperLU chooses a row
order on) are solved from Python by :class:`morphlab.solve.stepper.Stepper`; once the
factorization has settled, the steps run in compiled chunks (:func:`morphlab.kernels.steps.
run_steps`: the same kernels and arithmetic) that return to Python at the end of each chunk —
for the progress report and Ctrl-C — or at a step that needs Python (a new sparse row order,
a failure). A run with a step observer, in complex arithmetic, with modified Newton or with
``compiled_newton=False`` steps from Python throughout. This module stores the histories,
computes the diagnostics, reports progress, calls the observer or the sensitivity hook, and
turns a failure into an error that carries the results up to the last converged step.
"""

from __future__ import annotations

import signal
import threading
import time as _time
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from ..compile import System, compile_model
from ..compile.checks import check_units
from ..compile.system import time_table
from ..errors import Interrupted, ModelError, ProfileError, SolverError
from ..jit.progress import CompileProgress
from ..jit.threads import one_blas_thread
from ..kernels.newton import CONVERGED, PIVOT_REFUSED
from ..kernels.steps import run_steps
from ..model import Model
from ..results.checks import assess, report_findings
from ..results.result import Result
from .linalg import Factor
from .record import keep_record
from .scheme import StepCoefficients
from .settings import Settings, State
from .stepper import StepOutcome, Stepper
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


class StepHook:
    """What a sensitivity method does during the primal run (its base class; the direct and
    adjoint methods of :mod:`morphlab.sensitivity` subclass it).

    ``rows``: the rows of the Newton fill (3: the Newton matrix with ``Dq`` and ``Dv``);
    :meth:`python_step` is called after each step solved from Python (the initial solve
    included); :meth:`kernels` gives the compiled chunk of steps ``k0 .. k1 - 1`` the record
    it writes (``keep`` of :func:`~morphlab.kernels.steps.run_steps`, or None) and
    :meth:`after_chunk` follows it with the steps ``k0 .. k - 1`` it converged; :meth:`chunk`
    may shorten a chunk (a record has a capacity)."""

    rows = 1

    def start(self, stepper: Stepper, hist: HistoryStore) -> None:
        """Called once, before the initial solve."""

    def python_step(self, k: int, outcome: StepOutcome) -> None:
        """Step ``k``, solved from Python, has converged."""

    def kernels(self, k0: int, k1: int):
        return None

    def after_chunk(self, k0: int, k: int) -> None:
        """The compiled chunk converged the steps ``k0 .. k - 1``."""

    def chunk(self, k0: int, k1: int) -> int:
        return k1


def _check_options(settings: Settings, observer, hook, max_halvings) -> None:
    """Refuse the options that contradict each other or an observer; validate ``settings``."""
    watched = observer is not None or hook is not None
    if settings.newton == "modified" and watched:
        raise ModelError("newton='modified' cannot be combined with an observer: the "
                         "sensitivities need the exact Newton matrix of every step")
    if max_halvings and watched:
        raise ModelError("automatic step reduction cannot be combined with an observer "
                         "(sensitivity runs need one fixed step sequence)")
    if not (isinstance(max_halvings, int) and 0 <= max_halvings <= 20):
        raise ModelError(f"max_halvings must be an integer in [0, 20], got {max_halvings!r}")
    settings.validate()


def _time_table(system: System, settings: Settings, t: np.ndarray, hist: HistoryStore):
    """The time values of the run, and None; when a time profile fails at step ``k > 0``, the
    table of the steps before it and that error (raised at once, with an empty result, at
    step 0)."""
    try:
        return time_table(system, t), None
    except ProfileError as err:
        if err.step == 0:
            err.result = Result(system=system, settings=settings, status="failed",
                                message=str(err), **hist.result_fields())
            raise
        return time_table(system, t[:err.step]), err


@one_blas_thread()
def integrate(system: System, settings: Settings, *, observer: Callable | None = None,
              hook: StepHook | None = None, progress: bool | Callable = False,
              scale: float | None = None, q0=None, v0=None, polish: int = 0,
              max_halvings: int = 0, store=HISTORIES, memmap=None) -> Result:
    """Run the time loop on a compiled system; returns a :class:`morphlab.results.Result`.

    ``observer(info: StepInfo)`` is called after the initial solve and after every converged
    step (the run then steps from Python throughout); ``hook``: a sensitivity method's
    :class:`StepHook`. On failure the raised :class:`SolverError` carries the results up to
    the last converged step as ``error.result``; an interrupt (Ctrl-C, or a KeyboardInterrupt
    from the observer or the progress callback) raises :class:`~morphlab.errors.Interrupted`
    (a KeyboardInterrupt) carrying them the same way. ``max_halvings > 0`` retries a failed
    step with up to ``2**max_halvings`` sub-steps (not with an observer: sensitivity runs need
    the same step sequence for every design); the results stay on the regular grid and
    ``result.step_reductions`` lists ``(t, n_substeps)`` of each retried step. ``store``,
    ``memmap``: :class:`~morphlab.solve.store.HistoryStore`.
    """
    _check_options(settings, observer, hook, max_halvings)
    check_units(system, settings.t_end)  # warns (or raises) before anything runs
    n_steps = settings.n_steps
    check_memory(system, n_steps + 1, store, memmap)
    t = settings.t_start + settings.h * np.arange(n_steps + 1)
    hist = HistoryStore(system, t, store, memmap, settings.max_iter)
    T, failure = _time_table(system, settings, t, hist)
    if failure is not None:  # run the steps before the failing time, then raise it
        n_steps = failure.step - 1
    with CompileProgress("time loop"):  # a notice and progress while kernels compile
        stepper = Stepper.dynamic(system, settings, T, scale=scale, polish=polish,
                                  rows=hook.rows if hook is not None else 1)
        loop = _Loop(system, settings, stepper, hist, T, t, n_steps, observer, hook,
                     progress, max_halvings, q0, v0)
        result = loop.run()
    if failure is not None:  # the steps before the profile failed: a failed run's result
        result.status, result.message = "failed", str(failure)
        failure.result = result
        raise failure
    report_findings(result, assess(result, settings.constraint_tol, settings.kinematic_tol),
                    settings.checks)
    return result


class _Loop:
    """The steps of one run (module docstring)."""

    def __init__(self, system, settings, stepper, hist, T, t, n_steps, observer, hook,
                 progress, max_halvings, q0, v0):
        self.system, self.settings, self.stepper, self.hist = system, settings, stepper, hist
        self.T, self.t, self.n_steps = T, t, n_steps
        self.observer, self.hook, self.max_halvings = observer, hook, max_halvings
        self.report = progress if callable(progress) else (_print_progress if progress
                                                           else None)
        dt = system.dtype
        self.q0 = (system.q0 if q0 is None else q0).astype(dt)
        self.v0 = (system.v0 if v0 is None else v0).astype(dt)
        self.reductions: list = []
        self.logged = np.zeros(t.size, dtype=np.int64)  # Newton log rows of each step
        self.t_wall = _time.perf_counter()
        self.per_step = None  # measured wall time of a compiled step [s]
        self.python_next = False  # the last chunk stopped at a step Python must solve

    def make_result(self, status: str, message: str) -> Result:
        fields = self.hist.result_fields()
        n = self.hist.n_done + 1
        offsets = np.zeros(n + 1, dtype=np.int64)
        offsets[1:] = np.cumsum(self.logged[:n])
        H = self.hist.H
        fields["newton_log"] = (np.concatenate([H.newton[k, :self.logged[k]] for k in range(n)])
                                if n else np.zeros((0, 2)))
        fields["newton_log_offsets"] = offsets
        return Result(system=self.system, settings=self.settings, status=status,
                      message=message, n_factorizations=self.stepper.n_factorizations,
                      wall_time=_time.perf_counter() - self.t_wall, scale=self.stepper.scale,
                      step_reductions=list(self.reductions), **fields)

    def compiled(self) -> bool:
        """Can the next steps run in compiled chunks?"""
        s, nw = self.settings, self.stepper.newton
        return (self.observer is None and s.compiled_newton and s.newton == "full"
                and self.system.dtype.kind == "f" and nw.polish == 0
                and nw.factorization.settled)

    def run(self) -> Result:
        stepper, hist, t = self.stepper, self.hist, self.t
        with _Interrupts() as interrupts:
            try:
                if self.hook is not None:
                    self.hook.start(stepper, hist)
                st, lu, z = stepper.initial(t[0], self.q0, self.v0)
                hist.record(0, st, 1, ())
                self.logged[0] = 0
                outcome = StepOutcome(st, lu, 1, z, st.q, st.v, None, np.zeros((0, 2)))
                self.after(0, None, outcome)
                n = 1
                while n <= self.n_steps:
                    interrupts.check()
                    if self.compiled():
                        n = self.chunk(n)
                        if n > self.n_steps:
                            break
                        if not self.python_next:  # on in chunks (the interrupt checked first)
                            continue
                    prev = hist.state(n - 1)
                    out = stepper.advance(prev, float(t[n]), n, self.max_halvings,
                                          self.reductions)
                    hist.record(n, out.state, out.iterations, out.newton)
                    self.logged[n] = len(out.newton)
                    self.after(n, prev, out)
                    n += 1
            except SolverError as err:
                err.result = self.make_result("failed", str(err))
                err.result.findings = assess(err.result, self.settings.constraint_tol,
                                             self.settings.kinematic_tol)
                if err.result.findings:  # what the run showed before it failed
                    err.args = (f"{err}; before it: " + "; ".join(
                        f.message for f in err.result.findings),)
                raise
            except KeyboardInterrupt as err:
                k = hist.n_done
                stop = Interrupted(f"interrupted after step {k} (t={t[max(k, 0)]:.6g})",
                                   time=float(t[k]) if k >= 0 else None, step=k,
                                   result=self.make_result("interrupted",
                                                           "interrupted by the user"))
                raise stop from err
        return self.make_result("ok", f"completed {self.n_steps} steps")

    def after(self, n: int, prev, out: StepOutcome) -> None:
        """The observer, the hook and the progress report after a step solved from Python."""
        if self.hook is not None:
            self.hook.python_step(n, out)
        if self.observer is not None:
            coef = self.stepper.init_coef if n == 0 else self.stepper.step_coef
            self.observer(StepInfo(n, prev, out.state, out.factor, out.z, out.qh, out.vh,
                                   coef, self.stepper, out.newton))
        if self.report is not None and n > 0:
            self.report(n, self.n_steps, float(self.t[n]))

    def chunk(self, n: int) -> int:
        """Steps from ``n`` in one compiled call; returns the next step to solve (a step
        that needs Python: a new sparse row order)."""
        stp, nw = self.stepper, self.stepper.newton
        seconds = self.settings.chunk_seconds  # the work of a chunk (its wall time)
        if self.per_step is None:  # before a step was timed: a few steps
            size = 8 if seconds > 0 else 1
        else:
            size = max(1, int(seconds / self.per_step))
        k1 = min(self.n_steps + 1, n + size)
        keep = None
        if self.hook is not None:
            k1 = self.hook.chunk(n, k1)
            keep = self.hook.kernels(n, k1)
        F = nw.factorization.loop_arrays()
        if keep is None:  # an empty record: the compiled loop of a primal and a sensitivity
            keep = keep_record(self.system, F, 0, n, nw.data.shape[0] == 3)  # run is one
        w0 = _time.perf_counter()
        k, status, bad, it, z = run_steps(stp.M, self.T, stp.P, stp.scheme_of(), nw.csc, F,
                                          nw.options(), nw.work(), self.hist.H, n, k1, keep)
        if k > n:
            self.per_step = (_time.perf_counter() - w0) / (k - n)
        H = self.hist.H
        self.logged[n:k] = H.iters[n:k]
        nw.n_factorizations += int(H.iters[n:k].sum())
        self.hist.n_done = k - 1
        if self.hook is not None:
            self.hook.after_chunk(n, k)
        if self.report is not None and k > n:
            self.report(k - 1, self.n_steps, float(self.t[k - 1]))
        self.python_next = status != CONVERGED  # step k needs Python (a new row order...)
        if status == CONVERGED or status == PIVOT_REFUSED:
            if status == PIVOT_REFUSED:
                nw.n_factorizations += it - 1
            return k
        if self.max_halvings > 0:  # step k again from Python, which can sub-step it
            nw.n_factorizations += it
            return k
        # a failure at step k: the error of the step-by-step solver, with the step's problem
        prev = self.hist.state(k - 1)
        p = _problem_at(stp, prev, float(self.t[k]), k)
        nw.outcome(p, z, it, status, bad, F)
        raise AssertionError("unreachable")  # pragma: no cover


def _problem_at(stp: Stepper, st: State, t1: float, k: int):
    """The step problem of step ``k`` from ``st`` (for the messages of a failed chunk)."""
    from ..kernels import newmark

    coef = stp.step_coef
    qh, vh = np.empty_like(st.q), np.empty_like(st.q)
    newmark.predict(coef.arrays.pc, st.q, st.v, st.a, st.g, qh, vh)
    return stp.problem(qh, vh, coef, stp.history(st, coef, stp.T, k - 1), stp.T, k, t1, k)


class _Interrupts:
    """Ctrl-C during a run: while the default SIGINT handler is installed (main thread), a
    first SIGINT only sets a flag, which the loop checks between steps or chunks of steps (so
    it never arrives inside a compiled call, whose result would then be lost); a second one
    interrupts at once."""

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


@one_blas_thread()
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
        Invalid model or settings; a model that declares its units (``model.units``) with a
        material, gravity or mass far outside them (:func:`morphlab.compile.checks.
        check_units`, which otherwise warns: :class:`~morphlab.errors.UnitsWarning`).
    ConstraintViolationError
        A joint violated beyond 10 times ``constraint_tol`` (:mod:`morphlab.results.checks`),
        with ``error.result`` the whole run and ``time``, ``step`` where it went beyond.
    ResourceError
        The histories asked for do not fit the memory available (the message gives the size).
    Interrupted
        Ctrl-C (a KeyboardInterrupt) with ``error.result`` holding the completed steps.
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
                     v0=None if v0 is None else np.asarray(v0), store=store, memmap=memmap)
