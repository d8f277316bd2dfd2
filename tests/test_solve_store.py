"""What a run keeps and how it stops: the histories asked for (in memory or memory-mapped), a
run too large for the memory refused before it starts, and interrupts that carry the steps
converged before them (docs: ``simulate`` and ``morphlab.solve.store``)."""

import os
import signal
import subprocess
import sys

import numpy as np
import pytest
from models import flexible_mechanism

import morphlab as ml

RUN = dict(t_end=0.02, dt=1e-3)


def test_kept_histories_are_those_of_the_full_run():
    full = ml.simulate(flexible_mechanism(), **RUN)
    some = ml.simulate(flexible_mechanism(), store=("q", "lam"), **RUN)
    assert some.v is None and some.a is None
    np.testing.assert_array_equal(some.q, full.q)
    np.testing.assert_array_equal(some.lam, full.lam)
    # the diagnostics do not need what was not kept
    np.testing.assert_array_equal(some.velocity_violation, full.velocity_violation)
    np.testing.assert_array_equal(some.node_positions("coupler"), full.node_positions("coupler"))
    assert some.newton_history == full.newton_history
    assert sum(len(h) for h in full.newton_history) == full.newton_iterations[1:].sum()
    with pytest.raises(ml.ModelError, match="store"):
        some.energy  # noqa: B018


# how the steps are run: all from Python, or in compiled chunks of one step (after the first
# chunk), of the default size (~0.1 s of steps) or of the whole rest of the run
CHUNKS = {"python": None, "one-step chunks": 0.0, "default chunks": "default",
          "one chunk": 1e3}


@pytest.mark.parametrize("chunks", list(CHUNKS))
def test_violations_without_the_velocities_are_those_of_the_full_run(monkeypatch, chunks):
    """A run that keeps only ``q`` holds the velocities in a buffer of the last two levels and
    evaluates each step's constraint violations as it goes; they must be the full run's to the
    bit (same kernel, same states) whether the steps run from Python or in compiled chunks
    (whose boundaries the two-level buffer crosses), and for an interrupted run as well."""
    kw = dict(RUN)
    if CHUNKS[chunks] is None:
        kw["compiled_newton"] = False
    elif CHUNKS[chunks] != "default":
        kw["chunk_seconds"] = CHUNKS[chunks]
    full = ml.simulate(flexible_mechanism(), **RUN)
    assert full.constraint_violation.max() > 0.0 and full.velocity_violation.max() > 0.0
    some = ml.simulate(flexible_mechanism(), store=("q",), **kw)
    np.testing.assert_array_equal(some.q, full.q)
    np.testing.assert_array_equal(some.constraint_violation, full.constraint_violation)
    np.testing.assert_array_equal(some.velocity_violation, full.velocity_violation)
    stop, stopped = _stop_from(7)
    with pytest.raises(ml.Interrupted) as err:
        ml.simulate(flexible_mechanism(), store=("q",), progress=stop, **kw)
    part = err.value.result
    k = stopped[0]
    assert 7 <= k < RUN["t_end"] / RUN["dt"] and part.n_t == k + 1
    np.testing.assert_array_equal(part.constraint_violation, full.constraint_violation[:k + 1])
    np.testing.assert_array_equal(part.velocity_violation, full.velocity_violation[:k + 1])


def test_memory_mapped_histories(tmp_path):
    full = ml.simulate(flexible_mechanism(), **RUN)
    mapped = ml.simulate(flexible_mechanism(), memmap=tmp_path, **RUN)
    assert isinstance(mapped.q, np.memmap)
    np.testing.assert_array_equal(mapped.q, full.q)
    np.testing.assert_array_equal(np.load(tmp_path / "lam.npy"), full.lam)


def test_a_run_that_cannot_fit_is_refused_before_it_starts():
    """1e10 steps of a 35-unknown model: ~11 TB of histories. Refused at once with the size,
    not killed by the operating system while allocating."""
    with pytest.raises(ml.ResourceError, match="MiB.*store=") as err:
        ml.simulate(flexible_mechanism(), t_end=1.0, dt=1e-10)
    assert isinstance(err.value, MemoryError)


def _stop_from(k, action=None):
    """A progress callback that interrupts (raises KeyboardInterrupt, or calls ``action``) at
    the first step ``>= k`` it is told of, and the list that receives that step. Progress is
    reported after each step solved from Python and at the end of each compiled chunk of
    steps, so the step it stops at is the first report from ``k`` on."""
    stopped = []

    def callback(n, n_steps, t):
        if n >= k and not stopped:
            stopped.append(n)
            if action is None:
                raise KeyboardInterrupt
            action()
    return callback, stopped


@pytest.mark.parametrize("how", ["progress", "observer", "signal"])
def test_an_interrupt_carries_the_converged_steps(how):
    """From a progress callback or an observer (a KeyboardInterrupt raised in them) and from a
    real SIGINT to this process (its handler only flags the interrupt; the loop stops between
    steps or chunks of steps): an Interrupted, which is a KeyboardInterrupt, with the steps
    up to the one the callback was told of (an observer: every step; progress: the first
    report from step 7 on)."""
    kw = dict(RUN)
    if how == "progress":
        kw["progress"], stopped = _stop_from(7)
    elif how == "observer":
        stopped = [7]

        def observer(info):
            if info.n == stopped[0]:
                raise KeyboardInterrupt
        kw["observer"] = observer
    else:
        kw["progress"], stopped = _stop_from(7, lambda: os.kill(os.getpid(), signal.SIGINT))
    with pytest.raises(KeyboardInterrupt) as err:
        ml.simulate(flexible_mechanism(), **kw)
    k = stopped[0]
    assert 7 <= k < RUN["t_end"] / RUN["dt"]  # stopped before the end
    e = err.value
    assert isinstance(e, ml.Interrupted)
    assert e.result.status == "interrupted" and e.step == k and e.result.n_t == k + 1
    full = ml.simulate(flexible_mechanism(), **RUN)
    np.testing.assert_array_equal(e.result.q, full.q[:k + 1])
    assert signal.getsignal(signal.SIGINT) is signal.default_int_handler  # restored


@pytest.mark.slow
def test_sigint_from_outside_during_compiled_steps_is_a_clean_interrupt(tmp_path):
    """A real Ctrl-C from another process while the compiled Newton loop runs: the run ends
    with Interrupted and its partial result, never a SystemError of the compiled call."""
    script = tmp_path / "run.py"
    script.write_text(
        "import sys, morphlab as ml\n"
        "from morphlab import morphing as mo\n"
        "said = []\n"
        "def looping(n, n_steps, t):\n"
        "    if n >= 20 and not said:\n"  # progress comes at the end of each compiled chunk
        "        said.append(n)\n"
        "        print('looping', flush=True)\n"
        "try:\n"
        "    ml.simulate(mo.build(mo.DEFAULTS, n_elements=300), t_end=60.0, dt=5e-4,\n"
        "                progress=looping)\n"
        "except ml.Interrupted as e:\n"
        "    print('interrupted', e.result.n_t, e.result.status, flush=True)\n")
    proc = subprocess.Popen([sys.executable, str(script)], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)
    assert proc.stdout.readline().strip() == "looping"  # the time loop has started
    import time
    time.sleep(0.5)  # into the compiled steps
    proc.send_signal(signal.SIGINT)
    out, err = proc.communicate(timeout=120)
    assert "SystemError" not in err, err
    words = out.split()
    assert words[0] == "interrupted" and int(words[1]) > 1 and words[2] == "interrupted", (out,
                                                                                           err)
