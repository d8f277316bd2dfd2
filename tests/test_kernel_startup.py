"""The first compilation is announced, with progress while it lasts, and nothing is printed
when the kernels come from the cache; the cache lives where the user says."""

import os
import subprocess
import sys
import textwrap

import pytest
from numba import njit

from morphlab.jit import CompileProgress, cache
from morphlab.jit.progress import ESTIMATES

RUN = textwrap.dedent("""
    import numpy as np, morphlab as ml
    m = ml.Model()
    b = m.add_rigid_body(mass=1e-3, inertia=1.0, position=(10.0, 0.0), name="link")
    m.add_revolute(m.ground, b, at=(0.0, 0.0), name="pin")
    m.add_torque(b, 1.0, name="T")
    ml.simulate(m, t_end=0.002, dt=0.001)
""")


def test_a_compilation_is_announced_with_progress_and_its_total(capsys):
    """A compile event inside the block prints the notice at once, a progress line every
    ``every`` seconds while it lasts, and the total at the end."""
    import time

    @njit
    def slow(x):
        return x + 1

    with CompileProgress("time loop", every=0.05):
        slow(1.0)  # compiles: the notice
        time.sleep(0.2)  # progress lines while the block lasts (compiling or not)
    err = capsys.readouterr().err
    assert err.count("compiling the numerical kernels of the time loop") == 1
    estimate = ESTIMATES["time loop"]
    assert f"about {estimate:.0f} CPU-s on the 2-core reference machine" in err
    assert f"{ESTIMATES['time loop, every item kind']:.0f} with every item kind" in err
    assert str(cache.kernel_cache_dir()) in err
    assert err.count("still compiling") >= 2
    assert "compiled 1 kernels" in err


def test_silent_without_compilation(capsys):
    with CompileProgress("time loop", every=0.01):
        pass
    assert capsys.readouterr().err == ""


@pytest.mark.slow
def test_a_cold_run_is_announced_and_a_warm_one_is_silent(tmp_path):
    """In fresh processes on an empty cache: the first run prints the notice and the
    total; the second, which loads every kernel from the cache, prints nothing. Slow: the
    first process compiles the time loop (about 2 min)."""
    env = dict(os.environ, NUMBA_CACHE_DIR=str(tmp_path))
    first, second = (subprocess.run([sys.executable, "-c", RUN], env=env, capture_output=True,
                                    text=True, check=True).stderr for _ in range(2))
    assert "compiling the numerical kernels of the time loop" in first
    assert "compiled" in first and "CPU-s" in first
    assert "morphlab:" not in second


def test_numba_cache_dir_is_respected(tmp_path):
    env = dict(os.environ, NUMBA_CACHE_DIR=str(tmp_path))
    out = subprocess.run([sys.executable, "-c", "from morphlab.jit.cache import "
                          "kernel_cache_dir; print(kernel_cache_dir())"], env=env,
                         capture_output=True, text=True, check=True).stdout
    assert out.strip().startswith(str(tmp_path))


def test_a_wait_for_another_process_is_reported():
    """A kernel another process is compiling (a lock file held elsewhere) is waited for;
    the wait starts the notice and the progress lines name the kernel."""
    import io
    import time

    from morphlab.kernels._jit import LOCKS

    out = io.StringIO()
    with CompileProgress("adjoint", stream=out, every=0.05):
        for f in LOCKS.on_wait:
            f("morphlab.kernels.adjoint.sweep.0123456789abcdef0123.lock")
        time.sleep(0.2)
    text = out.getvalue()
    assert "compiling the numerical kernels of the adjoint" in text
    assert "now sweep (another process)" in text
    assert LOCKS.on_wait == []  # the block's hook is removed on leaving
