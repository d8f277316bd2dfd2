"""Fault injection across the families of the library's promises (bounded: < 30 s warm):
the command line (interrupt, unwritable or empty --out, failures while computing), damaged
result files, and wrong input to drives and profiles. Each fault ends in its documented way:
a typed error naming the item, or one line and a documented exit status."""

import os
import signal
import subprocess
import sys
import time

import numpy as np
import pytest
from models import flexible_mechanism

import morphlab as ml
from morphlab import cli
from morphlab import io as mio
from morphlab.errors import FormatError, ModelError, SolverError

CLI = [sys.executable, "-m", "morphlab.cli", "morphing"]


# ---- command line
def test_sigint_exits_130_with_one_line_and_no_output(tmp_path):
    """A real SIGINT while the study computes (the staging folder exists): exit 130, one line,
    neither the output folder nor the staging folder left behind."""
    out = tmp_path / "out"
    proc = subprocess.Popen([*CLI, "--out", str(out), "--no-figures"], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)
    deadline = time.monotonic() + 60
    while not any(n.startswith(".out.partial-") for n in os.listdir(tmp_path)):
        assert proc.poll() is None and time.monotonic() < deadline, proc.communicate()
        time.sleep(0.005)
    time.sleep(0.2)  # into the computation
    proc.send_signal(signal.SIGINT)
    stdout, stderr = proc.communicate(timeout=60)
    assert proc.returncode == 130, stderr
    assert stderr.strip().splitlines() == ["morphlab: interrupted"]
    assert os.listdir(tmp_path) == []


_HALF_BUILT = """
import sys
import morphlab.cli as cli


class HalfBuilt:  # as an LLVM handle whose construction an interrupt cut short
    def __del__(self):
        raise AttributeError("half built")


def interrupted(args, interrupts):
    cli.LEFT = HalfBuilt()  # finalized when the interpreter exits
    raise KeyboardInterrupt


cli._morphing = interrupted
sys.exit(cli.main(["morphing", "--out", sys.argv[1]]))
"""


def test_an_interrupt_says_one_line_even_when_finalizers_fail_at_exit(tmp_path):
    """The flake this guards against: a SIGINT during compilation leaves LLVM handles half built,
    and their finalizers fail when the process exits, after the one line (Python reports them as
    "Exception ignored in ..."). Here an object whose finalizer fails stands for them."""
    proc = subprocess.run([sys.executable, "-c", _HALF_BUILT, str(tmp_path / "out")],
                          capture_output=True, text=True, timeout=120)
    assert proc.returncode == 130, proc.stderr
    assert proc.stderr.strip().splitlines() == ["morphlab: interrupted"]


@pytest.mark.parametrize("out, word", [("", "empty string"), ("  ", "empty string"),
                                       ("a-file", "not a folder"),
                                       ("a-file/sub", "cannot be written")])
