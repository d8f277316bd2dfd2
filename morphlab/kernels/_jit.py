"""The one Numba configuration of the kernels: three decorators.

* :func:`kernel`: a kernel Python calls. Compiled on first call for the types of its
  arguments (float64 and complex128 alike), cached on disk (``cache=True``).
* :func:`inner`: a kernel only other kernels call. Compiled and cached the same way, but
  without the wrapper that converts Python arguments: for a function that takes a system's
  arrays (tens of arrays in nested tuples), generating that wrapper is most of its compile
  time, and an inner kernel never needs it. Called from Python it raises ``TypeError`` (with
  ``NUMBA_DISABLE_JIT=1``, for debugging, every kernel is the plain Python function).
  ``inner(forceinline=True)`` marks it for LLVM to inline into its callers: typed and
  compiled once, without the cost of a call where it runs.
* :func:`inlined`: a helper Numba inlines into its callers before typing them; no kernel of
  its own.

Inlining at Numba level types the helper's body again at every call site: about a CPU-second
for a point's value and derivatives (:func:`~morphlab.kernels.joints.side_terms`), which the
rows, the spring-dampers, the slides and the point loads took at eight call sites between
them. So a helper of some size with several call sites is ``inner(forceinline=True)``, and
:func:`inlined` is for a helper with one call site, a trivial one, or one in a loop whose speed
needs it: ``side_terms`` called through an LLVM-inlined kernel from the rows' side made the
morphing primal 15 % slower, so the rows keep it inlined at Numba level
(:data:`~morphlab.kernels.joints.point_terms` is the LLVM-inlined one the other kinds call).

``nogil=True`` (:func:`kernel` with ``nogil``) releases the GIL while a long kernel runs.

What a kernel's compile costs includes its callees' code: Numba links the code of every kernel
a kernel calls into the caller's own module and emits it there again (each cached kernel is
self-contained), so a kernel that only forwards to others emits all of them once more, and
every signature compiled for Python (``kernel``) or for kernels (``inner``) is a separate
emission. A level between a Python entry and the per-item kernels pays only where it is the
one caller of a large closure; a second entry over the same closure (a Python-callable twin
of a step the compiled loop takes) costs about as much as the closure's emission, not as
little as its wrapper.

That wrapper has its own price: it unboxes every array of the arguments (in nested tuples
too) and passes each on as seven or more scalars, about 6 ms of compile an array (a kernel
taking a tuple of 120 arrays: 0.8 CPU-s with its wrapper, 0.1 without). So a kernel Python
calls is given what it reads, and None for the rest: the design's shares get the system with
the bodies' kinds alone and no perturbed path's data where no variable takes that path, the
adjoint's sweep and the direct method's chunk no system where they form no matrix
(``morphlab.sensitivity.adjoint._share_inputs``, ``morphlab.sensitivity.designs.
system_read``).

About half of a kernel's compile time is Numba's own, in Python: typing the kernel and
lowering it to LLVM IR, in proportion to the code it writes (each array access, each array of
a tuple passed on); the other half is LLVM's optimization and machine code for the kernel's
module, its callees' code included (the compile bench's LLVM row: ``morphlab.bench.compile``).
Neither half yields to a setting: a lower LLVM optimization level (``NUMBA_OPT``) saves a
small part of the LLVM half and slows every run, and inner kernels compiled without reference
counting compile no faster. Less code, emitted fewer times, is what shortens it.

Numba would also turn each inner kernel's own library into machine code, and optimize its
module as a whole before its callers link it in and optimize it again: work whose result no one
runs. The kernels' libraries are :class:`_Library`: an inner kernel's, and those of the
functions Numba compiles for a kernel, are optimized function by function, linked and cached as
LLVM IR; only a kernel Python calls gets machine code, for its whole module, as before. The
same machine code runs; the compile is shorter by the inner kernels' share of LLVM's work. What
runs through a pointer keeps its machine code: a block of a kernel lifted out to run in object
mode, a parallel loop's body, a kernel Python calls. ``MORPHLAB_INNER_IR_ONLY=0`` turns this
off (Numba's own library for every kernel), and so does a Numba whose internals it relies on
differ (:data:`IR_ONLY` says which).

Processes that share a cache (the workers of ``pytest -n 2`` or of a parameter study, the
main command and its compile helper) compile each kernel once between them: a process
compiles a signature of a kernel holding a lock file for that signature, and a second
process that needs it waits and then loads it from the cache instead of compiling it again
(:class:`CacheLocks`). Writing a kernel's cache index is locked per kernel too: Numba reads,
extends and rewrites one index per kernel, so two processes adding different signatures at
once could otherwise drop one or give two signatures the same data file.
"""

