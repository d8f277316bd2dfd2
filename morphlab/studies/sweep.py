"""Parameter studies: run one task over a table of designs on any executor.

:func:`sweep` sends batches of designs to a ``concurrent.futures`` executor and collects one
row per design, in the order given, in a :class:`~.sweep_result.SweepResult`. The same call
runs in-process (``executor="serial"``), on a local process pool (the default) or on a
cluster through Dask's executor; values and gradients are bitwise the same on all of them,
since every design runs the same code on one thread.

Running on a cluster with Dask (``pip install 'morphlab[dask]'``)::

    from dask.distributed import Client
    client = Client("tcp://scheduler:8786")        # a running scheduler; or Client() locally
    table = sweep(task, designs, executor=client)  # or client.get_executor()

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
* Jobs are pinned to a worker, one per thread. A design whose worker died (a crash in native
  code, the out-of-memory killer, a lost node) is run again alone on one worker while the
  others go on, up to ``retries`` times; then its row fails with the reason. Dask's own
  reruns of a job whose worker died (``distributed.scheduler.allowed-failures``) do not
  apply: each death costs one attempt. (An executor made with ``workers=`` or
  ``resources=`` of its own, ``client.get_executor(resources=...)``, keeps Dask's
  placement and reruns instead, and a design lost there is rerun alone on the cluster.)
* A cluster that has no workers (all lost, or not started yet) is waited for
  ``worker_timeout`` seconds; then :class:`~.sweep_result.SweepAborted` (a StudyError)
  carries the rows finished so far. Give adaptive clusters behind a batch queue a timeout
  as long as the queue's wait.

Failures stay in their row: a design whose task raises gets status ``"failed"`` and the
exception's type and text (for a failed run also the time and step). A design whose worker
died is rerun alone, so the culprit is known, up to ``retries`` times (on a local process
pool, alone in the pool: one crashed process breaks all of it).

Rows stream: :func:`sweep_iter` yields each design's row as it finishes, on every executor;
:func:`sweep` collects them into the table, in the order given. A checkpoint
(:mod:`.checkpoint`) records the task's identity and every finished row, appended as it
finishes; a sweep given the same file resumes, running only the designs without an
``"ok"`` row there, and refuses a file written by another task.
"""

from __future__ import annotations

import math
import os
from collections.abc import Callable, Iterator

import numpy as np

from ..errors import StudyError
from .checkpoint import check_identity, matched, read
from .identity import as_json, task_identity
from .scheduler import Run, runs_in_process
from .sweep_result import SweepResult, SweepRow, assemble, design_table
from .tasks import serialize

WORKER_TIMEOUT_S = 300.0


def sweep(task, designs, *, executor=None, batch_size: int | None = None, checkpoint=None,
          progress: bool | Callable[[int, int], object] = False, retries: int = 2,
          worker_timeout: float = WORKER_TIMEOUT_S) -> SweepResult:
    """Run ``task`` for every design and collect the rows in a table.

    Parameters
    ----------
    task : SimulationTask or callable
        What to compute for a design: a :class:`~.tasks.SimulationTask` (values and gradients
        of responses of a parametric model) or any function ``p -> dict`` of response values.
    designs : list of dict, dict of columns, or pandas DataFrame
        The designs, one per row (e.g. from :mod:`morphlab.studies.samplers`).
    executor : None, "serial", concurrent.futures.Executor or distributed.Client
        ``None``: a local process pool of ``os.cpu_count()`` processes (closed at the end);
        ``"serial"``: in this process; or any Executor, e.g. a ``ProcessPoolExecutor`` of your
        own, or a Dask client (module docstring) or its ``client.get_executor()``.
    batch_size : int, optional
        Designs per job; default about four jobs per worker, at most 16 designs each.
    checkpoint : str or os.PathLike, optional
        A file that records the task and every finished row (:mod:`.checkpoint`, appended as
        rows finish). If it exists, designs with an ``"ok"`` row there (bitwise the same
        values) are not run again, failed ones are; a file written by another task (other
        responses, settings, gradients, build, variables) raises a StudyError naming what
        differs. :meth:`SweepResult.load` reads it.
    progress : bool or callable
        Print a progress bar, or call ``progress(n_done, n_total)`` as jobs finish.
    retries : int
        Reruns of a design whose worker died while it was in flight (each alone in its place,
        so that a design that kills its worker is found); after that its row fails with the
        reason.
    worker_timeout : float
        Seconds [s] a Dask cluster without any worker is waited for before the sweep stops
        with :class:`~.sweep_result.SweepAborted`.

    Returns
    -------
    SweepResult
        One row per design in the order given.

    Raises
    ------
    StudyError
        Bad designs, executor, batch size, retries, timeout or progress; a task that cannot
        be sent to worker processes; a checkpoint of another task or not a checkpoint.
    SweepAborted
        A Dask cluster without workers for ``worker_timeout`` seconds; ``partial`` holds the
        rows finished so far.
    """
    run = _prepare(task, designs, executor, batch_size, checkpoint, progress, retries,
                   worker_timeout)
    rows = run.stream()
    try:
        for _ in rows:
            pass  # every row is kept in run.rows as it finishes
    finally:
        rows.close()
    return assemble(run.variables, run.table, run.rows)


