"""Every notebook runs top to bottom, and every Python snippet of the README runs.

Notebooks read ``MORPHLAB_QUICK=1`` to use their reduced size (each states its full-size
default); each notebook's last cell asserts its key number against its reference.

Two runs per notebook:

* ``test_notebook_runs``: the reduced size, as a check of the code and the claims;
* ``test_notebook_full_size`` (slow): the default size a user gets, within a time limit.
  Every default run must finish in :data:`LIMIT_S` on an idle 2-core machine with a warm
  kernel cache, and a cell that takes more than :data:`QUIET_S` must show a progress line
  (text that rewrites itself with a carriage return: the bars of ``sweep`` and the lines of
  ``form``, ``compare_optimizers`` and the notebooks' own loops). Both limits are scaled for
  a loaded machine by ``min(MAX_SCALE, max(1, load / cores))``, the 1-minute load average
  before the notebook starts over the cores (rule in :func:`load_scale`), and for a machine
  slower than the one they were set on by the time of the notebooks' main workload, the
  morphing study's primal run, against its time there (:func:`speed_scale`); the product is
  at most :data:`MAX_TOTAL_SCALE`.
"""

import math
import os
import pathlib
import re
import time

import pytest

ROOT = pathlib.Path(__file__).resolve().parents[1]
NOTEBOOKS = sorted((ROOT / "notebooks").glob("*.ipynb"))

#: Default (full-size) run of one notebook on an idle 2-core machine, warm cache [s].
LIMIT_S = 300.0
#: Longest a cell may run without printing a progress line [s].
QUIET_S = 120.0
#: The largest allowance for load: a run over 2.5 x 300 s = 750 s fails however loaded the
#: machine (notebook 05's optimizer comparison ran for over 900 s before its budget).
MAX_SCALE = 2.5
#: The morphing study's primal run (build, compile, simulate, responses; warm cache) on the
#: machine :data:`LIMIT_S` was set on [s]: BENCHMARKS.md's record of it (commit 65bd236).
REF_PRIMAL_S = 0.053
#: The largest allowance for load and a slow machine together: a run over 4 x 300 s = 20 min
#: fails however slow or loaded the machine.
MAX_TOTAL_SCALE = 4.0
#: Reduced-size runs of ~10 s or more on a warm cache (2 cores, load ~2: 05 23 s, 09 20 s,
#: 08 20 s, 04 and 06 9 s; the others 3-5 s): in the slow set.
QUICK_SLOW = {"04_timing", "05_design", "06_parameter_study", "08_flight_loads", "09_reliability"}


def load_scale() -> float:
    """The allowance for other work on the machine: the 1-minute load average over the
    cores, at least 1 (an idle machine, or one loaded by less than its cores) and at most
    :data:`MAX_SCALE`. On a machine whose cores are all busy with other work a notebook gets
    about half of them, so it takes about twice as long."""
    try:
        load = os.getloadavg()[0]
    except OSError:  # no load average on this platform: no allowance
        return 1.0
    return min(MAX_SCALE, max(1.0, load / (os.cpu_count() or 1)))


def speed_scale() -> float:
    """The allowance for a slower machine: the best of three morphing primal runs (what most
    of the notebooks' time goes to) over :data:`REF_PRIMAL_S`, at least 1. The workload
    itself is timed: machines of one CPU model and core count have run it a factor of two or
    more apart."""
    from morphlab.bench.gradients import _primal
    from morphlab.morphing import leading_edge as le
    from morphlab.studies.timing import timed

    primal = _primal(le.build, le.DEFAULTS, le.RESPONSES, le.SETTINGS)  # the bench's primal
    best = timed(primal, 3)[0]["min"]  # after a first call that loads (or compiles) kernels
    return max(1.0, best / REF_PRIMAL_S)