from __future__ import annotations

import contextlib
import ctypes
import hashlib
import os
import re
import time
import warnings

from numba import njit
from numba.core import event, sigutils
from numba.core.codegen import JITCodeLibrary
from numba.core.compiler_lock import global_compiler_lock
from numba.core.environment import lookup_environment
from numba.core.registry import CPUDispatcher

try:
    import fcntl
except ImportError:  # pragma: no cover - not POSIX: no locks across processes
    fcntl = None


class CacheLocks:
    """Lock files beside the cached kernels, held across processes (``flock``).

    A lock is taken only while Numba's compiler lock is held, so one thread per process
    takes them; a lock this process already holds (a kernel compiled inside another one's
    compilation) is not taken again. A holder that died releases its lock with its process.
    A lock not obtained within :attr:`timeout` seconds (a holder stopped, not dead) is given
    up with a warning: the kernel is then compiled without it, as Numba would.
    """

    timeout = 600.0  #: seconds, far above any one kernel's compilation
    poll = 0.02  #: seconds between attempts

    def __init__(self):
        self.held: set = set()
        #: Called with the lock's name when this process starts waiting for it.
        self.on_wait: list = []

    @contextlib.contextmanager
    def hold(self, folder: str | None, name: str):
        """Hold the lock ``name`` in ``folder`` (no lock without a folder or ``fcntl``)."""
        if folder is None or fcntl is None:
            yield
            return
        path = os.path.join(folder, "locks", name)
        if path in self.held:
            yield
            return
        try:
            os.makedirs(os.path.dirname(path), exist_ok=True)
            fd = os.open(path, os.O_RDWR | os.O_CREAT, 0o666)
        except OSError:  # a read-only cache folder: Numba caches nothing there either
            yield
            return
        try:
            if self._acquire(fd, path, name):
                self.held.add(path)
            yield
        finally:
            self.held.discard(path)
            os.close(fd)  # releases the lock

    def _acquire(self, fd: int, path: str, name: str) -> bool:
        deadline = time.monotonic() + self.timeout
        waiting = False
        while True:
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
                return True
            except BlockingIOError:
                if not waiting:
                    waiting = True
                    for f in self.on_wait:
                        f(name)
                if time.monotonic() > deadline:
                    warnings.warn(f"kernel cache lock {path} still held by another process "
                                  f"after {self.timeout:.0f} s: compiling without it",
                                  RuntimeWarning, stacklevel=4)
                    return False
                time.sleep(self.poll)


#: The locks of this process.
LOCKS = CacheLocks()


def _cache_folder(dispatcher) -> str | None:
    return getattr(getattr(dispatcher, "_cache", None), "_cache_path", None)


def _kernel_name(dispatcher) -> str:
    """The kernel's module and qualified name, as a file name (``<lambda>`` -> ``_lambda_``)."""
    f = dispatcher.py_func
    return re.sub(r"[^\w.]", "_", f"{f.__module__}.{f.__qualname__}")


