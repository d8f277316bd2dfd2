"""Work a gradient needs only after the primal run, done beside it on a spare core.

The adjoint reads the variables' changes and the pseudo-load data
(:func:`~morphlab.sensitivity.designs.changes`, :func:`~morphlab.sensitivity.designs.
pseudo_data`) when its backward sweep begins, after the primal run. Forming them is Python and
NumPy work: the user's ``build`` once per variable, then each changed design's rows. The
primal's compiled steps (:func:`~morphlab.kernels.steps.run_steps`) release the interpreter
lock, so where a second core is idle (:func:`spare_core`) that work runs in a thread while the
steps run. The gradient then takes the wall time of the primal and the sweep, not of their sum with
the set-up; the CPU time is the same, and so are the results, bit for bit (the same calls in
another thread; the primal reads the nominal system only).

:class:`Beside` is started by the run's hook after the first compiled chunk of steps (not
before, where it would compete with the run's own Python set-up for the interpreter), and a
failure of the work (a variable ``build`` does not use, a design that changes the structure)
is raised at the next chunk boundary, at most ``Settings.chunk_seconds`` of steps later, not at
the end of the run. The work runs in a copy of the caller's context variables, NumPy's error
state among them (``np.errstate``), as it would in the caller's thread. With one usable core,
or ``overlap=False``, the work runs where the sweep asks for it, in the caller's thread.
"""

from __future__ import annotations

import contextvars
import os
import threading
from collections.abc import Callable
from concurrent.futures import Future, ThreadPoolExecutor

_POOL: dict = {}
_LOCK = threading.Lock()
_IN_WORKER = threading.local()  # set while the worker thread runs a piece of work


def _forget_pool() -> None:
    """In a forked child: the parent's worker thread does not exist there, and work queued on
    its executor would wait for ever; the child makes a pool of its own when it needs one."""
    global _LOCK
    _POOL.clear()
    _LOCK = threading.Lock()


if hasattr(os, "register_at_fork"):  # POSIX: process pools that fork (a sweep's workers)
    os.register_at_fork(after_in_child=_forget_pool)


def usable_cores() -> int:
    """The cores this process may run on (its CPU affinity, else the machine's count)."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # pragma: no cover - platforms without affinity (macOS, Windows)
        return os.cpu_count() or 1


def others_running() -> float:
    """How many threads of the machine run or wait to run besides the caller: Linux's
    instantaneous count (``/proc/loadavg``'s fourth field, less the caller), else the
    one-minute load average less one."""
    try:
        with open("/proc/loadavg") as f:
            return float(f.read().split()[3].split("/")[0]) - 1.0
    except (OSError, IndexError, ValueError):
        try:
            return max(0.0, os.getloadavg()[0] - 1.0)
        except (AttributeError, OSError):  # pragma: no cover - no load average at all
            return 0.0


def spare_core() -> bool:
    """Is a core free for the worker thread: at least two usable cores, and fewer other
    threads running than the cores besides the caller's? The worker only pays where a core
    is idle: beside another busy process (a sweep's second worker, a test worker) the two
    threads slow each other, which costs CPU and gains no wall time."""
    n = usable_cores()
    return n >= 2 and others_running() < n - 1


def _pool() -> ThreadPoolExecutor:
    """The one worker thread of the process (made on first use; later uses queue on it)."""
    with _LOCK:
        if "pool" not in _POOL:
            _POOL["pool"] = ThreadPoolExecutor(max_workers=1,
                                               thread_name_prefix="morphlab-beside")
        return _POOL["pool"]


def in_worker() -> bool:
    """Is the caller the worker thread (running a piece of work)?"""
    return getattr(_IN_WORKER, "on", False)


def submit(fn: Callable[[], object], context: contextvars.Context | None = None
           ) -> Future | None:
    """``fn()`` queued on the worker thread, in ``context`` (default: a copy of the caller's
    context variables), after the work queued before it; None from the worker thread itself,
    which would wait for its own thread (a gradient inside a piece of work, say a ``build``
    that runs one): the caller then runs ``fn`` where it is."""
    if in_worker():
        return None
    ctx = contextvars.copy_context() if context is None else context

    def run():
        _IN_WORKER.on = True
        try:
            return fn()
        finally:
            _IN_WORKER.on = False

    return _pool().submit(ctx.run, run)


class Beside:
    """``fn()`` computed beside the primal run (module docstring).

    Parameters
    ----------
    fn : callable
        The work, without arguments; it must read nothing the primal run writes.
    overlap : bool
        Run it in the worker thread once :meth:`start` is called; False: in the caller's
        thread, when :meth:`result` is first asked for.
    """

    def __init__(self, fn: Callable[[], object], overlap: bool):
        self.fn, self.overlap = fn, overlap
        # the caller's context variables (NumPy's error state among them), which a thread
        # does not inherit: the work sees what it would see in the caller's thread
        self.context = contextvars.copy_context()
        self.future: Future | None = None
        self._value = None
        self._done = False

    @property
    def started(self) -> bool:
        """Has the work been handed to the worker thread?"""
        return self.future is not None

    def start(self) -> None:
        """Hand the work to the worker thread (once; nothing without ``overlap``, nor from
        the worker thread itself: see :func:`submit`)."""
        if self.overlap and self.future is None and not self._done:
            self.future = submit(self.fn, self.context)

    def check(self) -> None:
        """Raise the work's error now if it has already failed (between chunks of steps)."""
        f = self.future
        if f is not None and f.done() and f.exception() is not None:
            f.result()  # raises it, with its traceback

    def result(self):
        """The work's value: waited for if it runs beside, computed here if it never started;
        its error raised."""
        if self.future is not None:
            return self.future.result()
        if not self._done:
            self._value, self._done = self.fn(), True
        return self._value
