"""The benchmark record, ``benchmarks.json``: one entry per case, each with what produced it.

A run of a subset of the cases replaces those cases' entries and keeps the others, so the file
always holds the latest figure of every case; each entry carries its own command line, git
commit, machine, date and library versions, because the cases of one file may come from
different runs. A case that failed keeps its earlier figures and records the failure beside
them (``"failed_run"``), so a broken run never erases a good record silently.
"""

from __future__ import annotations

import json
import math
import os
import platform
import subprocess
import tempfile
import time
from datetime import datetime, timezone
from pathlib import Path

from ..errors import MorphlabError

#: Version of the file's layout (the suite refuses files of another layout).
FORMAT = 2


class BenchError(MorphlabError, ValueError):
    """Bad input to the benchmark suite (an unknown case, an unreadable record)."""


def cpu_model() -> str:
    """The processor's model name (``/proc/cpuinfo`` on Linux, else what Python knows)."""
    try:
        with open("/proc/cpuinfo", encoding="utf-8", errors="replace") as fh:
            for line in fh:
                if line.lower().startswith("model name"):
                    return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or platform.machine() or "unknown"


def python_loop_ns(seconds: float = 2.0, n: int = 20_000) -> tuple[float, float, float]:
    """This machine's speed: the time of one iteration of a plain Python loop adding integers
    [ns], as the median, 10th and 90th percentiles of loops of ``n`` iterations (about a
    millisecond each) repeated for ``seconds``.

    The CPU model does not tell two machines apart: virtual machines of one model have run the
    same code at speeds a factor of two or more apart, compiled kernels and Python alike. One
    machine's speed moves too: a 2-core virtual machine, idle, has switched between about 35
    and about 65 ns an iteration every second or so. One short loop samples one moment; the
    median over seconds gives the speed of the moment's mix, the percentiles its spread."""
    import numpy as np

    times = []
    end = time.perf_counter() + seconds
    while True:
        t0 = time.perf_counter()
        total = 0
        for i in range(n):
            total += i
        t1 = time.perf_counter()
        times.append(t1 - t0)
        if t1 >= end:
            break
    ns = np.asarray(times) / n * 1e9
    return float(np.median(ns)), float(np.percentile(ns, 10)), float(np.percentile(ns, 90))


def machine() -> dict:
    """Cores, usable cores, CPU model, platform and Python of this machine, and its speed
    (:func:`python_loop_ns`: the median, and the 10th and 90th percentiles beside it)."""
    from ..sensitivity.beside import usable_cores

    median, lo, hi = python_loop_ns()
    return {"cores": os.cpu_count(), "usable_cores": usable_cores(), "cpu_model": cpu_model(),
            "platform": platform.platform(), "python": platform.python_version(),
            "python_loop_ns": round(median, 1),
            "python_loop_ns_p10_p90": [round(lo, 1), round(hi, 1)]}


def versions() -> dict:
    """Versions of morphlab and of the libraries its run time depends on."""
    import numba
    import numpy
    import scipy

    from .._version import __version__

    return {"morphlab": __version__, "numba": numba.__version__, "numpy": numpy.__version__,
            "scipy": scipy.__version__}


def git_state(path: str | os.PathLike | None = None) -> dict:
    """``{"commit": sha, "dirty": bool}`` of the git checkout holding ``path`` (default: this
    package's source); None each when it is not in a git checkout or git is missing.
    ``dirty`` says that the measured code, the package's files, differed from the commit
    (uncommitted changes; other files, such as the record itself, do not count)."""
    where = Path(path) if path is not None else Path(__file__).resolve().parents[2]
    try:
        sha = subprocess.run(["git", "rev-parse", "HEAD"], cwd=where, capture_output=True,
                             text=True, timeout=30)
        if sha.returncode != 0:
            return {"commit": None, "dirty": None}
        status = subprocess.run(["git", "status", "--porcelain", "--untracked-files=no", "--",
                                 str(Path(__file__).resolve().parents[1])],
                                cwd=where, capture_output=True, text=True, timeout=30)
    except (OSError, subprocess.SubprocessError):
        return {"commit": None, "dirty": None}
    return {"commit": sha.stdout.strip(),
            "dirty": bool(status.stdout.strip()) if status.returncode == 0 else None}