class KernelDispatcher(CPUDispatcher):
    """The dispatcher of a :func:`kernel`: compiles a signature under its lock file, so a
    process sharing the cache loads it rather than compiling it too (module docstring)."""

    def compile(self, sig):
        with global_compiler_lock:
            args, _ = sigutils.normalize_signature(sig)
            existing = self.overloads.get(tuple(args))
            if existing is not None:
                return existing.entry_point
            name = _kernel_name(self)
            key = hashlib.sha1(f"{name}{args}".encode()).hexdigest()[:20]
            _COMPILING.append(self)
            try:
                with LOCKS.hold(_cache_folder(self), f"{name}.{key}.lock"):
                    return super().compile(sig)
            finally:
                _COMPILING.pop()


#: The dispatchers compiling, innermost last (under Numba's compiler lock: one thread): the
#: kernels from their ``compile`` (a cache load included), any other (Numba's overloads, an
#: object-mode block lifted out of a kernel) from Numba's compile event (:class:`_Compiles`).
_COMPILING: list = []


class _Compiles(event.Listener):
    """Keeps :data:`_COMPILING` for the dispatchers that are not kernels."""

    def on_start(self, ev):
        d = ev.data["dispatcher"]
        if not isinstance(d, KernelDispatcher):
            _COMPILING.append(d)

    def on_end(self, ev):
        d = ev.data["dispatcher"]
        if not isinstance(d, KernelDispatcher):
            for i in range(len(_COMPILING) - 1, -1, -1):
                if _COMPILING[i] is d:
                    del _COMPILING[i]
                    break


def _links_only(name: str) -> bool:
    """Whether the library ``name`` made now holds code only other kernels' modules run: the
    own library of an inner kernel, or of a function Numba compiles with a plain ``njit``
    dispatcher (its overloads) for a kernel. Not a kernel Python calls, not a block lifted
    out of a kernel to run in object mode (called through a pointer), not a library a
    compilation makes besides its own (a subroutine, a parallel loop's body)."""
    top = _COMPILING[-1] if _COMPILING else None
    if top is None or name != getattr(getattr(top, "py_func", None), "__qualname__", None):
        return False
    if isinstance(top, KernelDispatcher):
        return isinstance(top, InnerDispatcher)
    return type(top) is CPUDispatcher and any(isinstance(d, KernelDispatcher)
                                              for d in _COMPILING)


class _Library(JITCodeLibrary):
    """Numba's code library, kept as LLVM IR when only other kernels' code runs it
    (:func:`_links_only`).

    That is the library of an :func:`inner` kernel and of every function Numba compiles for a
    kernel with a plain dispatcher (its overloads: ``np.empty``, ``max``, ...): a kernel
    called from Python holds a copy of all their code in its own module, which LLVM
    optimizes as a whole and turns into machine code; the machine code Numba would emit for
    their own libraries is never called, and the optimization of their own modules is done
    again in the caller's. Such a library is optimized function by function (Numba's
    per-function passes, as before it is linked), kept as IR for linking and cached as
    bitcode; nothing else of it is compiled. Every other library is Numba's, unchanged."""

    def __init__(self, codegen, name, **kwargs):
        super().__init__(codegen, name, **kwargs)
        self._ir_only = _links_only(name)

    def _optimize_final_module(self):
        if not self._ir_only:
            super()._optimize_final_module()

    def _finalize_final_module(self):
        if not self._ir_only:
            super()._finalize_final_module()
            self._set_linked_environments()
            return
        # what Numba checks of a finished module; it is not added to the JIT engine
        self._finalize_dynamic_globals()
        self._verify_declare_only_symbols()
        self._finalized = True

    def _set_linked_environments(self):
        """Point the environments of the IR-only code linked into this module at their
        objects. Numba sets a function's environment when its own library enters the engine
        (an IR-only library never does) and a cached kernel's environments when it is loaded;
        a kernel compiled now finds those of its inner kernels here (an object-mode block in
        one reads it)."""
        engine = self._codegen._engine
        for gv in self._final_module.global_variables:
            if not gv.name.startswith("_ZN08NumbaEnv"):
                continue
            addr = engine.get_global_value_address(gv.name)
            env = lookup_environment(gv.name)
            if addr and env is not None and not ctypes.c_void_p.from_address(addr).value:
                ctypes.c_void_p.from_address(addr).value = id(env)

    def serialize_using_object_code(self):
        if not self._ir_only:
            return super().serialize_using_object_code()
        self._ensure_finalized()  # Numba's loader takes 'bitcode' as it is (no new passes)
        return (self.name, "bitcode", self._get_module_for_linking().as_bitcode())


