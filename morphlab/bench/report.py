"""BENCHMARKS.md, generated from ``benchmarks.json`` (:mod:`morphlab.bench.record`).

:func:`render` reads only the record, so ``python -m morphlab.bench --report`` rewrites the page
without running anything. One section per case: the command that reproduces it, its commit,
machine and date, medians with their min–max, the ratios, and the targets of the issues
(:data:`TARGETS`) beside the figures they judge.
"""

from __future__ import annotations

import os
from pathlib import Path

from . import report_cases as cases

#: Targets of the issues: (figure, limit, issue). ``<=``: at most; ``>=``: at least.
TARGETS = {
    "compile.quickstart": ("<=", 8.0, 36), "compile.method": ("<=", 10.0, 36),
    "compile.every-item": ("<=", 15.0, 36), "compile.main-command": ("<=", 60.0, 36),
    "compile.main-command.wall": ("<=", 45.0, 36), "startup.first_result": ("<=", 1.5, 36),
    "morphing.best_over_primal": ("<=", 1.20, 37),
    "morphing.finite_difference_over_best": (">=", 5.0, 37),
    "variables.50": ("<=", 1.6, 37), "variables.200": ("<=", 2.0, 37),
    "pendulum.best_over_primal": ("<=", 1.4, 37),
}

#: Cases in the order of the page, with a one-line description (also the CLI's help).
DESCRIPTIONS = {
    "compile": "first use, empty Numba cache: CPU per scenario and per kernel",
    "startup": "warm start: import, and the quickstart's first result, filled cache",
    "morphing": "Table 2: every method's cost in primal runs, morphing defaults",
    "variables": "gradient cost against 1 ... 200 design variables, 240-element skin",
    "pendulum": "flexible pendulum, 32 thickness variables, one response",
    "optimizers": "notebook 05's optimizer comparison on its full budget",
    "aero": "flight loads: per flow evaluation, per coupled solve, drag gradient",
    "elements": "time per step and memory against 30 ... 3000 skin elements",
    "memory": "peak memory of the adjoint on a long run",
    "sweep": "parameter-study throughput: serial, process pool, Dask",
    "exudyn": "the flexible pendulum beside Exudyn (if installed)",
}

HEADER = """# Benchmarks

Generated from `benchmarks.json` by `python -m morphlab.bench --report`; do not edit by hand
(run the command under a section to measure it again: the record keeps the other sections).
Every time is the median of repeated runs in one process, with the min–max of the runs in
brackets; the runs of one table take turns in interleaved rounds, and every ratio is formed
from medians of one run. A ratio's brackets are the method's min and max over the median
primal. Targets are those of the issues named; ✓ met, ✗ not met. Earlier rounds, measured on
older code: [docs/benchmarks-history.md](docs/benchmarks-history.md).
"""


def check(key: str, value) -> str:
    """``"≤ 8 ✓ (#36)"``-style text of the target ``key`` for ``value`` (None: not measured);
    empty when :data:`TARGETS` has no such key."""
    if key not in TARGETS:
        return ""
    op, limit, issue = TARGETS[key]
    sign = "≤" if op == "<=" else "≥"
    if value is None:
        return f"{sign} {limit:g} (#{issue})"
    ok = value <= limit if op == "<=" else value >= limit
    return f"{sign} {limit:g} {'✓' if ok else '✗'} (#{issue})"


def reproduce(case: str, entry: dict) -> str:
    """The command that measures ``case`` again as its entry was measured."""
    quick = " --quick" if entry.get("quick") else ""
    return f"python -m morphlab.bench --cases {case} --repeats {entry.get('repeats')}{quick}"


def _meta(case: str, e: dict) -> list[str]:
    m, v = e.get("machine") or {}, e.get("versions") or {}
    commit = (e.get("commit") or "unknown")[:10] + (" with uncommitted changes" if e.get(
        "dirty") else "")
    load = e.get("load_average")
    load = f"; load {load[0]:.1f} → {load[1]:.1f}" if load else ""
    date = str(e.get("date", "?")).replace("T", " ").replace("+00:00", " UTC")
    lines = [f"`{reproduce(case, e)}` ({e.get('seconds', 0):.0f} s) · {date} · "
             f"commit {commit} · {m.get('cpu_model', '?')}, {m.get('usable_cores', '?')} of "
             f"{m.get('cores', '?')} cores{load} · Python {m.get('python', '?')}, numba "
             f"{v.get('numba', '?')}, numpy {v.get('numpy', '?')}", ""]
    if e.get("quick"):
        lines += ["**Quick run** (reduced sizes, `--quick`): not the reference figures.", ""]
    if "failed_run" in e:
        f = e["failed_run"]
        lines += [f"The latest run of this case ({f['date']}, `{f['command']}`) failed: "
                  f"{cases.clip(f['error'])}; the figures below are from the run before it.", ""]
    return lines


def render(record: dict) -> str:
    """The page for ``record`` (:mod:`morphlab.bench.record`)."""
    lines = [HEADER]
    known = [c for c in DESCRIPTIONS if c in record["cases"]]
    other = [c for c in record["cases"] if c not in DESCRIPTIONS]
    for case in known:
        e = record["cases"][case]
        lines += [f"## {case}: {DESCRIPTIONS[case]}", ""] + _meta(case, e)
        if "error" in e:
            lines += [f"Failed: {cases.clip(e['error'], 500)}", ""]
            continue
        lines += getattr(cases, case.replace("-", "_"))(e["result"], check)
    if other:
        lines += [f"Cases in the record this suite does not render: {', '.join(other)}.", ""]
    return "\n".join(lines).rstrip() + "\n"


def write(record: dict, path: str | os.PathLike) -> int:
    """Write :func:`render` of ``record`` to ``path``; returns the number of lines."""
    text = render(record)
    Path(path).write_text(text, encoding="utf-8")
    return text.count("\n")