def _execute(path, tmp_path, monkeypatch, quick: bool, timeout: float):
    """Run the notebook at ``path`` in ``tmp_path``; returns it with its outputs."""
    nbformat = pytest.importorskip("nbformat")
    nbclient = pytest.importorskip("nbclient")
    if quick:
        monkeypatch.setenv("MORPHLAB_QUICK", "1")
    else:
        monkeypatch.delenv("MORPHLAB_QUICK", raising=False)
    monkeypatch.setenv("MPLBACKEND", "Agg")
    nb = nbformat.read(path, as_version=4)
    client = nbclient.NotebookClient(nb, timeout=timeout, kernel_name="python3",
                                     resources={"metadata": {"path": str(tmp_path)}})
    client.execute()
    return nb


def _cell_seconds(cell) -> float:
    """Wall time of an executed cell, from the timestamps nbclient records."""
    from datetime import datetime

    ex = cell.metadata.get("execution", {})
    start, end = ex.get("iopub.execute_input"), ex.get("shell.execute_reply")
    if not (start and end):
        return 0.0
    return (datetime.fromisoformat(end.replace("Z", "+00:00"))
            - datetime.fromisoformat(start.replace("Z", "+00:00"))).total_seconds()


def _has_progress_line(cell) -> bool:
    """Did the cell print a line that rewrites itself (a progress bar)?"""
    return any(out.get("output_type") == "stream" and "\r" in out.get("text", "")
               for out in cell.get("outputs", []))


@pytest.mark.parametrize("path", [
    pytest.param(p, id=p.stem, marks=[pytest.mark.slow] if p.stem in QUICK_SLOW else [])
    for p in NOTEBOOKS])
def test_notebook_runs(path, tmp_path, monkeypatch):
    _execute(path, tmp_path, monkeypatch, quick=True, timeout=600)


@pytest.mark.slow
@pytest.mark.parametrize("path", NOTEBOOKS, ids=[p.stem for p in NOTEBOOKS])
def test_notebook_full_size(path, tmp_path, monkeypatch):
    """Up to ~5 min per notebook: the default size within LIMIT_S, and no cell longer than
    QUIET_S without a progress line, both scaled for the machine's load and speed (module
    docstring)."""
    load, speed = load_scale(), speed_scale()
    scale = min(MAX_TOTAL_SCALE, load * speed)
    limit = LIMIT_S * scale
    t0 = time.perf_counter()
    # a cell may take the whole limit; nbclient stops one that runs longer
    nb = _execute(path, tmp_path, monkeypatch, quick=False, timeout=math.ceil(limit))
    wall = time.perf_counter() - t0
    print(f"{path.stem}: {wall:.1f} s (limit {limit:.0f} s: load scale {load:.2f}, "
          f"speed scale {speed:.2f})")
    assert wall <= limit, f"{path.stem} took {wall:.0f} s, over its limit of {limit:.0f} s"
    quiet = [(i, round(_cell_seconds(c))) for i, c in enumerate(nb.cells)
             if c.cell_type == "code" and _cell_seconds(c) > QUIET_S * scale
             and not _has_progress_line(c)]
    assert not quiet, f"cells (index, seconds) over {QUIET_S * scale:.0f} s without a " \
                      f"progress line: {quiet}"


@pytest.mark.parametrize("load, cores, scale", [(0.3, 2, 1.0), (2.0, 2, 1.0), (3.0, 2, 1.5),
                                               (8.0, 4, 2.0), (40.0, 2, MAX_SCALE)])
def test_load_scale_rule(load, cores, scale, monkeypatch):
    """The allowance is the load over the cores, between 1 and MAX_SCALE."""
    monkeypatch.setattr(os, "getloadavg", lambda: (load, load, load))
    monkeypatch.setattr(os, "cpu_count", lambda: cores)
    assert load_scale() == scale


def _readme_snippets():
    text = (ROOT / "README.md").read_text(encoding="utf-8")
    return re.findall(r"```python\n(.*?)```", text, flags=re.S)


def test_readme_has_snippets():
    assert len(_readme_snippets()) >= 1


@pytest.mark.parametrize("index", range(len(_readme_snippets())))
def test_readme_snippet_runs(index, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    monkeypatch.setenv("MORPHLAB_QUICK", "1")
    code = _readme_snippets()[index]
    exec(compile(code, f"README snippet {index}", "exec"), {"__name__": "__readme__"})
