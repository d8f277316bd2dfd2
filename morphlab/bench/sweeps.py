"""Benchmark case ``sweep``: throughput of parameter studies on the three kinds of executor.

* **designs/s** on the morphing leading edge (one primal run and three responses per design,
  a Latin hypercube over the pivot ``x_A`` and the torque ``M_t``): in-process
  (``executor="serial"``), the default local process pool (one process per core, its start
  included, as a user calls it) and a Dask ``LocalCluster`` of two single-thread workers
  (started and warmed up before timing, as a running cluster would be);
* **overhead per job**: a task that does nothing, one design per job, so what is timed is
  what the executor adds to every job (sending the design and the task bytes, the result
  back, the book-keeping of :func:`~morphlab.studies.sweep`).

The executors take turns within each round, so a change of the machine's load (it is shared)
hits all of them alike; the speed-ups are ratios of medians of the same rounds.
"""

from __future__ import annotations

import dataclasses
import os

from ..morphing import leading_edge as mo
from ..solve.settings import Settings
from ..studies.samplers import latin_hypercube
from ..studies.sweep import sweep
from ..studies.tasks import SimulationTask
from ..studies.timing import interleaved_times, time_stats

DASK_WORKERS = 2


def nothing(p: dict) -> dict:
    """The trivial task of the overhead measurement."""
    return {"x": p["a"]}


def _rounds(fns: dict, repeats: int) -> dict:
    """A warm-up call of each (worker processes, caches), then interleaved rounds, so that a
    change of the machine's load hits every executor alike; median, min, max of each."""
    for fn in fns.values():
        fn()
    return {k: time_stats(v) for k, v in interleaved_times(fns, repeats).items()}


def _executors():
    """Name -> executor argument of sweep, and a closer for the Dask cluster (or None)."""
    out = {"serial": "serial", "pool": None}
    try:
        import distributed
    except ImportError:
        return out, None
    cluster = distributed.LocalCluster(n_workers=DASK_WORKERS, threads_per_worker=1,
                                       processes=True, dashboard_address=None)
    client = distributed.Client(cluster)
    out["dask"] = client.get_executor()

    def close():
        client.close()
        cluster.close()

    return out, close


def run(repeats: int, quick: bool) -> dict:
    settings = Settings.of(mo.SETTINGS, dt=2.0 * mo.SETTINGS.dt) if quick else mo.SETTINGS
    n_designs, n_jobs = (24, 100) if quick else (64, 300)
    designs = latin_hypercube({"x_A": (101.0, 103.0), "M_t": (9.0e3, 1.1e4)}, n_designs,
                              seed=0)
    task = SimulationTask(mo.build, mo.RESPONSES, settings)
    trivial = [{"a": float(i)} for i in range(n_jobs)]
    executors, close = _executors()
    out = {"n_designs": n_designs, "settings": dataclasses.asdict(settings), "cpus": os.cpu_count(),
           "dask_workers": DASK_WORKERS if close else None, "designs_per_s": {},
           "time_s": {}, "overhead_per_job_ms": {}, "n_jobs": n_jobs}
    load = os.getloadavg()[0]
    try:
        out["time_s"] = _rounds({name: (lambda ex=ex: sweep(task, designs, executor=ex))
                                 for name, ex in executors.items()}, repeats)
        jobs = _rounds({name: (lambda ex=ex: sweep(nothing, trivial, executor=ex,
                                                   batch_size=1))
                        for name, ex in executors.items()}, repeats)
    finally:
        if close:
            close()
    out["load_average_1min"] = [load, os.getloadavg()[0]]
    for name, t in out["time_s"].items():
        out["designs_per_s"][name] = n_designs / t["median"]
        out["overhead_per_job_ms"][name] = 1e3 * jobs[name]["median"] / n_jobs
    rate = out["designs_per_s"]
    out["speedup"] = {k: rate[k] / rate["serial"] for k in rate if k != "serial"}
    return out
