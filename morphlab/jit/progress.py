"""What the user sees while the kernels compile: a notice at the first compilation, then a
line of progress every few seconds, and the total at the end.

Numba compiles a kernel the first time it meets a new kind of model (a new set of item kinds,
dense or sparse step matrices, real or complex numbers) and caches the machine code on disk;
later processes load it without compiling. A kernel that another process is compiling (a
compile helper, a second test worker) is waited for, and the wait is reported like a
compilation. Compilation is detected exactly, from Numba's
compile events (a load from the cache sends none), so nothing is printed when the kernels are
cached, and a long compilation is never silent for more than :attr:`CompileProgress.every`
seconds.

The estimates are the compile CPU measured on the reference machine, the one of the records in
BENCHMARKS.md (2 cores, empty cache; ``python -m morphlab.bench --cases compile``): the sum
over every compilation of a scenario, for the time loop of a model like the README
quickstart's and of one with every item kind, for each sensitivity method on top of a compiled
time loop, and for the flight loads' statics. The notice says so. It does not scale them to
this machine: a short timing of this machine's speed is no guide to a compile of half a minute
on a virtual machine whose speed changes from second to second (a Python loop's time per
iteration there has switched between about 35 and 65 ns every second or so, while the compile
of one scenario varied by about a tenth from round to round). The compile bench keeps the
estimates beside what it measured, which shows how far they are off on the machine it ran on.
"""

from __future__ import annotations

import sys
import threading
import time

from numba.core import event

from ..kernels._jit import LOCKS

#: Compile CPU [s] of a first use on the reference machine (module docstring): the compile
#: bench's "all compilations" at commit b01da0b, kept in docs/benchmarks-history.md (median of
#: two rounds; the statics: the flight loads' :func:`~morphlab.morphing.aeroelastic.
#: warm_statics` from an empty cache, two runs: 30.3 and 33.6 CPU-s).
ESTIMATES = {"time loop": 36.0, "time loop, every item kind": 63.0, "statics": 32.0,
             "direct": 14.0, "direct-fd": 15.4, "adjoint": 19.3, "complex-step": 15.0}

_active: list = []  # the reporter of the outermost run (nested runs report through it)


class CompileProgress(event.Listener):
    """Report the compilations of morphlab's kernels during a ``with`` block.

    Parameters
    ----------
    what : str
        What is being compiled, for the messages (a key of :data:`ESTIMATES` gives the
        estimate).
    stream : file, optional
        Where the lines go (default ``sys.stderr``).
    every : float
        Seconds between progress lines while compiling.
    """

    def __init__(self, what: str, stream=None, every: float = 5.0):
        self.what = what
        self.stream = stream
        self.every = every
        self.count = 0  # kernels compiled
        self.depth = 0  # nesting of compile events in progress
        self.current = ""
        self.started = None  # (wall, cpu) of the first compilation
        self._stop = threading.Event()
        self._thread = None

    # ---- the listener
    def on_start(self, ev) -> None:
        disp = ev.data.get("dispatcher")
        name = getattr(getattr(disp, "py_func", None), "__qualname__", "?")
        self.depth += 1
        self.current = name
        if self.started is None:
            self.started = (time.perf_counter(), time.process_time())
            self._notice()

    def on_end(self, ev) -> None:
        self.depth -= 1
        self.count += 1

    def on_wait(self, lock: str) -> None:
        """This process waits for a kernel another one is compiling (a lock file of
        :mod:`morphlab.kernels._jit`: ``module.kernel.<signature hash>.lock``)."""
        self.current = lock.rsplit(".", 2)[0].rsplit(".", 1)[-1] + " (another process)"
        if self.started is None:
            self.started = (time.perf_counter(), time.process_time())
            self._notice()

    # ---- the messages
    def _print(self, text: str) -> None:
        print(f"morphlab: {text}", file=self.stream or sys.stderr, flush=True)

    def _notice(self) -> None:
        from .cache import kernel_cache_dir

        estimate = ESTIMATES.get(self.what)
        about = ("" if estimate is None else
                 f"; about {estimate:.0f} CPU-s on the 2-core reference machine of the "
                 "benchmarks")
        if estimate is not None and self.what == "time loop":
            about += f", {ESTIMATES['time loop, every item kind']:.0f} with every item kind"
        self._print(f"compiling the numerical kernels of the {self.what} for this kind of "
                    f"model (first use only: cached in {kernel_cache_dir()}){about}")
        self._thread = threading.Thread(target=self._tick, daemon=True)
        self._thread.start()

    def _tick(self) -> None:
        while not self._stop.wait(self.every):
            wall = time.perf_counter() - self.started[0]
            self._print(f"  ... still compiling: {self.count} kernels done, now "
                        f"{self.current}, {wall:.0f} s")

    # ---- the block
    def __enter__(self) -> CompileProgress:
        if _active:  # a run inside a run (a sensitivity method's primal): one report
            return _active[0]
        _active.append(self)
        event.register("numba:compile", self)
        LOCKS.on_wait.append(self.on_wait)
        return self

    def __exit__(self, *exc) -> None:
        if not _active or _active[0] is not self:
            return
        _active.pop()
        event.unregister("numba:compile", self)
        LOCKS.on_wait.remove(self.on_wait)
        self._stop.set()
        if self.started is not None:
            wall = time.perf_counter() - self.started[0]
            cpu = time.process_time() - self.started[1]
            self._print(f"compiled {self.count} kernels in {wall:.1f} s ({cpu:.1f} CPU-s); "
                        "later runs load them from the cache")
