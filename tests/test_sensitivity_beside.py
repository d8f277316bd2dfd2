"""The worker thread that forms the adjoint's design data beside the primal run
(``morphlab/sensitivity/beside.py``): its value, its errors, and the two ways a single worker
thread could wait for ever — work started from inside a piece of work, and a forked child
that inherits the parent's pool without its thread."""

import multiprocessing as mp
import os
import threading

import pytest

from morphlab.sensitivity.beside import Beside


def test_value_and_error_come_back_to_the_caller():
    b = Beside(lambda: threading.current_thread().name, overlap=True)
    b.start()
    assert b.started and b.result().startswith("morphlab-beside")

    def fail():
        raise ValueError("no such variable")

    bad = Beside(fail, overlap=True)
    bad.start()
    with pytest.raises(ValueError, match="no such variable"):
        bad.result()
    with pytest.raises(ValueError, match="no such variable"):  # done and failed
        bad.check()
    b.check()  # done and well: nothing


def test_without_overlap_the_work_runs_in_the_callers_thread_once():
    calls = []
    b = Beside(lambda: calls.append(threading.current_thread().name) or len(calls),
               overlap=False)
    b.start()
    assert not b.started
    assert b.result() == 1 and b.result() == 1 and calls == [threading.current_thread().name]


def test_work_started_inside_a_piece_of_work_runs_inline():
    """A Beside started from the worker thread (a gradient inside a ``build``) is not queued
    behind the work that waits for it: it runs in that thread when asked for."""

    def outer():
        inner = Beside(lambda: threading.current_thread().name, overlap=True)
        inner.start()
        if inner.started:  # queued behind this very work: waiting for it would never end
            return True, None
        return False, inner.result()

    b = Beside(outer, overlap=True)
    b.start()
    started, where = b.result()
    assert not started and where.startswith("morphlab-beside")


def _child(queue):
    b = Beside(lambda: os.getpid(), overlap=True)
    b.start()
    queue.put(b.result())


@pytest.mark.skipif(not hasattr(os, "register_at_fork"), reason="no fork on this platform")
def test_a_forked_child_makes_a_worker_of_its_own():
    """The parent's worker thread exists (it ran a piece of work); a child forked from it
    (a process pool's worker) gets its own thread instead of queueing on the parent's
    executor, whose thread it does not have. The child is given 60 s (it needs well under
    one); a child that waits for ever fails the test."""
    parent = Beside(os.getpid, overlap=True)
    parent.start()
    assert parent.result() == os.getpid()
    ctx = mp.get_context("fork")
    queue = ctx.Queue()
    p = ctx.Process(target=_child, args=(queue,))
    p.start()
    p.join(60)
    if p.is_alive():
        p.terminate()
        pytest.fail("the forked child waited for the parent's worker thread")
    assert p.exitcode == 0 and queue.get(timeout=5) == p.pid


@pytest.mark.parametrize(("cores", "others", "spare"),
                         [(1, 0.0, False), (2, 0.0, True), (2, 1.0, False), (4, 2.0, True),
                          (4, 3.0, False)])
def test_a_spare_core_is_an_idle_one(monkeypatch, cores, others, spare):
    """The worker thread is used where a core besides the caller's is idle: not on one core,
    not beside another busy process (a sweep's second worker on two cores)."""
    from morphlab.sensitivity import beside

    monkeypatch.setattr(beside, "usable_cores", lambda: cores)
    monkeypatch.setattr(beside, "others_running", lambda: others)
    assert beside.spare_core() is spare


def test_others_running_reads_a_count():
    from morphlab.sensitivity.beside import others_running

    assert 0.0 <= others_running() < 10_000
