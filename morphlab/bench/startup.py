"""Benchmark case ``startup``: a warm start, the kernels loaded from a filled Numba cache.

Three kinds of fresh process, interleaved round by round, each run as a user runs it (a
script, with nothing of the bench imported into it):

* ``import morphlab`` alone;
* the README quickstart up to its first result (:data:`morphlab.bench.scenarios.QUICKSTART`)
  with the default cache (``NUMBA_CACHE_DIR`` if the environment sets it, else next to the
  kernels); it must compile nothing, else the cache was not filled and the figure is no warm
  start;
* the floor set by the dependencies: the interpreter, the imports the quickstart needs
  (NumPy, ``scipy.sparse.linalg``, Numba) and one trivial kernel loaded from the cache, which
  is when Numba loads its own typing and lowering registries (:data:`FLOOR`).

Each process's CPU and wall time are measured from outside, and its time to result from its
launch to the moment the result exists (the script writes the clock then). The two differ by
the interpreter's exit: its garbage collection over Numba's many objects takes a few tenths of
a second, after the result.
"""

from __future__ import annotations

import json
import os
import shutil
import sys
import tempfile

from ..studies.timing import time_stats
from .compile import timed_process
from .scenarios import QUICKSTART

#: The end of each timed script: the clock at its result, and the compilations it ran.
_TAIL = '''
import json as _json
import time as _time
_AT = _time.time()
with open(_OUT, "w") as _fh:
    _json.dump({"result_at": _AT, "in_process_s": _time.perf_counter() - _T0,
                "compilations": _COUNT.n}, _fh)
'''

#: The head of each timed script: its start, and a count of Numba's compilations.
_HEAD = '''\
import time as _time
_T0 = _time.perf_counter()
_OUT = {out!r}
from numba.core import event as _event


class _Count(_event.Listener):
    n = 0

    def on_start(self, ev):
        _Count.n += 1

    def on_end(self, ev):
        pass


_COUNT = _Count()
_event.register("numba:compile", _COUNT)
'''

#: The dependencies' share of a first result: what the quickstart imports besides morphlab,
#: and a kernel of one line loaded from the cache (its first load in a process loads Numba's
#: registries, as the quickstart's first kernel does).
FLOOR = '''\
import numpy as np
import scipy.sparse
import scipy.sparse.linalg
from numba import njit


@njit(cache=True)
def _one(x):
    return x.sum()


_one(np.ones(3))
'''


def _timed(cmd: list[str], out: str | None = None) -> dict:
    """CPU and wall [s] of the process ``cmd`` (:func:`~morphlab.bench.compile.timed_process`);
    with ``out``, the JSON its script wrote there and its time from launch to result
    ``at_s`` [s]."""
    proc, m = timed_process(cmd)
    if proc.returncode != 0:
        tail = (proc.stderr or proc.stdout).strip().splitlines()[-1:]
        raise RuntimeError(f"{cmd[-1]} failed (status {proc.returncode}): "
                           f"{tail[0] if tail else '?'}")
    launched = m.pop("launched")
    if out is not None:
        with open(out, encoding="utf-8") as fh:
            m.update(json.load(fh))
        m["at_s"] = m.pop("result_at") - launched
    return m


def _script(folder: str, name: str, body: str) -> tuple[list[str], str]:
    """The command that runs ``body`` as a script in ``folder``, and its JSON's path."""
    out = os.path.join(folder, name + ".json")
    path = os.path.join(folder, name + ".py")
    with open(path, "w", encoding="utf-8") as fh:
        fh.write(_HEAD.format(out=out) + body + _TAIL)
    return [sys.executable, path], out


def case_startup(repeats: int, quick: bool) -> dict:
    """Import, warm first-result and dependency-floor times of fresh processes (module
    docstring): median, min and max over ``repeats`` rounds, after one untimed round that
    fills the caches. ``quick`` changes nothing (the case takes seconds).

    Raises
    ------
    RuntimeError
        A process failed, or a warm first result compiled kernels.
    """
    folder = tempfile.mkdtemp(prefix="morphlab-startup-")
    try:  # the floor's kernel is cached beside its script, in this folder
        quickstart = _script(folder, "quickstart", QUICKSTART)
        floor = _script(folder, "floor", FLOOR)
        importing = [sys.executable, "-c", "import morphlab"]
        _timed(*quickstart)  # fill the caches if they were not yet
        _timed(*floor)
        imports, firsts, floors = [], [], []
        for _ in range(repeats):
            imports.append(_timed(importing))
            firsts.append(_timed(*quickstart))
            floors.append(_timed(*floor))
    finally:
        shutil.rmtree(folder, ignore_errors=True)
    compiled = [m["compilations"] for m in firsts]
    if any(compiled):
        raise RuntimeError(f"the warm first results compiled kernels ({compiled} "
                           "compilations): the Numba cache was not filled or not used")

    def stats(ms: list[dict], key: str) -> dict:
        return time_stats([m[key] for m in ms])

    from ..jit.cache import kernel_cache_dir

    return {
        "import_cpu_s": stats(imports, "cpu_s"), "import_wall_s": stats(imports, "wall_s"),
        "first_result_cpu_s": stats(firsts, "cpu_s"),
        "first_result_wall_s": stats(firsts, "wall_s"),
        "first_result_at_s": stats(firsts, "at_s"),
        "first_result_in_process_wall_s": stats(firsts, "in_process_s"),
        "floor_cpu_s": stats(floors, "cpu_s"), "floor_wall_s": stats(floors, "wall_s"),
        "floor_at_s": stats(floors, "at_s"),
        "cache_dir": kernel_cache_dir(),
    }
