"""Wall-clock (and CPU) timing of whole runs, for comparisons formed within one process."""

from __future__ import annotations

import statistics
import time
from collections.abc import Callable


def interleaved_times(fns: dict[str, Callable[[], object]], repeats: int, *,
                      cpu: dict | None = None) -> dict[str, list]:
    """Wall times [s] of each function over ``repeats`` rounds that call every function once,
    in turn, so that a change of the machine's load hits all of them alike. ``cpu``: a dict
    that receives, per function, the process's CPU times [s] of the same calls (all its
    threads: a call that works on two cores counts both)."""
    times: dict = {k: [] for k in fns}
    if cpu is not None:
        cpu.update({k: [] for k in fns})
    for _ in range(repeats):
        for k, fn in fns.items():
            c0, t0 = time.process_time(), time.perf_counter()
            fn()
            times[k].append(time.perf_counter() - t0)
            if cpu is not None:
                cpu[k].append(time.process_time() - c0)
    return times


def median_time(fn: Callable[[], object], repeats: int) -> tuple[float, list[float]]:
    """Median and list of the wall times [s] of ``repeats`` calls of ``fn``."""
    times = interleaved_times({"fn": fn}, repeats)["fn"]
    return statistics.median(times), times


def time_stats(times: list[float]) -> dict:
    """``{"median", "min", "max", "runs"}`` of wall times [s]."""
    return {"median": statistics.median(times), "min": min(times), "max": max(times),
            "runs": len(times)}


def timed(fn: Callable[[], object], repeats: int) -> tuple[dict, object]:
    """A warm-up call (compilation, caches), then ``repeats`` timed calls: their
    :func:`time_stats` and the value of the last call."""
    out = fn()
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        out = fn()
        times.append(time.perf_counter() - t0)
    return time_stats(times), out
