"""The compile helper of a cold start (morphlab.solve.precompile).

Its jobs must be the very signatures the run compiles (otherwise it compiles kernels nobody
loads), it must leave the cache consistent (a later process loads every kernel and gets the
same numbers), and the run must not compile what the helper compiles.
"""

import json
import os
import subprocess
import sys
import textwrap

import numpy as np
import pytest

import morphlab as ml
from morphlab.solve import precompile

# a model run in fresh processes: sparse factors (dense_max=0) and one with the dense LU and
# the items behind the extra switch (a point force), each the other kind of every kernel
_MODELS = """
import numpy as np
import morphlab as ml

def strip(extra):
    m = ml.Model(gravity=(0.0, -9.81e3))
    nodes = np.c_[np.linspace(0.0, 40.0, 5), np.zeros(5)]
    b = m.add_beam(nodes, E=7.0e4, rho=2.7e-9, thickness=1.0, width=10.0, name="strip")
    m.add_fix(b, at=(0.0, 0.0), dofs="xy")
    if extra:
        m.add_force(b, at=(40.0, 0.0), force=(0.0, -1.0))
    return m

SETTINGS = {False: dict(t_end=4e-5, dt=1e-5, dense_max=0),
            True: dict(t_end=4e-5, dt=1e-5)}

def record_compilations():  # a list receiving (module, name) of every compilation here
    from numba.core import event

    compiled = []

    class Seen(event.Listener):
        def on_start(self, e):
            f = e.data["dispatcher"].py_func
            compiled.append((f.__module__, f.__name__))

        def on_end(self, e):
            pass

    event.register("numba:compile", Seen())
    return compiled
"""


def _run(code: str, env=None) -> dict:
    out = subprocess.run([sys.executable, "-c", _MODELS + textwrap.dedent(code)], env=env,
                         capture_output=True, text=True, timeout=600)
    assert out.returncode == 0, out.stderr[-3000:]
    return json.loads(out.stdout.strip().splitlines()[-1])


def test_jobs_are_the_signatures_the_run_compiles():
    # in a fresh process (warm cache): compile the jobs, run, and compare each job kernel's
    # signatures with the jobs'; a job typed unlike the run's call leaves the run's own
    # signature beside it
    out = _run("""
        import importlib, json
        from morphlab.compile.system import time_table
        from morphlab.solve import precompile
        jobs, kernels = {}, {}
        for extra in (False, True):
            system = ml.compile_model(strip(extra))
            for m, k, sig in precompile.primal_jobs(system, time_table(system, np.zeros(1))):
                kernels[k] = getattr(importlib.import_module(m), k)
                kernels[k].compile(sig)
                jobs.setdefault(k, set()).add(str(sig))
            ml.simulate(system, **SETTINGS[extra])
        print(json.dumps({k: [sorted(jobs[k]), sorted(map(str, d.signatures))]
                          for k, d in kernels.items()}))
        """)
    assert sorted(out) == ["factor_matrix", "newton_loop", "solve_factored", "step_residual"]
    for kernel, (jobs, compiled) in out.items():
        assert compiled == jobs, kernel
    # the extra switch is part of the system's type: two step residuals, two loops
    assert len(out["step_residual"][0]) == len(out["newton_loop"][0]) == 2


@pytest.mark.skipif(not precompile.enabled(), reason="the helper needs two cores")
def test_a_cold_run_with_the_helper(tmp_path):
    env = dict(os.environ, NUMBA_CACHE_DIR=str(tmp_path))
    cold = _run("""
        import json
        from morphlab.solve import precompile
        compiled = record_compilations()
        r = ml.simulate(strip(False), **SETTINGS[False])
        helper = precompile._helper
        assert precompile.wait(300)
        guarded = [d for d in helper.guarded.values()
                   if isinstance(d._cache, precompile._Guard)]
        print(json.dumps(dict(q=r.q.tolist(), compiled=compiled, rc=helper.proc.returncode,
                              guarded=len(guarded))))
        """, env)
    assert cold["rc"] == 0 and cold["guarded"] == 0
    # the helper's first job is compiled there, never here: the run meets it only after the
    # constraint checks and the step matrix, seconds after the helper has started it
    names = [name for _, name in cold["compiled"]]
    assert "step_residual" not in names and "step_matrix" in names
    # a later process finds every kernel in the cache and gets the same numbers
    warm = _run("""
        import json
        compiled = record_compilations()
        r = ml.simulate(strip(False), **SETTINGS[False])
        print(json.dumps(dict(q=r.q.tolist(), compiled=compiled)))
        """, env)
    assert not [m for m, _ in warm["compiled"] if m.startswith("morphlab")]
    here = ml.simulate(_strip_here(), **dict(t_end=4e-5, dt=1e-5, dense_max=0))
    np.testing.assert_array_equal(np.array(cold["q"]), here.q)
    np.testing.assert_array_equal(np.array(warm["q"]), here.q)


def _strip_here():
    scope: dict = {}
    exec(_MODELS, scope)  # noqa: S102 - the same model text the subprocesses run
    return scope["strip"](False)


def test_switched_off_by_the_environment(monkeypatch):
    monkeypatch.setenv(precompile.ENV, "0")
    assert not precompile.enabled()
    monkeypatch.setenv(precompile.ENV, "1")
    monkeypatch.setenv("NUMBA_DISABLE_JIT", "1")
    assert not precompile.enabled()


def test_not_started_on_a_warm_cache(monkeypatch):
    monkeypatch.setattr(precompile, "_helper", None)
    monkeypatch.setattr(precompile, "kernels_cached", lambda: True)
    precompile.start(ml.compile_model(_strip_here()))
    assert precompile._helper is None
