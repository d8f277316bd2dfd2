"""Parameter studies: run one task over a table of designs on any executor.

:func:`sweep` sends batches of designs to a ``concurrent.futures`` executor and collects one
row per design, in the order given, in a :class:`~.sweep_result.SweepResult`. The same call
runs in-process (``executor="serial"``), on a local process pool (the default) or on a
cluster through Dask's executor; values and gradients are bitwise the same on all of them,
since every design runs the same code on one thread.

Running on a cluster with Dask (``pip install 'morphlab[dask]'``)::

    from dask.distributed import Client
    client = Client("tcp://scheduler:8786")        # a running scheduler; or Client() locally
    table = sweep(task, designs, executor=client.get_executor())

* A batch scheduler (SLURM, PBS, SGE, ...) starts the workers with ``dask-jobqueue``, e.g.
  ``SLURMCluster(cores=1, processes=1, memory="2GB"); cluster.scale(jobs=32)``, then
  ``Client(cluster)``; machines reachable by SSH with
  ``distributed.SSHCluster(["head", "node1", "node2"], worker_options={"nthreads": 1})``.
* Give every worker **one thread** (``--nthreads 1``, ``n_workers`` = cores): a design holds
  the GIL for much of its run (model building, the Newton loop in Python), so threads of one
  process do not run designs in parallel; processes do.
* Every node compiles the Numba kernels once into its own cache (``__pycache__`` next to the
  installed package, or ``NUMBA_CACHE_DIR``); :func:`sweep` warms each worker process up
  before its first design, so the first batches take a few seconds (cache present) to a
  minute or more (fresh node) longer. A shared file system with a writable cache directory
  saves the compilations. (Workers of the local pool are forked from the warmed-up parent
  where the platform forks, and need nothing.)
* Jobs in flight follow the workers the cluster has at each moment, so an adaptive cluster
  that is still starting its workers is used as they arrive.
* The task travels as bytes (cloudpickle), and the workers need morphlab and whatever the task
  imports, in the same versions as the client.

Failures stay in their row: a design whose task raises gets status ``"failed"`` and the
exception's type and text (for a failed run also the time and step). A design whose worker
died (a crash in native code, the out-of-memory killer, a lost node) is rerun alone, so the
culprit is known, up to ``retries`` times.
"""

from __future__ import annotations

import concurrent.futures as cf
import math
import os
import time
from collections import deque
from collections.abc import Callable

import numpy as np

from ..errors import StudyError
from .sweep_result import FAILED, OK, SweepResult, assemble, design_table, rows_of
from .tasks import (
    describe,
    ensure_warm,
    in_process,
    lost_worker,
    make_executor,
    run_batch,
    serialize,
    worker_count,
)

MAX_BATCH = 16
BATCHES_PER_WORKER = 4
WORKERS_REFRESH_S = 1.0


def sweep(task, designs, *, executor=None, batch_size: int | None = None, checkpoint=None,
          progress: bool | Callable[[int, int], object] = False, retries: int = 2
          ) -> SweepResult:
    """Run ``task`` for every design and collect the rows in a table.

    Parameters
    ----------
    task : SimulationTask or callable
        What to compute for a design: a :class:`~.tasks.SimulationTask` (values and gradients
        of responses of a parametric model) or any function ``p -> dict`` of response values.
    designs : list of dict, dict of columns, or pandas DataFrame
        The designs, one per row (e.g. from :mod:`morphlab.studies.samplers`).
    executor : None, "serial" or concurrent.futures.Executor
        ``None``: a local process pool of ``os.cpu_count()`` processes (closed at the end);
        ``"serial"``: in this process; or any Executor, e.g. ``client.get_executor()`` of a
        Dask client (module docstring) or a ``ProcessPoolExecutor`` of your own.
    batch_size : int, optional
        Designs per job; default about four jobs per worker, at most 16 designs each.
    checkpoint : str or os.PathLike, optional
        A file that holds the finished rows (rewritten atomically after every batch, a
        :meth:`SweepResult.save` file). If it exists, designs with an ``"ok"`` row in it
        (same values, exactly) are not run again; failed ones are.
    progress : bool or callable
        Print a progress bar, or call ``progress(n_done, n_total)`` after every batch.
    retries : int
        Reruns of a design whose worker died while it was in flight (each alone, so that a
        design that kills its worker is found); after that its row fails with the reason.

    Returns
    -------
    SweepResult
        One row per design in the order given.

    Raises
    ------
    StudyError
        Bad designs, executor, batch size, retries or progress; a task that cannot be sent
        to worker processes.
    """
    variables, table = design_table(designs)
    _check_options(task, batch_size, retries, progress)
    ex, owned = make_executor(executor)
    run = None
    try:
        payload = task if in_process(ex) else serialize(task)
        rows = _resumed(checkpoint, variables, table)
        ensure_warm()  # the kernels are in the cache before the workers look for them
        run = _Run(ex, payload, variables, table, rows, retries, checkpoint, progress)
        run.execute(batch_size)
    finally:
        for pool in ([ex] if owned else []) + (run.spare if run else []):
            pool.shutdown(wait=True, cancel_futures=True)
    return assemble(variables, table, rows)


def _check_options(task, batch_size, retries, progress) -> None:
    if not callable(task):
        raise StudyError(f"task must be a SimulationTask or a function p -> dict, got {task!r}")
    if batch_size is not None and (not isinstance(batch_size, int | np.integer)
                                   or isinstance(batch_size, bool) or batch_size < 1):
        raise StudyError(f"batch_size must be a positive integer or None, got {batch_size!r}")
    if not isinstance(retries, int | np.integer) or isinstance(retries, bool) or retries < 0:
        raise StudyError(f"retries must be an integer >= 0, got {retries!r}")
    if not (isinstance(progress, bool) or callable(progress)):
        raise StudyError(f"progress must be True, False or a function (done, total), got "
                         f"{progress!r}")


