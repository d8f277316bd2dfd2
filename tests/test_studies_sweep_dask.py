"""Sweeps on a real Dask cluster whose workers die: bounded time, the culprit found, the
others finished, a cluster without workers ends the sweep with the rows so far.

The clusters are real: a ``distributed.LocalCluster`` of two single-thread worker processes
under nannies (which restart a worker that died), or a scheduler with two worker processes
started without nannies (``--no-nanny``: a worker that dies stays dead). The task kills its
worker on purpose with ``os._exit(1)`` for one design; calls are counted in files, since
they happen in other processes. Every sweep runs in a thread joined with a time limit, so a
sweep that would hang fails the test instead.

Run as a script to repeat the two scenarios and see the spread of their wall times::

    PYTHONPATH=$PWD python tests/test_studies_sweep_dask.py 20
"""

import os
import pathlib
import statistics
import subprocess
import sys
import tempfile
import threading
import time

import numpy as np
import pytest

from morphlab.studies import SweepAborted, SweepResult, sweep, sweep_iter

distributed = pytest.importorskip("distributed")

DESIGNS = [{"t": float(t)} for t in range(12)]
KILLER = 5.0
# Limits of the tests, far above what the sweeps take (a few seconds; the script's numbers),
# far below what waiting for a hung cluster would take (forever).
BOUND_S = 90.0


class Killer:
    """Exits its worker process for the design t == ``kill`` (every time it runs), takes
    ``work`` seconds for the others, and counts every call of every design in files."""

    def __init__(self, folder, kill=KILLER, work=0.05):
        self.folder, self.kill, self.work = str(folder), kill, work
        os.makedirs(self.folder, exist_ok=True)

    def calls(self, t: float) -> int:
        return len(list(pathlib.Path(self.folder).glob(f"t{t!r}-*")))

    def __call__(self, p):
        pathlib.Path(self.folder, f"t{p['t']!r}-{time.time_ns()}-{os.getpid()}").touch()
        if p["t"] == self.kill:
            os._exit(1)
        time.sleep(self.work)
        return {"twice": 2.0 * p["t"]}


def bounded(fn, seconds: float = BOUND_S):
    """``fn()`` in a thread; fail if it has not returned within ``seconds``."""
    out = {}

    def target():
        try:
            out["value"] = fn()
        except BaseException as exc:  # handed to the test's thread
            out["error"] = exc

    thread = threading.Thread(target=target, daemon=True)
    thread.start()
    thread.join(seconds)
    assert not thread.is_alive(), f"the sweep did not finish within {seconds} s"
    if "error" in out:
        raise out["error"]
    return out["value"]


def local_cluster():
    """Two single-thread worker processes under nannies."""
    cluster = distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                       dashboard_address=None)
    return cluster, distributed.Client(cluster)


def nanny_less_cluster(n_workers=2):
    """A scheduler and ``n_workers`` worker processes without nannies (a worker that dies is
    gone for good); returns the cluster, the client and the worker processes."""
    cluster = distributed.LocalCluster(n_workers=0, processes=True, dashboard_address=None)
    client = distributed.Client(cluster)
    here = os.path.dirname(os.path.abspath(__file__))  # the task's class is imported there
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(
        [here] + [p for p in [os.environ.get("PYTHONPATH")] if p])}
    procs = [subprocess.Popen(
        [sys.executable, "-m", "distributed.cli.dask_worker", cluster.scheduler_address,
         "--no-nanny", "--nthreads", "1", "--no-dashboard"], env=env,
        stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL) for _ in range(n_workers)]
    client.wait_for_workers(n_workers, timeout=60)
    return cluster, client, procs


# ------------------------------------------------------------------------------ scenarios
def killer_scenario(client, folder, retries=2, batch_size=None):
    """A design that kills every worker that runs it, among 11 that do not."""
    task = Killer(folder)
    t0 = time.perf_counter()
    out = bounded(lambda: sweep(task, DESIGNS, executor=client, retries=retries,
                                batch_size=batch_size))
    return out, task, time.perf_counter() - t0


def lost_cluster_scenario(client, folder, checkpoint=None):
    """Designs one per job on two workers without nannies; the fifth kills the worker that
    runs it, and its rerun the other one: no workers are left."""
    task = Killer(folder, kill=4.0)
    t0 = time.perf_counter()
    try:
        out = bounded(lambda: sweep(task, DESIGNS[:8], executor=client, batch_size=1,
                                    worker_timeout=2.0, checkpoint=checkpoint))
    except SweepAborted as exc:
        return exc, task, time.perf_counter() - t0
    raise AssertionError(f"the sweep ended without SweepAborted: {out!r}, {out.errors}")


# ---------------------------------------------------------------------------------- tests
@pytest.mark.slow
def test_a_design_that_kills_every_worker_fails_alone_and_the_others_finish(tmp_path):
    """The killer costs one worker per attempt: its first run (in a batch with a neighbour)
    and ``retries`` reruns alone, whatever Dask's own ``allowed-failures`` (3) would allow;
    the other designs finish meanwhile on the other worker."""
    cluster, client = local_cluster()
    with cluster, client:
        out, task, _ = killer_scenario(client, tmp_path)
    k = DESIGNS.index({"t": KILLER})
    assert [i for i in range(len(DESIGNS)) if out.status[i] == "failed"] == [k]
    assert "worker died while this design was running (3 time(s), 2 of them alone" in (
        out.errors[k])
    assert task.calls(KILLER) == 3  # one death per attempt: 1 + retries
    expected = 2.0 * np.array([d["t"] for d in DESIGNS])
    ok = np.arange(len(DESIGNS)) != k
    np.testing.assert_array_equal(out.values["twice"][ok], expected[ok])
    for t in (d["t"] for d in DESIGNS if d["t"] != KILLER):
        assert task.calls(t) <= 2  # a neighbour of the killer reruns once, alone


