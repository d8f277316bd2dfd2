"""Benchmark case ``compile``: what a first use costs with an empty Numba cache.

Every scenario of :mod:`morphlab.bench.scenarios` runs in a fresh process whose Numba cache
is an empty temporary folder (``NUMBA_CACHE_DIR``; the kernels use ``cache=True``, so without
it they would load from the filled cache next to their sources, :mod:`morphlab.jit.cache`):

* ``quickstart``: the README quickstart's first result;
* ``direct``, ``adjoint``, ``complex-step``, ``direct-fd``: the same first result, then the
  quickstart's first ``sensitivities`` with that method. The method's own cost is the
  process's CPU minus that of the ``quickstart`` process of the same round (the brief's
  definition: on top of a compiled primal); the CPU of the method's phase measured inside the
  process is kept beside it;
* ``every-item``: the first result of a model with every kind of item;
* ``main-command``: ``morphlab morphing --out DIR`` on its defaults.

The process CPU (user + system of the child and anything it waited for, from
``getrusage(RUSAGE_CHILDREN)``) and the wall time are measured from outside. Inside, a Numba
event listener (:class:`CompileRecorder`, on ``"numba:compile"``) records the CPU of every
compilation of a kernel for a signature; a compilation that triggers another (a kernel calling
a kernel compiles its callee first) is charged its own time only (self time = its time minus
that of the compilations nested in it), so the self times add up to the compile CPU. A cache
load is no compilation and is not recorded. Kernels compiled in another process (a helper)
would be missing from the table; the process CPU would still count them. Of each self time, the
part spent inside LLVM (Numba's ``"numba:llvm_lock"`` event, broadcast around every call into
LLVM: parsing, optimizing and emitting machine code) is recorded apart, so the table tells
Numba's own work (typing, lowering to LLVM IR in Python, the wrappers) from LLVM's; listening
to it adds a few microseconds of Python per call into LLVM (tens of thousands per scenario).

Rounds are interleaved: every round runs each scenario once, so a change of the machine's load
weighs on all of them alike.
"""

from __future__ import annotations

import json
import os
import resource
import shutil
import statistics
import subprocess
import sys
import tempfile
import threading
import time
from collections import defaultdict

from numba.core import event

from ..jit.progress import ESTIMATES
from ..studies.timing import time_stats
from .scenarios import METHODS, SCENARIOS

#: The compile notice each scenario's own phase prints (its key of
#: :data:`morphlab.jit.progress.ESTIMATES`), whose estimate the record keeps beside the
#: measured compile; the main command compiles several groups in two processes and has none.
NOTICE = {"quickstart": "time loop", "every-item": "time loop, every item kind",
          **{m: m for m in METHODS}}


class CompileRecorder(event.Listener):
    """Records every Numba compilation while installed (a context manager).

    Each record: ``kernel`` (module and qualified name of the Python function), ``signature``
    (the argument types as text), ``complex`` (does any argument type hold complex numbers),
    ``cpu_s`` (thread CPU of the whole compilation), ``self_cpu_s`` (minus the compilations
    nested in it), ``llvm_cpu_s`` (the part of ``self_cpu_s`` spent in calls into LLVM) and
    ``phase`` (the value of :attr:`phase` when it started).
    """

    def __init__(self):
        self.records: list[dict] = []
        self.phase = ""
        self._local = threading.local()

    def _stack(self) -> list:
        if not hasattr(self._local, "stack"):
            self._local.stack = []
        return self._local.stack

    def on_start(self, ev) -> None:
        if ev.kind == "numba:llvm_lock":  # LLVM's lock is reentrant: the outermost span
            depth = getattr(self._local, "llvm_depth", 0)
            if depth == 0:
                self._local.llvm_t0 = time.thread_time()
            self._local.llvm_depth = depth + 1
            return
        self._stack().append([time.thread_time(), 0.0, self.phase, 0.0])

    def on_end(self, ev) -> None:
        stack = self._stack()
        if ev.kind == "numba:llvm_lock":  # a call into LLVM: the current compilation's
            depth = getattr(self._local, "llvm_depth", 0) - 1
            self._local.llvm_depth = max(depth, 0)
            if depth == 0 and stack:
                stack[-1][3] += time.thread_time() - self._local.llvm_t0
            return
        t0, nested, phase, llvm = stack.pop()
        total = time.thread_time() - t0
        if stack:
            stack[-1][1] += total
        fn = ev.data["dispatcher"].py_func
        sig = str(ev.data.get("args"))
        self.records.append({"kernel": f"{fn.__module__}.{fn.__qualname__}", "signature": sig,
                             "complex": "complex" in sig, "cpu_s": total,
                             "self_cpu_s": total - nested, "llvm_cpu_s": llvm,
                             "phase": phase})

    def __enter__(self) -> CompileRecorder:
        event.register("numba:compile", self)
        event.register("numba:llvm_lock", self)
        return self

    def __exit__(self, *exc) -> None:
        event.unregister("numba:llvm_lock", self)
        event.unregister("numba:compile", self)


