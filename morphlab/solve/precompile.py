"""A second process that compiles part of a cold run's kernels while the run compiles the rest.

Numba compiles one function at a time in a process, and the kernels of a first run take most
of its time (``morphlab.solve.cache``). When the cache is cold and the machine has a second
core, :func:`start` launches a helper process (:func:`main`) that compiles the kernels of
:func:`primal_jobs` for the run's exact argument types and caches them on disk, while the run
compiles the kernels it meets first (the constraint checks and the step matrix); when the run
reaches a kernel the helper has cached, it loads it instead of compiling it.
:func:`morphlab.simulate` and :func:`morphlab.static` start the helper as soon as the model's
arrays are built.

Numba's cache keeps one index file per function, rewritten whenever an overload is added, so
two processes must not save overloads of one function at the same time (the index could end
up naming the other's machine code). While the helper runs, every kernel dispatcher of the
run's process is guarded: before it loads from or saves to the cache a kernel the helper is
compiling at that moment, it waits until the helper has saved it (the helper reports on its
standard output each compilation it starts and each overload it has saved). The guards go
when the helper ends; the run never waits for the helper otherwise.

The helper is skipped on a warm cache, on a single core, under ``NUMBA_DISABLE_JIT``, inside
another helper, for runs with a step observer (sensitivity runs, which compile complex
kernels), and when ``MORPHLAB_COMPILE_HELPER=0``. It starts in a session of its own, so a
Ctrl-C that interrupts the run leaves it to finish its few kernels; a helper that fails only
costs the time it would have saved: the run compiles what it finds missing.
"""

from __future__ import annotations

import importlib
import os
import pickle
import subprocess
import sys
import threading

import numba
import numpy as np

from ..compile.system import System, TimeTable, kernel_arrays, table_at, time_table
from .cache import kernels_cached
from .linalg import DENSE_MAX, empty_loop_arrays
from .newton import NewtonSolver, StepProblem
from .scheme import GeneralizedAlpha, step_coefficients
from .superlu import PIVOT_THRESHOLD

#: Environment variable: ``0`` switches the helper off.
ENV = "MORPHLAB_COMPILE_HELPER"

_helper: _Helper | None = None


def primal_jobs(system: System, table: TimeTable, dense_max: int = DENSE_MAX
                ) -> list[tuple[str, str, tuple]]:
    """``(module, kernel, signature)`` of what the helper compiles for a time integration of
    ``system`` (time data ``table``; step matrices factored dense up to ``dense_max``
    unknowns), in order: the step residual, the factor and solve kernels of the compiled
    Newton loop, and the loop, typed as
    :class:`~morphlab.solve.newton.StepProblem` and
    :class:`~morphlab.solve.newton.NewtonSolver` call them. (The run compiles the step matrix
    meanwhile, in the checks of the model, and the loop finds it cached.)"""
    dt, n, n_dof = system.dtype, system.n, system.n_dof
    coef = step_coefficients("arnold-bruls", GeneralizedAlpha(0.8), 1.0)
    p = StepProblem(system, kernel_arrays(system), np.zeros(n_dof, dt), np.zeros(n_dof, dt),
                    coef, np.zeros(n, dt), table_at(table, 0), 1.0, 0.0, 0.0, 0.0, 0)
    solver = NewtonSolver(system, dt, tol=1e-10, max_iter=2, dense_max=0)
    arrays = empty_loop_arrays(dt, dense=n <= dense_max)
    loop = solver.loop_args(p, np.zeros(n, dt), np.zeros(n, dt), arrays, np.zeros((2, 2)))
    LU, piv, Lx, Ux, Ud, order, pattern = arrays
    block = np.zeros((n, 1), dtype=dt)  # newton_loop's correction and scratch
    jobs = [
        ("morphlab.kernels.assemble", "step_residual",
         p.residual_args(np.zeros(n, dt), n_dof, np.zeros(n, dt))),
        ("morphlab.kernels.newton", "factor_matrix",
         (solver.data, system.indices, system.indptr, LU, piv, Lx, Ux, Ud, order, pattern,
          PIVOT_THRESHOLD)),
        ("morphlab.kernels.newton", "solve_factored",
         (block, block, LU, piv, Lx, Ux, Ud, pattern)),
        ("morphlab.kernels.newton", "newton_loop", loop),
    ]
    return [(module, name, tuple(numba.typeof(a) for a in args)) for module, name, args in jobs]


def enabled() -> bool:
    """Would a cold run start the helper here (cores, settings; not the cache)?"""
    if os.environ.get(ENV, "1") == "0" or os.environ.get("NUMBA_DISABLE_JIT", "0") != "0":
        return False
    try:
        cores = len(os.sched_getaffinity(0))
    except AttributeError:  # pragma: no cover - platforms without affinity
        cores = os.cpu_count() or 1
    return cores >= 2


