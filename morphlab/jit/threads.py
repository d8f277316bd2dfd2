"""One BLAS thread while morphlab computes.

NumPy's and SciPy's OpenBLAS start a thread per core for a product or a solve they deem large
enough, and those threads then spin, waiting for the next call, for about a tenth of a second.
morphlab's time loop and sensitivity kernels do not use BLAS (Numba kernels on their own
sparse LU), and its NumPy set-up and post-processing (initial velocities, rank checks,
stresses, NeuralFoil's small networks, the panel method) gain nothing from a second thread at
these sizes. So a run that calls BLAS once spends most of a second core spinning while its
compiled loop works alone: about 30 % more CPU than wall time for the 240-element skin's
primal, and on a machine whose cores are busy (a second worker of a sweep, a test worker)
the spinning threads and the other process slow each other down. :class:`one_blas_thread`
sets the BLAS libraries loaded in the process (``threadpoolctl``) to one thread for the
duration of a call and restores their setting after the outermost one ends; the public
entry points (``simulate``, ``static``, ``sensitivities``, the flow analysis) run under it.
BLAS calls of the user's own code outside these calls are untouched.
"""

from __future__ import annotations

import functools
import threading

_LOCK = threading.Lock()
_state = {"depth": 0, "saved": [], "controller": None}


def _blas_libraries() -> list:
    """threadpoolctl's controllers of the BLAS libraries loaded in the process (found once:
    morphlab's imports have loaded NumPy's and SciPy's by the first call)."""
    if _state["controller"] is None:
        from threadpoolctl import ThreadpoolController

        _state["controller"] = ThreadpoolController()
    return [lc for lc in _state["controller"].lib_controllers if lc.user_api == "blas"]


class one_blas_thread:  # noqa: N801 - used as a decorator, like a function
    """Run the block (or the decorated function) with one BLAS thread (module docstring).
    Nested and concurrent uses share one setting: the first to enter sets it, the last to
    leave restores the threads the libraries had."""

    def __call__(self, fn):
        """``fn`` run inside the block. The wrapper is defined here, in the package, so that
        a warning raised inside still points at the user's line
        (:func:`morphlab.errors.warn` skips the package's frames)."""

        @functools.wraps(fn)
        def call(*args, **kwargs):
            with self:
                return fn(*args, **kwargs)

        return call

    def __enter__(self) -> one_blas_thread:
        with _LOCK:
            if _state["depth"] == 0:
                saved = [(lc, lc.get_num_threads()) for lc in _blas_libraries()]
                for lc, n in saved:
                    if n != 1:
                        lc.set_num_threads(1)
                _state["saved"] = saved
            _state["depth"] += 1
        return self

    def __exit__(self, *exc) -> bool:
        with _LOCK:
            _state["depth"] -= 1
            if _state["depth"] == 0:
                for lc, n in _state["saved"]:
                    if n != 1:
                        lc.set_num_threads(n)
                _state["saved"] = []
        return False


def blas_threads() -> list[int]:
    """The thread count of each BLAS library loaded in the process (for tests and checks)."""
    return [lc.get_num_threads() for lc in _blas_libraries()]
