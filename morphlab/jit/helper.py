"""A second process that compiles kernels the first will need later.

Numba compiles in one thread per process, so a first use on a 2-core machine leaves a core
idle. :class:`CompileHelper` starts a process that compiles kernels into the shared cache
while this process works on its own (the main command's: :mod:`morphlab.morphing.warmup`).
The two never compile the same kernel: each signature is compiled under a lock file
(:mod:`morphlab.kernels._jit`), so a process that needs a kernel the other is compiling waits
for it and loads it from the cache. The helper's output goes to a log, shown only if it fails.
"""

from __future__ import annotations

import os
import subprocess
import sys
import tempfile
import warnings


class CompileHelper:
    """A process ``python -m module *args`` that compiles kernels (a context manager: on
    leaving, it is waited for after success, stopped after an error or an interrupt).

    Parameters
    ----------
    module : str
        The module the process runs (``python -m``).
    args : sequence of str
        Its arguments (e.g. the kernel groups to compile).
    """

    def __init__(self, module: str, args=()):
        self.module = module
        self.args = tuple(args)
        self._log = tempfile.TemporaryFile(mode="w+")
        self.process = subprocess.Popen(
            [sys.executable, "-m", module, *self.args], stdin=subprocess.DEVNULL,
            stdout=self._log, stderr=subprocess.STDOUT,
            env=dict(os.environ, PYTHONWARNINGS="ignore"))

    def close(self, stop: bool = False) -> int:
        """Wait for the helper (``stop``: terminate it first) and return its exit status. A
        failure is reported as a warning with the helper's output (the kernels it did not
        compile are compiled by whoever needs them)."""
        if self.process.returncode is None:
            if stop:
                self.process.terminate()
            self.process.wait()
        status = self.process.returncode
        if status != 0 and not stop:
            self._log.seek(0)
            tail = self._log.read()[-2000:]
            warnings.warn(f"the compile helper ({self.module} {' '.join(self.args)}) ended "
                          f"with status {status}:\n{tail}", RuntimeWarning, stacklevel=2)
        self._log.close()
        return status

    def __enter__(self) -> CompileHelper:
        return self

    def __exit__(self, exc_type, exc, tb) -> None:
        self.close(stop=exc_type is not None)