def sweep_iter(task, designs, *, executor=None, batch_size: int | None = None,
               checkpoint=None, progress: bool | Callable[[int, int], object] = False,
               retries: int = 2, worker_timeout: float = WORKER_TIMEOUT_S
               ) -> Iterator[tuple[int, SweepRow]]:
    """Run ``task`` for every design and yield each design's row as it finishes.

    The same arguments, checks and rows as :func:`sweep` (which collects these rows); the
    arguments are checked, and the checkpoint read, when it is called.

    Yields
    ------
    index : int
        The design's position in ``designs``.
    row : SweepRow
        Its outcome. Rows found in the checkpoint come first (``row.resumed``), then the
        others in the order they finish (the rows of one job together).

    Notes
    -----
    Stopping early (``break``, an exception in the loop) leaves the generator open until it
    is closed or collected; ``with contextlib.closing(sweep_iter(...)) as rows:`` closes it
    (jobs still waiting are cancelled, a pool of its own shut down) at once.
    """
    run = _prepare(task, designs, executor, batch_size, checkpoint, progress, retries,
                   worker_timeout)
    return _stream(run)


def _stream(run: Run) -> Iterator[tuple[int, SweepRow]]:
    resumed = [(i, r) for i, r in enumerate(run.rows) if r is not None]
    for i, row in resumed:
        yield i, _row(run, i, row, resumed=True)
    rows = run.stream()
    try:
        for i, row in rows:
            yield i, _row(run, i, row)
    finally:
        rows.close()


def _row(run: Run, i: int, row: dict, resumed: bool = False) -> SweepRow:
    return SweepRow(dict(zip(run.variables, map(float, run.table[i]))), row["status"],
                    dict(row["values"]), {r: dict(g) for r, g in row["gradients"].items()},
                    row["error"], row["wall_time"], resumed)


def _prepare(task, designs, executor, batch_size, checkpoint, progress, retries,
             worker_timeout) -> Run:
    """The checks of every argument, the task as it travels and the rows of the checkpoint:
    a :class:`Run` ready to start."""
    variables, table = design_table(designs)
    _check_options(task, batch_size, retries, progress, worker_timeout, checkpoint)
    payload = task if runs_in_process(executor) else serialize(task)
    rows, file_variables, identity = [None] * len(table), None, None
    if checkpoint is not None:
        identity = as_json(task_identity(task))
        if os.path.exists(checkpoint):
            header, records = read(checkpoint, stacklevel=4)
            check_identity(checkpoint, header, variables, identity)
            rows, file_variables = matched(header, records, variables, table), header[
                "variables"]
    report = progress if callable(progress) else (_bar if progress else None)
    return Run(executor=executor, payload=payload, variables=variables, table=table,
               rows=rows, batch_size=batch_size, retries=int(retries),
               worker_timeout=float(worker_timeout), progress=report, checkpoint=checkpoint,
               file_variables=file_variables, identity=identity)


def _check_options(task, batch_size, retries, progress, worker_timeout, checkpoint) -> None:
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
    if (isinstance(worker_timeout, bool) or not isinstance(worker_timeout, int | float)
            or not math.isfinite(worker_timeout) or worker_timeout <= 0):
        raise StudyError(f"worker_timeout must be a finite number of seconds > 0, got "
                         f"{worker_timeout!r}")
    if checkpoint is not None and not isinstance(checkpoint, str | os.PathLike):
        raise StudyError(f"checkpoint must be a file path or None, got {checkpoint!r}")
    if checkpoint is not None and os.path.isdir(checkpoint):
        raise StudyError(f"checkpoint {os.fspath(checkpoint)!r} is a folder: give a file path")


def _bar(done: int, total: int) -> None:
    width = 30
    filled = int(width * done / total)
    end = "\n" if done == total else "\r"
    print(f"[{'#' * filled}{'.' * (width - filled)}] {done}/{total} designs", end=end,
          flush=True)