def now() -> str:
    """The current UTC time, ISO 8601 to the second."""
    return datetime.now(timezone.utc).isoformat(timespec="seconds")


def entry(result: dict | None, *, command: str, repeats: int, quick: bool, seconds: float,
          load: tuple | None = None, error: str | None = None, context: dict | None = None
          ) -> dict:
    """One case's entry: its ``result`` (or ``error``) with what produced it.

    Parameters
    ----------
    result : dict or None
        The case's figures (None when it failed).
    command : str
        The command line of the run.
    repeats : int
        Timed runs per figure.
    quick : bool
        Reduced sizes (``--quick``): not the reference figures.
    seconds : float
        Wall time the case took [s].
    load : (float, float), optional
        One-minute load average before and after the case (the machine may be shared).
    error : str, optional
        Why the case failed.
    context : dict, optional
        ``{"commit", "dirty", "machine", "versions"}``, computed once per run (default:
        computed here).
    """
    ctx = context if context is not None else run_context()
    out = {"command": command, "date": now(), "commit": ctx["commit"], "dirty": ctx["dirty"],
           "machine": ctx["machine"], "versions": ctx["versions"], "repeats": repeats,
           "quick": bool(quick), "seconds": seconds,
           "load_average": list(load) if load is not None else None}
    if error is not None:
        out["error"] = error
    else:
        out["result"] = result
    return out


def run_context() -> dict:
    """What every entry of one run shares: commit, machine and versions."""
    return {**git_state(), "machine": machine(), "versions": versions()}


def empty() -> dict:
    """A record without cases."""
    return {"format": FORMAT, "cases": {}}


def load(path: str | os.PathLike) -> dict:
    """The record in ``path``; an empty record if the file does not exist.

    Raises
    ------
    BenchError
        The file is not JSON, or not a record of this layout (:data:`FORMAT`).
    """
    p = Path(path)
    if not p.exists():
        return empty()
    try:
        data = json.loads(p.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise BenchError(f"{p}: not a readable benchmark record ({exc})") from exc
    if not isinstance(data, dict) or data.get("format") != FORMAT or not isinstance(
            data.get("cases"), dict):
        found = data.get("format") if isinstance(data, dict) else type(data).__name__
        raise BenchError(f"{p}: not a benchmark record of format {FORMAT} (found format "
                         f"{found!r}); a record of an earlier suite cannot be merged: move it "
                         "away or give another file with --out")
    return data


def merge(record: dict, entries: dict) -> dict:
    """``record`` with ``entries`` (case -> :func:`entry`) in place of its cases' entries.

    A failed entry (with ``"error"``) does not erase an earlier result of its case: the
    earlier entry is kept and the failure is recorded in it as ``"failed_run"``.
    """
    out = {"format": FORMAT, "cases": dict(record.get("cases", {}))}
    for case, new in entries.items():
        old = out["cases"].get(case)
        if "error" in new and old is not None and "result" in old:
            failed = {k: new[k] for k in ("command", "date", "commit", "dirty", "error")}
            out["cases"][case] = {**old, "failed_run": failed}
        else:
            out["cases"][case] = new
    return out


def _finite(x):
    """``x`` with NumPy scalars as Python numbers and every non-finite float replaced by None
    (strict JSON has no NaN)."""
    if hasattr(x, "item") and getattr(x, "ndim", None) == 0:  # a NumPy scalar
        x = x.item()
    if isinstance(x, dict):
        return {k: _finite(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_finite(v) for v in x]
    if isinstance(x, float) and not math.isfinite(x):
        return None
    return x


def save(record: dict, path: str | os.PathLike) -> None:
    """Write ``record`` to ``path`` atomically (a temporary file moved into place)."""
    p = Path(path)
    fd, tmp = tempfile.mkstemp(prefix=f".{p.name}.", dir=p.parent or ".")
    try:
        with os.fdopen(fd, "w", encoding="utf-8") as fh:
            json.dump(_finite(record), fh, indent=1, allow_nan=False)
            fh.write("\n")
        os.chmod(tmp, p.stat().st_mode & 0o777 if p.exists() else 0o644)  # not mkstemp's 0600
        os.replace(tmp, p)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
