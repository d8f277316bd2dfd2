"""Benchmark case ``startup``: a warm start, the kernels loaded from a filled Numba cache.

In fresh processes, interleaved round by round: ``import morphlab`` alone, and the README
quickstart's first result (:data:`morphlab.bench.scenarios.QUICKSTART`) with the default
cache (``NUMBA_CACHE_DIR`` if the environment sets it, else next to the kernels). Process CPU
and wall time from outside, as in :mod:`morphlab.bench.compile`; the first-result processes
must compile nothing (else the cache was not filled and the figure is no warm start).
"""

from __future__ import annotations

import resource
import subprocess
import sys
import time

from ..studies.timing import time_stats
from .compile import fresh_process


def _import_once() -> dict:
    """CPU and wall [s] of a fresh ``python -c "import morphlab"``."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    w0 = time.perf_counter()
    subprocess.run([sys.executable, "-c", "import morphlab"], check=True, capture_output=True)
    wall = time.perf_counter() - w0
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    return {"cpu_s": (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime),
            "wall_s": wall}


def case_startup(repeats: int, quick: bool) -> dict:
    """Import and warm first-result times of fresh processes (module docstring): median, min
    and max over ``repeats`` rounds, after one untimed first result that fills the cache.
    ``quick`` changes nothing (the case takes seconds)."""
    fresh_process("quickstart", cache_dir=None)  # fills the cache if it was not yet
    imports, firsts = [], []
    for _ in range(repeats):
        imports.append(_import_once())
        firsts.append(fresh_process("quickstart", cache_dir=None))
    compiled = [m["compilations"] for m in firsts]
    if any(compiled):
        raise RuntimeError(f"the warm first results compiled kernels ({compiled} "
                           "compilations): the Numba cache was not filled or not used")
    return {
        "import_cpu_s": time_stats([m["cpu_s"] for m in imports]),
        "import_wall_s": time_stats([m["wall_s"] for m in imports]),
        "first_result_cpu_s": time_stats([m["process"]["cpu_s"] for m in firsts]),
        "first_result_wall_s": time_stats([m["process"]["wall_s"] for m in firsts]),
        "first_result_in_process_wall_s": time_stats(
            [m["phases"]["quickstart"]["wall_s"] for m in firsts]),
        "cache_dir": firsts[0]["cache_dir"],
    }
