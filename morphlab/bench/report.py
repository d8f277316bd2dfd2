"""BENCHMARKS.md and its details page, generated from ``benchmarks.json``
(:mod:`morphlab.bench.record`).

Both read only the record, so ``python -m morphlab.bench --report`` rewrites them without
running anything. :func:`render`, the one page a reader opens: each case's key figures
(:mod:`~morphlab.bench.report_glance`) with the targets of the issues (:data:`TARGETS`), and
the command, commit and date of each case. :func:`render_detail`, ``docs/benchmarks-detail.md``:
one section per case with every table (:mod:`~morphlab.bench.report_cases`), medians with their
min–max, the machine and its load.
"""

from __future__ import annotations

import os
from pathlib import Path

from . import report_cases as cases
from . import report_glance as glance

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
    "startup": "warm start, filled cache: import, the quickstart's first result, the floor",
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

The current figure of each benchmark case, generated from `benchmarks.json` by `python -m
morphlab.bench --report`; do not edit by hand. Times are medians of repeated runs in one
process; a ratio is formed from medians of one run. ✓ / ✗: the target of the issue named is
met / not met. Every table in full, with the min–max of the runs, the compile time per kernel
and each run's machine and load: [docs/benchmarks-detail.md](docs/benchmarks-detail.md);
earlier rounds, on older code: [docs/benchmarks-history.md](docs/benchmarks-history.md).
Machines of one CPU model can differ in speed by a factor of two or more (virtual machines
especially), and one virtual machine's speed can change from second to second: each run gives
its machine's time for one iteration of a plain Python loop ("Python loop": the median over
two seconds, the 10th to 90th percentiles in brackets), and times of runs whose loops differ
are not comparable; ratios measured in one run are.
"""

DETAIL_HEADER = """# Benchmarks in detail

Generated from `benchmarks.json` by `python -m morphlab.bench --report` with
[BENCHMARKS.md](../BENCHMARKS.md), its one-page summary; do not edit by hand (run the command
under a section to measure it again: the record keeps the other sections). Every time is the
median of repeated runs in one process, with the min–max of the runs in brackets; the runs of
one table take turns in interleaved rounds, and every ratio is formed from medians of one run.
A ratio's brackets are the method's min and max over the median primal. Targets are those of
the issues named; ✓ met, ✗ not met. Earlier rounds, measured on older code:
[benchmarks-history.md](benchmarks-history.md).
"""

#: Where ``--report`` writes the details page, relative to the summary page's folder.
DETAIL_PATH = Path("docs") / "benchmarks-detail.md"


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
             f"{m.get('cores', '?')} cores{_speed(m, ', ')}{load} · Python "
             f"{m.get('python', '?')}, numba "
             f"{v.get('numba', '?')}, numpy {v.get('numpy', '?')}", ""]
    if e.get("quick"):
        lines += ["**Quick run** (reduced sizes, `--quick`): not the reference figures.", ""]
    if "failed_run" in e:
        f = e["failed_run"]
        lines += [f"The latest run of this case ({f['date']}, `{f['command']}`) failed: "
                  f"{cases.clip(f['error'])}; the figures below are from the run before it.", ""]
    return lines


def render(record: dict) -> str:
    """The one-page summary for ``record`` (:mod:`morphlab.bench.record`): each case's key
    figures with their targets, then the command, duration, commit and date of each case."""
    known, other = _cases(record)
    lines = [HEADER, "| case | figure | measured | target |", "|---|---|---|---|"]
    runs = ["| case | command | took | commit | date |", "|---|---|---|---|---|"]
    for case in known:
        e = record["cases"][case]
        if "error" in e:
            rows = [(DESCRIPTIONS[case], f"failed: {cases.clip(e['error'], 120)}", "")]
        else:
            try:
                rows = getattr(glance, case)(e["result"], check)
            except (KeyError, TypeError, ValueError) as exc:  # a record of another layout
                rows = [(DESCRIPTIONS[case], f"not summarized ({type(exc).__name__}: {exc}); "
                         "see the details page", "")]
        lines += [f"| {case} | {a} | {b} | {c} |" for a, b, c in rows]
        m = e.get("machine") or {}
        note = "; **quick run**: not the reference figures" if e.get("quick") else ""
        if "failed_run" in e:
            note += f"; its latest run ({e['failed_run']['date'][:10]}) failed"
        commit = (e.get("commit") or "unknown")[:7] + ("+" if e.get("dirty") else "")
        runs.append(f"| {case} | `{reproduce(case, e)}`{note} | {e.get('seconds', 0):.0f} s | "
                    f"{commit} | {str(e.get('date', '?'))[:10]}, {m.get('usable_cores', '?')} "
                    f"cores{_speed(m, ', ')}, load {_load(e)} |")
    lines += ["", "Each case as it was last measured (commit: `+` with uncommitted changes; "
              "load: the one-minute load average before the run):", ""] + runs
    if other:
        lines += ["", f"Cases in the record this suite does not render: {', '.join(other)}."]
    return "\n".join(lines).rstrip() + "\n"


def _cases(record: dict) -> tuple[list, list]:
    """The record's cases this suite renders, in the page's order, and the others."""
    return ([c for c in DESCRIPTIONS if c in record["cases"]],
            [c for c in record["cases"] if c not in DESCRIPTIONS])


def _speed(m: dict, sep: str) -> str:
    """The machine's speed as recorded (``record.python_loop_ns``: the median, and the 10th
    to 90th percentiles where recorded); nothing for a record taken before it was."""
    ns = m.get("python_loop_ns")
    if not ns:
        return ""
    spread = m.get("python_loop_ns_p10_p90")
    return f"{sep}Python loop {ns:.0f} ns" + (f" ({spread[0]:.0f}–{spread[1]:.0f})"
                                               if spread else "")


def _load(e: dict) -> str:
    load = e.get("load_average")
    return f"{load[0]:.1f}" if load else "?"


def render_detail(record: dict) -> str:
    """The details page for ``record``: every case's tables in full, with its command,
    commit, machine and date."""
    lines = [DETAIL_HEADER]
    known, other = _cases(record)
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


def write(record: dict, path: str | os.PathLike) -> tuple[int, Path]:
    """Write :func:`render` of ``record`` to ``path`` and :func:`render_detail` to
    :data:`DETAIL_PATH` beside it; returns the summary's number of lines and the details
    page's path."""
    text = render(record)
    Path(path).write_text(text, encoding="utf-8")
    detail = Path(path).parent / DETAIL_PATH
    detail.parent.mkdir(parents=True, exist_ok=True)
    detail.write_text(render_detail(record), encoding="utf-8")
    return text.count("\n"), detail