def kernel_table(records: list[dict], phase: str | None = None) -> dict:
    """Per kernel: ``{"signatures", "complex_signatures", "self_cpu_s", "llvm_cpu_s"}`` of
    the records (of one ``phase``, or all)."""
    out: dict = defaultdict(lambda: {"signatures": 0, "complex_signatures": 0,
                                     "self_cpu_s": 0.0, "llvm_cpu_s": 0.0})
    for r in records:
        if phase is not None and r["phase"] != phase:
            continue
        row = out[r["kernel"]]
        row["signatures"] += 1
        row["complex_signatures"] += int(r["complex"])
        row["self_cpu_s"] += r["self_cpu_s"]
        row["llvm_cpu_s"] += r["llvm_cpu_s"]
    return dict(out)


# ------------------------------------------------------------------------------ child process
def _child(argv: list[str]) -> int:
    """``python -m morphlab.bench.compile SCENARIO JSON [--quick] [--out-dir DIR]``: run the
    scenario under a :class:`CompileRecorder` and write what it measured to JSON."""
    from ..jit.cache import kernel_cache_dir
    from .scenarios import run

    scenario, path = argv[0], argv[1]
    quick = "--quick" in argv
    out_dir = argv[argv.index("--out-dir") + 1] if "--out-dir" in argv else None
    with CompileRecorder() as rec:
        measured = run(scenario, out_dir=out_dir, quick=quick, recorder=rec)
    measured.update({"scenario": scenario, "cache_dir": kernel_cache_dir(),
                     "compilations": len(rec.records),
                     "kernels": {ph: kernel_table(rec.records, ph) for ph in measured["phases"]}})
    with open(path, "w", encoding="utf-8") as fh:
        json.dump(measured, fh)
    return 0


