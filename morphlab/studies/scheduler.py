"""The running of one sweep: jobs to places, rows as they finish, lost workers, time limits.

:class:`Run` cuts the designs still to run into batches and keeps every place of the pool
(:mod:`.executors`) as busy as it allows. A job returns its rows; a job whose worker died
returns nothing, and each of its designs becomes a *suspect*, run again as a job of its own,
alone in its place (on a process pool: alone in the pool, which a crash breaks whole; on a
Dask cluster: alone on one worker, while the other workers go on), so the design that kills
its worker is found; after ``retries`` reruns its row fails with the reason. Each finished
row goes to the checkpoint (one append per job) and out of :meth:`Run.stream` at once.

Nothing waits without a limit: the workers of a Dask cluster are looked at every
:attr:`~.executors.DaskPool.poll` seconds while jobs are in flight, a job pinned to a worker
that left the cluster is taken as lost, and a cluster without workers for longer than
``worker_timeout`` seconds ends the sweep with a :class:`~.sweep_result.SweepAborted` that
carries the rows finished so far.
"""

from __future__ import annotations

import concurrent.futures as cf
import math
import time
from collections import deque
from collections.abc import Callable, Iterator
from dataclasses import dataclass

import numpy as np

from .checkpoint import Writer
from .executors import in_process, lost_worker, pool_of
from .sweep_result import FAILED, SweepAborted, assemble
from .tasks import describe, ensure_warm, run_batch

MAX_BATCH = 16
BATCHES_PER_WORKER = 4
IDLE_LOOK_S = 0.1  # how often a sweep with nothing in flight looks for workers


@dataclass
class _Job:
    indices: list[int]
    place: object
    executor: cf.Executor
    alone: bool  # one design, and nothing else in its place while it runs


