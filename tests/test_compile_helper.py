"""The compile helper: a second process compiling kernel groups into the shared cache
(morphlab.jit.helper, morphlab.morphing.warmup), used by the main command's first use."""

import json
import os
import subprocess
import sys
import textwrap
import time

import pytest

from morphlab.jit.helper import CompileHelper
from morphlab.morphing import warmup as mw


def test_unknown_group_is_named():
    with pytest.raises(ValueError, match=r"'loop'.*known: \['time loop'"):
        mw.helper(["statics", "loop"])


def test_a_failed_helper_is_reported_with_its_output():
    h = CompileHelper("morphlab.no_such_module")
    with pytest.warns(RuntimeWarning, match=r"(?s)ended with status 1.*No module named"):
        assert h.close() == 1


def test_the_helper_is_stopped_when_the_work_fails(tmp_path, monkeypatch):
    (tmp_path / "sleeper.py").write_text("import time\ntime.sleep(60)\n")
    monkeypatch.setenv("PYTHONPATH", str(tmp_path))
    t0 = time.perf_counter()
    with pytest.raises(RuntimeError, match="the work"):
        with CompileHelper("sleeper") as h:
            raise RuntimeError("the work failed")
    assert h.process.returncode is not None and h.process.returncode != 0
    assert time.perf_counter() - t0 < 30.0  # terminated, not waited for (60 s)


#: After the statics group, count the kernels the flight loads' static solves compile.
_AFTER = textwrap.dedent("""
    import json
    from numba.core import event
    from morphlab.morphing import flight_loads as fl
    compiled = []
    class Count(event.Listener):
        def on_start(self, ev):
            f = ev.data["dispatcher"].py_func
            if f.__module__.startswith("morphlab"):
                compiled.append(f.__module__ + "." + f.__qualname__)
        def on_end(self, ev):
            pass
    with event.install_listener("numba:compile", Count()):
        for actuator in ("torque", "locked"):
            r = fl.configuration("high_speed", actuator=actuator)
    print(json.dumps({"compiled": compiled, "iterations": r.iterations}))
""")


@pytest.mark.slow
def test_the_statics_group_compiles_what_the_flight_loads_solve_with(tmp_path):
    """After ``python -m morphlab.morphing.warmup statics`` (no flow analysis), the flight
    loads' aeroelastic equilibria (vacuum, under the air load, crank free and locked)
    compile no kernel: the group's uniform suction has the item kinds of the real load."""
    env = dict(os.environ, NUMBA_CACHE_DIR=str(tmp_path))
    subprocess.run([sys.executable, "-m", "morphlab.morphing.warmup", "statics"], env=env,
                   check=True, capture_output=True, timeout=600)
    out = subprocess.run([sys.executable, "-c", _AFTER], env=env, check=True,
                         capture_output=True, text=True, timeout=600)
    measured = json.loads(out.stdout.strip().splitlines()[-1])
    assert measured["iterations"] >= 1
    assert measured["compiled"] == []


@pytest.mark.parametrize("no_aero, no_timing, cached, groups", [
    (False, False, False, ["statics", "adjoint"]),
    (True, False, False, ["adjoint"]),
    (False, True, False, ["statics"]),
    (True, True, False, None),
    (False, False, True, None),
])
def test_the_main_command_starts_a_helper_on_first_use_only(monkeypatch, no_aero, no_timing,
                                                           cached, groups):
    """``morphlab morphing`` starts the helper for the groups it will need (the adjoint only
    with the timing, the statics only with the flight loads) when they are not cached."""
    import argparse
    import contextlib

    from morphlab import cli
    from morphlab.jit import cache

    started = []
    monkeypatch.setattr(mw, "helper", lambda g: started.append(list(g)) or
                        contextlib.nullcontext())
    from morphlab.kernels.adjoint import sweep
    from morphlab.kernels.steps import run_steps

    asked = []
    monkeypatch.setattr(cache, "kernels_cached", lambda *k: asked.append(k) or cached)
    with cli._compile_helper(argparse.Namespace(no_aero=no_aero, no_timing=no_timing)):
        pass
    assert started == ([] if groups is None else [groups])
    if not (no_aero and no_timing):  # the time loop always asked, the adjoint with the timing
        assert asked == [(run_steps,) + (() if no_timing else (sweep,))]