def timed_process(cmd: list[str], *, env: dict | None = None, timeout: float | None = None
                  ) -> tuple[subprocess.CompletedProcess, dict]:
    """Run ``cmd`` (output captured as text) and return it with its CPU time (user and
    system, ``getrusage(RUSAGE_CHILDREN)``) and wall time from outside, ``{"cpu_s",
    "wall_s"}`` [s], and ``launched``: the clock (``time.time()``) at its launch."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    launched = time.time()
    w0 = time.perf_counter()
    proc = subprocess.run(cmd, env=env, capture_output=True, text=True, timeout=timeout)
    wall = time.perf_counter() - w0
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    return proc, {"cpu_s": (after.ru_utime - before.ru_utime)
                  + (after.ru_stime - before.ru_stime), "wall_s": wall, "launched": launched}


def fresh_process(scenario: str, *, cache_dir: str | None, quick: bool = False,
                  timeout: float = 3600.0) -> dict:
    """Run ``scenario`` in a new Python process (with ``NUMBA_CACHE_DIR=cache_dir``; None:
    the default cache) and return what it measured with its process CPU and wall time.

    Raises
    ------
    RuntimeError
        The process failed (the end of its error output in the message).
    """
    env = dict(os.environ)
    if cache_dir is not None:
        env["NUMBA_CACHE_DIR"] = cache_dir
    work = tempfile.mkdtemp(prefix="morphlab-bench-")
    try:
        path = os.path.join(work, "measured.json")
        cmd = [sys.executable, "-m", "morphlab.bench.compile", scenario, path]
        if quick:
            cmd.append("--quick")
        if scenario == "main-command":
            cmd += ["--out-dir", os.path.join(work, "out")]
        proc, times = timed_process(cmd, env=env, timeout=timeout)
        if proc.returncode != 0:
            tail = [x.strip() for x in (proc.stderr or proc.stdout).strip().splitlines()[-5:]]
            raise RuntimeError(f"scenario {scenario!r} failed (status {proc.returncode}): "
                               f"{tail[-1] if tail else '?'} (after: {' | '.join(tail[:-1])})")
        with open(path, encoding="utf-8") as fh:
            measured = json.load(fh)
    finally:
        shutil.rmtree(work, ignore_errors=True)
    measured["process"] = {k: times[k] for k in ("cpu_s", "wall_s")}
    return measured


def _cold(scenario: str, quick: bool) -> dict:
    """:func:`fresh_process` with an empty cache of its own, checked to have been used."""
    cache = tempfile.mkdtemp(prefix="morphlab-numba-cache-")
    try:
        m = fresh_process(scenario, cache_dir=cache, quick=quick)
    finally:
        shutil.rmtree(cache, ignore_errors=True)
    if not str(m.get("cache_dir") or "").startswith(cache):
        raise RuntimeError(f"scenario {scenario!r}: the kernels were cached in "
                           f"{m.get('cache_dir')!r}, not in the empty folder {cache!r} "
                           "(NUMBA_CACHE_DIR ignored?): not a cold start")
    return m


def _median_table(tables: list[dict]) -> dict:
    """Per kernel: the median over rounds of its self CPU (and the part of it in LLVM) and its
    signature counts."""
    names = sorted({k for t in tables for k in t})
    zero = {"signatures": 0, "complex_signatures": 0, "self_cpu_s": 0.0, "llvm_cpu_s": 0.0}
    return {k: {f: statistics.median([t.get(k, zero)[f] for t in tables]) for f in zero}
            for k in names}


def case_compile(repeats: int, quick: bool, *, scenarios=SCENARIOS) -> dict:
    """The ``compile`` case (module docstring): per scenario the process CPU and wall [s]
    (median, min, max over ``repeats`` interleaved rounds), the CPU of each phase, and the
    compile CPU per kernel; per method the CPU on top of the quickstart's primal.

    ``quick`` runs the main command with ``--quick``; ``scenarios`` selects a subset (the
    methods need ``"quickstart"`` for their difference). A scenario that fails keeps its error
    in ``"errors"``; the case fails when every scenario does.
    """
    runs: dict = {s: [] for s in scenarios}
    errors: dict = {}
    for _ in range(repeats):
        for s in scenarios:
            if s in errors:
                continue
            try:
                runs[s].append(_cold(s, quick))
            except (RuntimeError, OSError, subprocess.SubprocessError) as exc:
                errors[s] = f"{type(exc).__name__}: {exc}"[:1500]
            print(f"  [compile: {s} done]", file=sys.stderr, flush=True)
    if not any(runs.values()):
        raise RuntimeError("every scenario failed: " + "; ".join(f"{k}: {v}" for k, v in
                                                                 errors.items()))
    out: dict = {"scenarios": {}, "errors": errors,
                 "main_command": "morphlab morphing --out DIR" + (" --quick" if quick else "")}
    for s, ms in runs.items():
        if not ms:
            continue
        phases = list(ms[0]["phases"])
        row = {"process_cpu_s": time_stats([m["process"]["cpu_s"] for m in ms]),
               "process_wall_s": time_stats([m["process"]["wall_s"] for m in ms]),
               "phases": {p: {"cpu_s": time_stats([m["phases"][p]["cpu_s"] for m in ms]),
                              "wall_s": time_stats([m["phases"][p]["wall_s"] for m in ms])}
                          for p in phases},
               "compilations": statistics.median([m["compilations"] for m in ms]),
               "kernels": {p: _median_table([m["kernels"][p] for m in ms]) for p in phases}}
        if "kinds" in ms[0]:
            row["kinds"] = ms[0]["kinds"]
        if NOTICE.get(s) in ESTIMATES:
            row["notice_estimate_cpu_s"] = ESTIMATES[NOTICE[s]]
        out["scenarios"][s] = row
    base = runs.get("quickstart", [])
    for s in METHODS:
        ms = runs.get(s, [])
        n = min(len(ms), len(base))
        if n:  # round by round: the method's process against the primal-only process
            out["scenarios"][s]["method_cpu_s"] = time_stats(
                [ms[i]["process"]["cpu_s"] - base[i]["process"]["cpu_s"] for i in range(n)])
    return out


if __name__ == "__main__":
    sys.exit(_child(sys.argv[1:]))
