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
    # the warm-up marked its group in that cache, for the kernels it compiled
    held = subprocess.run([sys.executable, "-c", "from morphlab.morphing import warmup; "
                           "print(sorted(warmup.compiled_groups()))"], env=env, check=True,
                          capture_output=True, text=True, timeout=600)
    assert held.stdout.strip().splitlines()[-1] == "['statics']"


@pytest.mark.parametrize("no_aero, no_timing, held, groups", [
    (False, False, set(), ["statics", "adjoint"]),
    (True, False, set(), ["adjoint"]),
    (False, True, set(), ["statics"]),
    (True, True, set(), None),
    (False, False, {"statics", "adjoint"}, None),
    # a cache that holds the adjoint (a warm-up without the flight loads): the statics alone
    (False, False, {"time loop", "direct", "adjoint"}, ["statics"]),
    # kernels of other groups do not spare the helper its own
    (False, False, {"time loop", "direct", "direct-fd"}, ["statics", "adjoint"]),
])
def test_the_main_command_starts_a_helper_for_the_groups_not_held(monkeypatch, no_aero,
                                                                  no_timing, held, groups):
    """``morphlab morphing`` starts the helper for the groups it will need (the adjoint only
    with the timing, the statics only with the flight loads) that the cache is not marked as
    holding."""
    import argparse
    import contextlib

    from morphlab import cli

    started = []
    monkeypatch.setattr(mw, "helper", lambda g: started.append(list(g)) or
                        contextlib.nullcontext())
    monkeypatch.setattr(mw, "compiled_groups", lambda: set(held))
    with cli._compile_helper(argparse.Namespace(no_aero=no_aero, no_timing=no_timing)):
        pass
    assert started == ([] if groups is None else [groups])


def test_the_mark_adds_groups_and_holds_only_for_the_kernels_it_was_made_for(tmp_path,
                                                                            monkeypatch):
    """The mark beside the cache: groups add up; a mark of other kernels (another stamp: a
    source changed, another Numba or processor), an unreadable one or none hold nothing."""
    from morphlab.jit import cache

    monkeypatch.setattr(cache, "kernel_cache_dir", lambda: str(tmp_path))
    assert mw.compiled_groups() == set()
    mw.mark_compiled(["time loop", "adjoint"])
    mw.mark_compiled(["statics"])
    assert mw.compiled_groups() == {"time loop", "adjoint", "statics"}
    assert not [f for f in os.listdir(tmp_path) if f.endswith(".tmp")]
    with pytest.raises(ValueError, match="unknown kernel groups"):
        mw.mark_compiled(["adjoint", "sweep"])
    real = mw._stamp()
    monkeypatch.setattr(mw, "_stamp", lambda: real + "0")
    assert mw.compiled_groups() == set()
    mw.mark_compiled(["direct"])  # a mark for the new kernels starts afresh
    assert mw.compiled_groups() == {"direct"}
    (tmp_path / mw.MARK).write_text("{not json")
    assert mw.compiled_groups() == set()


def test_a_changed_kernel_source_changes_the_stamp(tmp_path, monkeypatch):
    """The stamp follows the kernels' sources (Numba compiles again when one changes): the
    modification time of one of them changes it."""
    from morphlab import kernels

    folder = tmp_path / "kernels"
    folder.mkdir()
    (folder / "__init__.py").write_text("")
    (folder / "a.py").write_text("x = 1\n")
    monkeypatch.setattr(kernels, "__file__", str(folder / "__init__.py"))
    before = mw._stamp()
    assert mw._stamp() == before
    st = os.stat(folder / "a.py")
    os.utime(folder / "a.py", ns=(st.st_atime_ns, st.st_mtime_ns + 1_000_000))
    assert mw._stamp() != before


@pytest.mark.parametrize("overrides, marked", [([], True), (["x_A=100"], False)])
def test_the_main_command_marks_its_groups_when_it_has_run_the_defaults(
        tmp_path, monkeypatch, overrides, marked):
    """After a finished run on the defaults the command marks the groups it ran; a run with
    ``--set`` (other kernels, perhaps) or a failed one marks nothing."""
    import contextlib

    from morphlab import cli

    marks = []
    monkeypatch.setattr(mw, "mark_compiled", lambda g: marks.append(list(g)))
    monkeypatch.setattr(cli, "_compile_helper", lambda args: contextlib.nullcontext())
    monkeypatch.setattr(cli, "_check_design", lambda overrides: None)
    monkeypatch.setattr(cli, "_study", lambda *a: "report")
    argv = ["morphing", "--out", str(tmp_path / "out"), "--no-aero"]
    argv += [a for o in overrides for a in ("--set", o)]
    args = cli._parser().parse_args(argv)
    assert cli._morphing(args, cli._Interrupts()) == "report"
    assert marks == ([["time loop", "direct", "direct-fd", "adjoint"]] if marked else [])

    def fail(*a):
        raise RuntimeError("the study failed")

    monkeypatch.setattr(cli, "_study", fail)
    with pytest.raises(RuntimeError):
        cli._morphing(cli._parser().parse_args(["morphing", "--out", str(tmp_path / "o2")]),
                      cli._Interrupts())
    assert len(marks) == (1 if marked else 0)