def _resumed(checkpoint, variables, table) -> list:
    """One slot per design: the ``"ok"`` row of the checkpoint with the same values, or None."""
    rows = [None] * len(table)
    if checkpoint is None or not os.path.exists(checkpoint):
        return rows
    done = SweepResult.load(checkpoint)
    if sorted(done.variables) != sorted(variables):
        raise StudyError(f"checkpoint {os.fspath(checkpoint)!r} holds designs of "
                         f"{done.variables}, these have {variables}: use another file")
    order = [done.variables.index(v) for v in variables]
    found = {tuple(done.designs[i, order]): row for i, row in enumerate(rows_of(done))
             if row["status"] == OK}
    for i, design in enumerate(table):
        rows[i] = found.get(tuple(design))
    return rows


class _Run:
    """The state of one sweep: jobs in flight, designs to isolate, rows so far."""

    def __init__(self, ex, payload, variables, table, rows, retries, checkpoint,
                 progress):
        self.ex, self.payload, self.table, self.rows = ex, payload, table, rows
        self.variables, self.retries, self.checkpoint = variables, retries, checkpoint
        self.progress = progress if callable(progress) else (_bar if progress else None)
        self.spare = []  # replacement pools this run created (closed at the end)
        self.workers, self.asked = worker_count(ex), time.monotonic()
        # A crash of one process breaks a whole process pool and fails every job in it: one
        # job per process in flight (in-process executors run a job as it is submitted).
        # Elsewhere a lost worker loses only its own jobs, and a second job queued per worker
        # hides the round trip to the scheduler.
        self.per_worker = 1 if isinstance(ex, cf.ProcessPoolExecutor) or in_process(ex) else 2
        self.lost = {}  # design -> times its worker died under it
        self.suspects = deque()
        self.flight = {}  # future -> (executor, design indices)

    def execute(self, batch_size: int | None) -> None:
        todo = [i for i, r in enumerate(self.rows) if r is None]
        if batch_size is None:
            batch_size = min(MAX_BATCH, max(1, math.ceil(
                len(todo) / (BATCHES_PER_WORKER * self.workers))))
        queue = deque(todo[k:k + batch_size] for k in range(0, len(todo), batch_size))
        self._report()
        while queue or self.suspects or self.flight:
            if not self.suspects:
                window = self.per_worker * self._workers()
                while queue and len(self.flight) < window:
                    self._submit(queue.popleft())
            elif not self.flight:  # alone in flight: if its worker dies, it is the culprit
                self._submit([self.suspects.popleft()])
            finished, _ = cf.wait(list(self.flight), return_when=cf.FIRST_COMPLETED)
            for future in finished:
                self._collect(future)
            self._save()
            self._report()

    def _workers(self) -> int:
        """The executor's workers, asked again at most once a second (a scheduler query)."""
        now = time.monotonic()
        if now - self.asked > WORKERS_REFRESH_S:
            self.workers, self.asked = worker_count(self.ex), now
        return self.workers

    def _submit(self, indices: list[int]) -> None:
        batch = [(i, dict(zip(self.variables, map(float, self.table[i])))) for i in indices]
        self.flight[self.ex.submit(run_batch, self.payload, batch)] = (self.ex, indices)

    def _collect(self, future) -> None:
        ex, indices = self.flight.pop(future)
        try:
            out = future.result()
        except Exception as exc:
            if not lost_worker(exc):  # the job itself failed (not a design): all its rows
                for i in indices:
                    self.rows[i] = _failed(f"the job failed: {describe(exc)}")
                return
            self._replace(ex, exc)
            for i in indices:
                self._lost_under(i, exc)
            return
        for i, row in out:
            self.rows[i] = row

    def _lost_under(self, i: int, exc: BaseException) -> None:
        self.lost[i] = self.lost.get(i, 0) + 1
        if self.lost[i] > self.retries:
            self.rows[i] = _failed(
                f"worker lost ({describe(exc)}) while this design was in flight, "
                f"{self.lost[i]} time(s); {self.retries} rerun(s) alone allowed (retries)")
        elif self.lost[i] > 1:
            self.suspects.appendleft(i)  # it was alone: finish it before the others
        else:
            self.suspects.append(i)

    def _replace(self, ex, exc) -> None:
        """A broken process pool is replaced by a fresh one of the same size (once)."""
        if isinstance(exc, cf.BrokenExecutor) and ex is self.ex:
            self.ex = cf.ProcessPoolExecutor(max_workers=self.workers)
            self.spare.append(self.ex)

    def _save(self) -> None:
        if self.checkpoint is None:
            return
        done = [i for i, r in enumerate(self.rows) if r is not None]
        if done:
            assemble(self.variables, self.table[done], [self.rows[i] for i in done]).save(
                self.checkpoint)

    def _report(self) -> None:
        if self.progress is not None:
            self.progress(sum(r is not None for r in self.rows), len(self.rows))


def _failed(error: str) -> dict:
    return {"status": FAILED, "values": {}, "gradients": {}, "error": error, "wall_time": 0.0}


def _bar(done: int, total: int) -> None:
    width = 30
    filled = int(width * done / total)
    end = "\n" if done == total else "\r"
    print(f"[{'#' * filled}{'.' * (width - filled)}] {done}/{total} designs", end=end,
          flush=True)