#: The Numba internals :class:`_Library` relies on; without one of them (another Numba
#: layout) Numba's own library is kept and every library is compiled to machine code.
_NEEDS = ("_finalize_dynamic_globals", "_verify_declare_only_symbols", "_optimize_final_module",
          "_finalize_final_module", "_get_module_for_linking", "_ensure_finalized",
          "serialize_using_object_code")


def _use_ir_only_libraries() -> bool:
    """Make :class:`_Library` the library class of Numba's CPU code generator (unless
    ``MORPHLAB_INNER_IR_ONLY=0``, or Numba's layout differs). Returns whether it is."""
    from numba.core.registry import cpu_target

    if os.environ.get("MORPHLAB_INNER_IR_ONLY", "1") == "0":
        return False
    codegen = cpu_target.target_context.codegen()
    if getattr(codegen, "_library_class", None) is _Library:
        return True
    if (getattr(codegen, "_library_class", None) is not JITCodeLibrary
            or not all(hasattr(JITCodeLibrary, a) for a in _NEEDS)
            or not hasattr(getattr(codegen, "_engine", None), "get_global_value_address")):
        return False
    set_env = codegen.set_env

    def set_env_if_defined(env_name, env):
        # an IR-only library is not in the JIT engine, so neither is its environment: the
        # kernel it is linked into sets its copy (_Library._set_linked_environments)
        if codegen._engine.get_global_value_address(env_name):
            set_env(env_name, env)

    codegen.set_env = set_env_if_defined
    codegen._library_class = _Library
    event.register("numba:compile", _Compiles())
    return True


class InnerDispatcher(KernelDispatcher):
    """The dispatcher of an :func:`inner` kernel: callable from kernels only."""

    def __call__(self, *args, **kws):
        raise TypeError(f"{self.py_func.__module__}.{self.py_func.__qualname__} is a kernel "
                        "other kernels call: it has no Python entry")


#: Whether the kernels' inner libraries are kept as IR (:class:`_Library`).
IR_ONLY = _use_ir_only_libraries()


def _locked_saves(d, cls):
    """``d`` as a ``cls`` whose cache index is written under the kernel's lock."""
    if not isinstance(d, CPUDispatcher):  # NUMBA_DISABLE_JIT returns the function itself
        return d
    d.__class__ = cls
    cache = d._cache
    save = cache.save_overload

    def save_overload(sig, data):
        with LOCKS.hold(_cache_folder(d), f"{_kernel_name(d)}.index.lock"):
            save(sig, data)

    cache.save_overload = save_overload
    return d


def kernel(fn=None, *, nogil: bool = False):
    """Compile ``fn`` as a kernel Python calls (module docstring)."""
    if fn is None:
        return lambda f: kernel(f, nogil=nogil)
    return _locked_saves(njit(cache=True, nogil=nogil)(fn), KernelDispatcher)


def inner(fn=None, *, forceinline: bool = False):
    """Compile ``fn`` as a kernel only kernels call (module docstring); ``forceinline``: LLVM
    inlines it into every caller."""
    if fn is None:
        return lambda f: inner(f, forceinline=forceinline)
    return _locked_saves(njit(cache=True, no_cpython_wrapper=True, no_cfunc_wrapper=True,
                              forceinline=forceinline)(fn), InnerDispatcher)


def inlined(fn):
    """Inline ``fn`` into the kernels that call it, at Numba level (no kernel of its own).
    Each call site types it again (module docstring), so it is for a helper with one call
    site."""
    return njit(inline="always")(fn)