def test_bad_out_is_refused_before_computing(tmp_path, monkeypatch, capsys, out, word):
    (tmp_path / "a-file").write_text("x")
    monkeypatch.chdir(tmp_path)

    def never(**kw):
        raise AssertionError("the study must not start")

    monkeypatch.setattr("morphlab.morphing.leading_edge.study", never)
    assert cli.main(["morphing", "--out", out]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and word in err[0]
    assert sorted(os.listdir(tmp_path)) == ["a-file"]


@pytest.mark.parametrize("exc, status, word", [
    (SolverError("Newton failed at t=0.1\nmore"), 1, "solver failed: Newton failed at t=0.1"),
    (ModelError("bad model"), 1, "error: bad model"),
    (OSError(28, "No space left on device"), 1, "No space left"),
    (KeyboardInterrupt(), 130, "interrupted"),
])
def test_failures_while_computing_give_one_line_and_leave_nothing(tmp_path, monkeypatch,
                                                                  capsys, exc, status, word):
    def failing(out, **kw):
        (__import__("pathlib").Path(out) / "fig.png").write_bytes(b"half a figure")
        raise exc

    monkeypatch.setattr("morphlab.morphing.leading_edge.study", failing)
    assert cli.main(["morphing", "--out", str(tmp_path / "out")]) == status
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and word in err[0], err
    assert os.listdir(tmp_path) == []
    if status == 1:  # --traceback shows the original exception
        with pytest.raises(type(exc)):
            cli.main(["--traceback", "morphing", "--out", str(tmp_path / "out")])


def test_an_interrupt_python_drops_still_stops_the_command(tmp_path, monkeypatch, capsys):
    """A KeyboardInterrupt raised in a weakref callback (as a SIGINT landing in an import
    lock's callback is) is dropped by Python, and the study returns normally: the command still
    exits 130 with one line and publishes nothing."""
    import gc
    import weakref

    class Lock:
        pass

    def dropped(ref):
        raise KeyboardInterrupt

    def study(out, **kw):
        (__import__("pathlib").Path(out) / "morphing.json").write_text("finished")
        lock = Lock()
        ref = weakref.ref(lock, dropped)  # noqa: F841 - the callback fires when lock dies
        del lock
        gc.collect()
        return "report"

    monkeypatch.setattr("morphlab.morphing.leading_edge.study", study)
    assert cli.main(["morphing", "--out", str(tmp_path / "out")]) == 130
    captured = capsys.readouterr()
    assert captured.err.strip().splitlines() == ["morphlab: interrupted"]
    assert captured.out == "" and os.listdir(tmp_path) == []


def test_results_move_into_an_existing_folder(tmp_path, monkeypatch, capsys):
    out = tmp_path / "out"
    out.mkdir()
    (out / "keep.txt").write_text("mine")
    (out / "morphing.json").write_text("old")

    def ok(out, **kw):
        (__import__("pathlib").Path(out) / "morphing.json").write_text("new")
        return "report"

    monkeypatch.setattr("morphlab.morphing.leading_edge.study", ok)
    assert cli.main(["morphing", "--out", str(out), "--no-aero"]) == 0
    assert capsys.readouterr().out.strip() == "report"
    assert sorted(os.listdir(tmp_path)) == ["out"]
    assert (out / "morphing.json").read_text() == "new" and (out / "keep.txt").exists()


# ---- files
@pytest.mark.slow
def test_damaged_result_files_raise_format_error(tmp_path):
    """A saved Result with bits flipped at 300 positions spread over the whole file (headers,
    data, directory): bitwise the same result or FormatError naming the file, never another
    error or changed numbers. Truncations likewise."""
    run = ml.simulate(flexible_mechanism(), t_end=0.002, dt=1e-3)
    good = tmp_path / "r.npz"
    mio.save(run, good)
    data = good.read_bytes()
    bad = tmp_path / "bad.npz"
    rng = np.random.default_rng(19)
    cases = [bytes(b ^ (1 << int(k)) if i == pos else b for i, b in enumerate(data))
             for pos, k in zip(rng.integers(0, len(data), 300), rng.integers(0, 8, 300))]
    cases += [data[:n] for n in (0, 10, len(data) // 2, len(data) - 1)]
    for blob in cases:
        bad.write_bytes(blob)
        try:
            back = mio.load(bad)
        except FormatError as exc:
            assert str(bad) in str(exc)
            continue
        for name in ("t", "q", "v", "a", "lam"):
            assert np.array_equal(getattr(back, name), getattr(run, name)), name


# ---- model input
@pytest.mark.parametrize("kwargs, word", [
    ({}, "exactly one"),
    ({"angle": ml.Linear(1.0), "speed": 1.0}, "exactly one"),
    ({"speed": ml.Custom(np.sin)}, "closed-form integral"),
    ({"speed": ml.Sine(2.0) * ml.Ramp(0.0, 1.0)}, "closed-form integral"),
    ({"speed": "fast"}, "expected a Profile"),
    ({"speed": True}, "profile must be"),
    ({"angle": ml.Constant(0.5)}, "angle\\(0\\) must be 0"),
])
def test_bad_drives_raise_model_error_naming_the_drive(kwargs, word):
    m = ml.Model()
    crank = m.add_rigid_body(mass=1.0, inertia=1.0, position=(1.0, 0.0), name="crank")
    m.add_revolute(m.ground, crank, at=(0.0, 0.0))
    with pytest.raises(ModelError, match=word) as err:
        m.add_drive(crank, name="motor", **kwargs)
    assert "motor" in str(err.value)