class Run:
    """One sweep: its designs, the rows so far (None: to run), the options of
    :func:`~.sweep.sweep`; :meth:`stream` runs it."""

    def __init__(self, *, executor, payload, variables: list[str], table: np.ndarray,
                 rows: list, batch_size: int | None, retries: int, worker_timeout: float,
                 progress: Callable[[int, int], object] | None, checkpoint=None,
                 file_variables: list[str] | None = None, identity: dict | None = None):
        self.executor, self.payload, self.variables, self.table = (executor, payload,
                                                                   variables, table)
        self.rows, self.batch_size, self.retries = rows, batch_size, retries
        self.worker_timeout, self.progress = worker_timeout, progress
        self.checkpoint, self.identity = checkpoint, identity
        self.file_variables = file_variables or list(variables)
        self.lost: dict[int, int] = {}  # design -> times its worker died under it
        self.alone: dict[int, int] = {}  # of those, times it was alone in its place
        self.suspects: deque[int] = deque()
        self.flight: dict[cf.Future, _Job] = {}
        self.pending: list[int] = []  # finished since the last emission
        self.pool = self.writer = None

    def stream(self) -> Iterator[tuple[int, dict]]:
        """``(index, row)`` of every design still to run, as each finishes."""
        self.pool = pool_of(self.executor)
        try:
            if self.checkpoint is not None:
                order = [self.variables.index(v) for v in self.file_variables]
                self.writer = Writer(self.checkpoint, self.file_variables, order,
                                     self.identity)
            ensure_warm()  # the kernels are in the cache before the workers look for them
            yield from self._loop()
        finally:
            self.pool.close(list(self.flight))
            if self.writer is not None:
                self.writer.close()

    def _loop(self) -> Iterator[tuple[int, dict]]:
        todo = [i for i, r in enumerate(self.rows) if r is None]
        size = self.batch_size or min(MAX_BATCH, max(1, math.ceil(
            len(todo) / (BATCHES_PER_WORKER * self.pool.size))))
        queue = deque(todo[k:k + size] for k in range(0, len(todo), size))
        self._report()
        idle_since = None
        while queue or self.suspects or self.flight:
            places = self.pool.places()
            self._departed(places)
            self._fill(places, queue)
            now = time.monotonic()
            if places:
                idle_since = None
            elif idle_since is None:
                idle_since = now
            elif now - idle_since > self.worker_timeout:
                self._abort(now - idle_since)
            if self.flight:
                done, _ = cf.wait(list(self.flight), timeout=self.pool.poll,
                                  return_when=cf.FIRST_COMPLETED)
                for future in done:
                    self._collect(future)
            elif not self.pending:
                time.sleep(IDLE_LOOK_S)
                self.pool.places(fresh=True)
            yield from self._emit()

    def _fill(self, places: dict, queue: deque) -> None:
        """Suspects first, each alone in an empty place; else batches up to the room."""
        held: dict = {}
        for job in self.flight.values():
            held.setdefault(job.place, []).append(job)
        for place, room in places.items():
            jobs = held.get(place, [])
            if any(j.alone for j in jobs):
                continue
            if self.suspects:
                if not jobs:
                    self._submit([self.suspects.popleft()], place, alone=True)
                continue
            while queue and len(jobs) < room:
                indices = queue.popleft()
                jobs.append(self._submit(indices, place,
                                         alone=len(indices) == 1 and not jobs and room == 1))

    def _submit(self, indices: list[int], place, alone: bool) -> _Job:
        batch = [(i, dict(zip(self.variables, map(float, self.table[i])))) for i in indices]
        future, ex = self.pool.submit(place, run_batch, self.payload, batch)
        job = self.flight[future] = _Job(indices, place, ex, alone)
        return job

    def _departed(self, places: dict) -> None:
        """Jobs pinned to a worker that left the cluster are lost (Dask keeps them waiting
        for it): cancel them and count the loss."""
        for future, job in list(self.flight.items()):
            if job.place is not None and job.place not in places and not future.done():
                del self.flight[future]
                future.cancel()
                self._lost(job, f"worker {job.place} left the cluster")

    def _collect(self, future: cf.Future) -> None:
        job = self.flight.pop(future)
        try:
            out = future.result()
        except Exception as exc:
            if not lost_worker(exc):  # the job itself failed (not a design): all its rows
                for i in job.indices:
                    self._finish(i, failed(f"the job failed: {describe(exc)}"))
                return
            self.pool.replace(job.executor, exc)
            self._lost(job, describe(exc))
            return
        for i, row in out:
            self._finish(i, row)

    def _lost(self, job: _Job, detail: str) -> None:
        for i in job.indices:
            self.lost[i] = self.lost.get(i, 0) + 1
            self.alone[i] = self.alone.get(i, 0) + job.alone
            if self.lost[i] > self.retries:
                self._finish(i, failed(
                    f"worker died while this design was running ({self.lost[i]} time(s), "
                    f"{self.alone[i]} of them alone; retries={self.retries}): {detail}"))
            elif job.alone:
                self.suspects.appendleft(i)  # the likely culprit: settle it first
            else:
                self.suspects.append(i)

    def _finish(self, i: int, row: dict) -> None:
        self.rows[i] = row
        self.pending.append(i)

    def _emit(self) -> Iterator[tuple[int, dict]]:
        """Append the rows finished since the last call to the checkpoint (one write),
        then hand them out, then report the progress."""
        if not self.pending:
            return
        done, self.pending = self.pending, []
        if self.writer is not None:
            self.writer.append([(self.table[i], self.rows[i]) for i in done])
        for i in done:
            yield i, self.rows[i]
        self._report()

    def _report(self) -> None:
        if self.progress is not None:
            self.progress(sum(r is not None for r in self.rows), len(self.rows))

    def _abort(self, waited: float) -> None:
        if self.pending and self.writer is not None:
            self.writer.append([(self.table[i], self.rows[i]) for i in self.pending])
        done = np.array([i for i, r in enumerate(self.rows) if r is not None], dtype=int)
        partial = assemble(self.variables, self.table[done], [self.rows[i] for i in done])
        where = f"; they are also in the checkpoint {self.checkpoint!r}" if (
            self.checkpoint is not None) else ""
        raise SweepAborted(
            f"the Dask cluster has had no workers for {waited:.1f} s (worker_timeout="
            f"{self.worker_timeout} s) with {len(self.rows) - len(done)} of {len(self.rows)} "
            f"designs still to run: start workers (or give a longer worker_timeout) and run "
            f"the sweep again; the {len(done)} finished rows are in this error's .partial"
            f"{where}", partial=partial, indices=done)


def failed(error: str) -> dict:
    """The row of a design that did not run to its end."""
    return {"status": FAILED, "values": {}, "gradients": {}, "error": error, "wall_time": 0.0}


def runs_in_process(executor) -> bool:
    """True if the ``executor`` argument of a sweep runs its jobs in this process (the task
    then travels as itself, not as bytes)."""
    return (isinstance(executor, str) and executor == "serial") or in_process(executor)