def start(system: System, table: TimeTable | None = None, dense_max: int = DENSE_MAX) -> None:
    """Launch the helper for a run of ``system`` (time data ``table``, by default evaluated
    at t = 0: only its types matter; ``dense_max`` of the run's settings) if the cache is
    cold (module docstring)."""
    global _helper
    if _helper is not None or kernels_cached() or not enabled():
        return
    try:
        if table is None:
            table = time_table(system, np.zeros(1))
    except Exception:  # noqa: BLE001 - a failing profile is the run's to report
        return
    try:
        _helper = _Helper(pickle.dumps(primal_jobs(system, table, dense_max)))
    except Exception:  # noqa: BLE001 - no helper: the run compiles everything itself
        _helper = None


def wait(timeout: float | None = None) -> bool:
    """Wait until the helper of this process (if any) has ended and its guards are gone;
    False if it is still running after ``timeout`` seconds."""
    helper = _helper
    if helper is None:
        return True
    helper.reader.join(timeout)
    return not helper.reader.is_alive()


def _kernel_dispatchers() -> dict:
    """Every compiled kernel of ``morphlab.kernels``, by ``module.qualname``."""
    from numba.core.registry import CPUDispatcher

    out = {}
    for name, module in list(sys.modules.items()):
        if name.startswith("morphlab.kernels.") and module is not None:
            for obj in vars(module).values():
                if isinstance(obj, CPUDispatcher):
                    out[_key(obj.py_func)] = obj
    return out


def _key(py_func) -> str:
    return f"{py_func.__module__}.{py_func.__qualname__}"


class _Guard:
    """A dispatcher's cache that waits for the helper before touching a kernel it compiles."""

    def __init__(self, inner, key: str, helper: _Helper):
        self._inner, self._key, self._helper = inner, key, helper

    def load_overload(self, sig, target_context):
        self._helper.wait_for(self._key)
        return self._inner.load_overload(sig, target_context)

    def save_overload(self, sig, data):
        self._helper.wait_for(self._key)
        return self._inner.save_overload(sig, data)

    def __getattr__(self, name):
        return getattr(self._inner, name)


class _Helper:
    """The helper process, the thread reading its reports, and the guards."""

    def __init__(self, jobs: bytes):
        env = dict(os.environ, **{ENV: "0"})  # no helper of the helper
        self.proc = subprocess.Popen(
            [sys.executable, "-c", "from morphlab.solve.precompile import main; main()"],
            stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, env=env,
            start_new_session=os.name == "posix")
        self.cond = threading.Condition()
        self.busy: set[str] = set()  # kernels the helper is compiling now
        self.alive = True
        self.guarded = _kernel_dispatchers()
        for key, disp in self.guarded.items():
            disp._cache = _Guard(disp._cache, key, self)
        self.reader = threading.Thread(target=self._read, daemon=True)
        try:
            self.proc.stdin.write(jobs)
            self.proc.stdin.close()
        finally:  # the reader removes the guards when the helper ends, however it ends
            self.reader.start()

    def _read(self) -> None:
        for line in self.proc.stdout:
            what, _, key = line.decode(errors="replace").strip().partition(" ")
            with self.cond:
                if what == "start":
                    self.busy.add(key)
                elif what == "end":
                    self.busy.discard(key)
                self.cond.notify_all()
        self.proc.wait()
        with self.cond:
            self.alive = False
            self.busy.clear()
            self.cond.notify_all()
        self._unguard()

    def wait_for(self, key: str) -> None:
        with self.cond:
            while self.alive and key in self.busy:
                self.cond.wait(1.0)

    def _unguard(self) -> None:
        for disp in self.guarded.values():
            if isinstance(disp._cache, _Guard):
                disp._cache = disp._cache._inner


# ------------------------------------------------------------------------- the helper process
def _report(line: str) -> None:
    try:
        sys.stdout.write(line + "\n")
        sys.stdout.flush()
    except (BrokenPipeError, ValueError):  # the run has ended: finish the kernels all the same
        pass


class _Starts(numba.core.event.Listener):
    """Reports each kernel compilation the helper starts."""

    def on_start(self, event):
        func = getattr(event.data.get("dispatcher"), "py_func", None)
        if func is not None and func.__module__.startswith("morphlab.kernels."):
            _report(f"start {_key(func)}")

    def on_end(self, event):
        pass


class _Saves:
    """A dispatcher's cache in the helper that reports each overload once it is saved."""

    def __init__(self, inner, key: str):
        self._inner, self._key = inner, key

    def save_overload(self, sig, data):
        try:
            return self._inner.save_overload(sig, data)
        finally:
            _report(f"end {self._key}")

    def __getattr__(self, name):
        return getattr(self._inner, name)


def main() -> None:
    """The helper: compile the jobs pickled on standard input, in order, reporting on standard
    output when each kernel's compilation starts (``start <kernel>``) and when it is saved
    (``end <kernel>``)."""
    jobs = pickle.loads(sys.stdin.buffer.read())
    kernels = [getattr(importlib.import_module(module), name) for module, name, _ in jobs]
    for key, disp in _kernel_dispatchers().items():
        disp._cache = _Saves(disp._cache, key)
    numba.core.event.register("numba:compile", _Starts())
    for disp, (_, _, sig) in zip(kernels, jobs):
        disp.compile(sig)
