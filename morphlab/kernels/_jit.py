"""The one Numba configuration of the kernels: two decorators.

* :func:`kernel`: a kernel Python calls. Compiled on first call for the types of its
  arguments (float64 and complex128 alike), cached on disk (``cache=True``).
* :func:`inner`: a kernel only other kernels call. Compiled and cached the same way, but
  without the wrapper that converts Python arguments: for a function that takes a system's
  arrays (tens of arrays in nested tuples), generating that wrapper is most of its compile
  time, and an inner kernel never needs it. Called from Python it raises ``TypeError`` (with
``NUMBA_DISABLE_JIT=1``, for debugging, every kernel is the plain Python function).

``nogil=True`` (:func:`kernel` with ``nogil``) releases the GIL while a long kernel runs.
"""

from numba import njit
from numba.core.registry import CPUDispatcher


class InnerDispatcher(CPUDispatcher):
    """The dispatcher of an :func:`inner` kernel: callable from kernels only."""

    def __call__(self, *args, **kws):
        raise TypeError(f"{self.py_func.__module__}.{self.py_func.__qualname__} is a kernel "
                        "other kernels call: it has no Python entry")


def kernel(fn=None, *, nogil: bool = False):
    """Compile ``fn`` as a kernel Python calls (module docstring)."""
    if fn is None:
        return lambda f: njit(cache=True, nogil=nogil)(f)
    return njit(cache=True, nogil=nogil)(fn)


def inner(fn):
    """Compile ``fn`` as a kernel only kernels call (module docstring)."""
    d = njit(cache=True, no_cpython_wrapper=True, no_cfunc_wrapper=True)(fn)
    if isinstance(d, CPUDispatcher):  # not with NUMBA_DISABLE_JIT, which returns ``fn``
        d.__class__ = InnerDispatcher
    return d


def inlined(fn):
    """Inline ``fn`` into the kernels that call it, at Numba level (no call of its own): for
    the small helpers of the per-row loops, whose calls would cost a sizable part of a step.
    Each call site types it again, so it is for helpers called from few places."""
    return njit(inline="always")(fn)