@pytest.mark.slow
def test_retries_bound_the_deaths_and_a_culprit_alone_is_known_at_once(tmp_path):
    """One design per job on single-thread workers: each job is alone on its worker, so with
    ``retries=0`` the killer fails after one death and no other design is touched."""
    cluster, client = local_cluster()
    with cluster, client:
        out, task, _ = killer_scenario(client, tmp_path, retries=0, batch_size=1)
    k = DESIGNS.index({"t": KILLER})
    assert [i for i in range(len(DESIGNS)) if out.status[i] == "failed"] == [k]
    assert task.calls(KILLER) == 1 and "(1 time(s), 1 of them alone; retries=0)" in (
        out.errors[k])
    assert all(task.calls(d["t"]) == 1 for d in DESIGNS)


@pytest.mark.slow
def test_a_cluster_that_lost_all_its_workers_ends_with_the_rows_so_far(tmp_path):
    """Workers without nannies: the killer takes both; after ``worker_timeout`` seconds
    without workers the sweep raises SweepAborted carrying the finished rows, which the
    checkpoint holds too."""
    cluster, client, procs = nanny_less_cluster()
    path = tmp_path / "lost.ckpt"
    try:
        with cluster, client:
            err, task, wall = lost_cluster_scenario(client, tmp_path / "calls", path)
    finally:
        for proc in procs:
            proc.kill()
            proc.wait()
    assert isinstance(err, SweepAborted) and "no workers for" in str(err)
    assert task.calls(4.0) == 2  # it killed both workers, one each
    done = set(err.indices.tolist())
    assert {0, 1, 2} <= done and 4 not in done  # 0-2 finish before 4 is sent
    assert list(err.partial.status) == ["ok"] * len(done)
    np.testing.assert_array_equal(err.partial.values["twice"], 2.0 * err.indices)
    saved = SweepResult.load(path)
    assert sorted(saved.designs[:, 0].tolist()) == sorted(float(i) for i in done)
    assert wall < BOUND_S


def test_no_workers_at_all_times_out_instead_of_waiting_forever():
    with distributed.LocalCluster(n_workers=0, processes=True, dashboard_address=None) as c, \
            distributed.Client(c) as client:
        t0 = time.perf_counter()
        with pytest.raises(SweepAborted, match=r"no workers for .*worker_timeout=1.0 s") as info:
            bounded(lambda: sweep(lambda p: {"x": p["t"]}, DESIGNS, executor=client,
                                  worker_timeout=1.0), seconds=30.0)
        assert time.perf_counter() - t0 < 30.0
    assert len(info.value.partial) == 0 and info.value.indices.size == 0


@pytest.mark.slow
def test_streamed_rows_on_dask_equal_the_table(tmp_path):
    cluster, client = local_cluster()
    with cluster, client:
        task = Killer(tmp_path, kill=None, work=0.0)
        streamed = bounded(lambda: list(sweep_iter(task, DESIGNS, executor=client)))
        table = bounded(lambda: sweep(task, DESIGNS, executor=client.get_executor()))
    assert sorted(i for i, _ in streamed) == list(range(len(DESIGNS)))
    for i, row in streamed:
        assert row.ok and row.design == DESIGNS[i]
        assert row.values["twice"] == table.values["twice"][i] == 2.0 * DESIGNS[i]["t"]


# --------------------------------------------------------------------------------- script
def _repeat(n: int) -> None:
    """Run both scenarios ``n`` times on fresh clusters; print the wall times of the sweeps
    (cluster start-up excluded) and whether every run finished."""
    kills, losts = [], []
    for k in range(n):
        with tempfile.TemporaryDirectory() as folder:
            cluster, client = local_cluster()
            with cluster, client:
                out, task, wall = killer_scenario(client, pathlib.Path(folder))
            assert list(out.status).count("failed") == 1 and task.calls(KILLER) == 3
            kills.append(wall)
            cluster, client, procs = nanny_less_cluster()
            try:
                with cluster, client:
                    err, _, wall = lost_cluster_scenario(client, pathlib.Path(folder, "c"))
            finally:
                for proc in procs:
                    proc.kill()
                    proc.wait()
            assert isinstance(err, SweepAborted)
            losts.append(wall)
        print(f"run {k + 1}: killer {kills[-1]:.2f} s, lost cluster {losts[-1]:.2f} s",
              flush=True)
    for name, times in (("killer design", kills), ("cluster losing its workers", losts)):
        print(f"{name}: {len(times)}/{n} finished; wall min {min(times):.2f} s, median "
              f"{statistics.median(times):.2f} s, max {max(times):.2f} s")


if __name__ == "__main__":
    import logging

    logging.disable(logging.WARNING)  # Dask logs every worker death at length
    _repeat(int(sys.argv[1]) if len(sys.argv) > 1 else 20)
