"""Where the jobs of a sweep run: an executor seen as places with room for jobs.

A *place* holds jobs that die together: when a worker dies, every job in flight in its place
is lost. A process pool is one place (one crashed process breaks the whole pool and fails
every job in it), and so is any other ``concurrent.futures`` executor, whose failures the
sweep cannot tell apart. A Dask cluster has one place per worker, with room for one job per
thread: :class:`DaskPool` pins every job to a worker (``workers=[address]``,
``allow_other_workers=False``), so a job whose worker died is not rerun elsewhere by Dask's
own rules (up to ``distributed.scheduler.allowed-failures`` further deaths, each taking
whatever else ran there) but seen lost when its worker leaves the cluster, and the sweep
decides what runs again, where and how often. It also sees the cluster's workers as they
come and go, so a cluster without any can be waited for with a time limit.
"""

from __future__ import annotations

import concurrent.futures as cf
import os
import time

from ..errors import StudyError


class SerialExecutor(cf.Executor):
    """Runs each job at once in the calling process (``executor="serial"``)."""

    _max_workers = 1

    def submit(self, fn, /, *args, **kwargs):
        future = cf.Future()
        try:
            future.set_result(fn(*args, **kwargs))
        except BaseException as exc:
            future.set_exception(exc)
        return future


def make_executor(executor) -> tuple[cf.Executor, bool]:
    """``(executor, owned)``: a process pool of ``os.cpu_count()`` workers for ``None``, the
    serial executor for ``"serial"``, a Dask client's executor for a ``distributed.Client``,
    any concurrent.futures Executor as given."""
    if executor is None:
        return cf.ProcessPoolExecutor(max_workers=os.cpu_count() or 1), True
    if isinstance(executor, str) and executor == "serial":
        return SerialExecutor(), True
    if isinstance(executor, cf.Executor):
        return executor, False
    if type(executor).__module__.startswith("distributed") and hasattr(executor,
                                                                        "get_executor"):
        return executor.get_executor(), False
    raise StudyError(f"executor must be None (a local process pool), 'serial', a "
                     f"concurrent.futures.Executor or a Dask distributed.Client (or its "
                     f"client.get_executor()), got {executor!r}")


def worker_count(executor) -> int:
    """Jobs the executor runs at once: its processes, or a Dask cluster's threads."""
    client = dask_client(executor)
    if client is not None:
        return max(1, sum(client.nthreads().values()))
    return max(1, int(getattr(executor, "_max_workers", None) or os.cpu_count() or 1))


def dask_client(executor):
    """The ``distributed.Client`` behind a Dask executor, or None for any other."""
    client = getattr(executor, "_client", None)
    if type(executor).__module__.startswith("distributed") and hasattr(client, "nthreads"):
        return client
    return None


def in_process(executor) -> bool:
    return isinstance(executor, SerialExecutor | cf.ThreadPoolExecutor)


def lost_worker(exc: BaseException) -> bool:
    """True for the errors of a job whose worker died: a broken process pool, a Dask
    ``KilledWorker``, a cancelled job."""
    names = {"KilledWorker", "CancelledError", "FutureCancelledError"}
    return isinstance(exc, cf.BrokenExecutor | cf.CancelledError) or any(
        t.__name__ in names for t in type(exc).__mro__)


class Pool:
    """A concurrent.futures executor as one place (module docstring).

    Attributes
    ----------
    size : int
        The workers, for the default batch size.
    poll : float or None
        Seconds between looks at the workers while jobs are in flight (None: never needed).
    """

    poll: float | None = None

    def __init__(self, ex: cf.Executor, owned: bool):
        self.ex, self.owned, self.spare = ex, owned, []
        self.size = worker_count(ex)
        # A crash of one process breaks a whole process pool and fails every job in it: one
        # job per process in flight (in-process executors run a job as it is submitted).
        # Elsewhere a lost worker loses only its own jobs, and a second job queued per worker
        # hides the round trip to the scheduler.
        per = 1 if isinstance(ex, cf.ProcessPoolExecutor) or in_process(ex) else 2
        self.capacity = per * self.size

    def places(self, fresh: bool = False) -> dict:
        """``{place: jobs it takes at once}``."""
        return {None: self.capacity}

    def submit(self, place, fn, *args) -> tuple[cf.Future, cf.Executor]:
        return self.ex.submit(fn, *args), self.ex

    def replace(self, ex: cf.Executor, exc: BaseException) -> None:
        """A broken process pool is replaced by a fresh one of the same size (once)."""
        if isinstance(exc, cf.BrokenExecutor) and ex is self.ex:
            self.ex = cf.ProcessPoolExecutor(max_workers=self.size)
            self.spare.append(self.ex)

    def close(self, futures) -> None:
        """Cancel the jobs still waiting, close the pools this sweep created."""
        for future in futures:
            future.cancel()
        for pool in ([self.ex] if self.owned else []) + self.spare:
            pool.shutdown(wait=True, cancel_futures=True)


class DaskPool(Pool):
    """The workers of a Dask cluster, one place each (module docstring); with ``pin=False``
    the whole cluster as one place (its jobs placed by Dask)."""

    poll = 0.25

    def __init__(self, ex: cf.Executor, owned: bool, client, pin: bool = True):
        self.client, self.pin, self._places, self._asked = client, pin, {}, -float("inf")
        self.ex, self.owned, self.spare = ex, owned, []
        self.size = max(1, sum(self.places(fresh=True).values()))

    def places(self, fresh: bool = False) -> dict:
        """``{worker address: threads}`` of the workers running now (asked of the scheduler
        at most every :attr:`poll` seconds unless ``fresh``), none while the client has lost
        its scheduler; unpinned, ``{None: all their threads}`` or none."""
        now = time.monotonic()
        if fresh or now - self._asked >= self.poll:
            self._places, self._asked = self._query(), now
        if not self.pin:
            total = sum(self._places.values())
            return {None: total} if total else {}
        return self._places

    def _query(self) -> dict:
        if getattr(self.client, "status", "running") != "running":
            return {}
        try:
            workers = self.client.nthreads()
        except Exception:  # a scheduler that does not answer has no workers for us
            return {}
        return {addr: int(n) for addr, n in workers.items() if n}

    def submit(self, place, fn, *args) -> tuple[cf.Future, cf.Executor]:
        if place is None:
            return self.ex.submit(fn, *args), self.ex
        return self.ex.submit(fn, *args, workers=[place], allow_other_workers=False,
                              pure=False), self.ex

    def replace(self, ex, exc) -> None:
        return None

    def close(self, futures) -> None:
        for future in futures:
            future.cancel()  # also cancels the Dask future (ClientExecutor's callback)


def pool_of(executor) -> Pool:
    """The :class:`Pool` of a sweep's ``executor`` argument (:func:`make_executor`). A Dask
    executor made with ``workers=`` or ``resources=`` of its own keeps them: its jobs are
    placed by Dask (and a job whose worker died rerun by Dask's rules)."""
    ex, owned = make_executor(executor)
    client = dask_client(ex)
    own = getattr(ex, "_kwargs", {}) or {}
    if client is not None:
        return DaskPool(ex, owned, client, pin=not ({"workers", "resources"} & set(own)))
    return Pool(ex, owned)

