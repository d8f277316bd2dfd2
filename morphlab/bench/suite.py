"""The benchmark suite: ``python -m morphlab.bench [--cases ...] [--repeats N] [--quick]
[--report]``.

Each case is a function ``case(repeats, quick) -> dict`` of figures; every timed figure is a
median over ``repeats`` runs in one process with its min and max, the runs of one comparison
interleaved round by round, and every ratio formed within one run. The results are merged into
``benchmarks.json`` (:mod:`morphlab.bench.record`: a run of some cases replaces those and keeps
the others), each case with its command line, commit, machine, date and versions;
``--report`` rewrites ``BENCHMARKS.md`` (one page) and ``docs/benchmarks-detail.md`` (every
table) from that file (:mod:`morphlab.bench.report`), alone without running anything.
"""

from __future__ import annotations

import argparse
import os
import shlex
import sys
import time
import traceback

from . import record
from .report import DESCRIPTIONS, render_detail, write


def case_exudyn(repeats: int, quick: bool) -> dict:
    """The ``exudyn`` case (:mod:`morphlab.bench.exudyn`), or why it was skipped."""
    try:
        import exudyn  # noqa: F401
    except ImportError:
        return {"skipped": "Exudyn is not installed (pip install -e '.[bench]'): not run."}
    from . import exudyn as comparison

    return comparison.run(repeats, quick)


def _case(name: str):
    """The function of case ``name`` (imported on use: a case may need optional packages)."""
    if name == "compile":
        from .compile import case_compile as fn
    elif name == "startup":
        from .startup import case_startup as fn
    elif name == "morphing":
        from .gradients import case_morphing as fn
    elif name == "pendulum":
        from .gradients import case_pendulum as fn
    elif name == "variables":
        from .variables import case_variables as fn
    elif name == "optimizers":
        from .optimizers import case_optimizers as fn
    elif name == "aero":
        from .aero import case_aero as fn
    elif name == "elements":
        from .elements import case_elements as fn
    elif name == "memory":
        from .memory import case_memory as fn
    elif name == "sweep":
        from .sweeps import run as fn
    elif name == "exudyn":
        fn = case_exudyn
    else:
        raise record.BenchError(f"unknown case {name!r}; choose from {', '.join(CASES)}")
    return fn


#: The cases, in the order they run and are reported.
CASES = tuple(DESCRIPTIONS)


def _parser() -> argparse.ArgumentParser:
    listing = "\n".join(f"  {k:<11} {v}" for k, v in DESCRIPTIONS.items())
    ap = argparse.ArgumentParser(
        prog="python -m morphlab.bench", formatter_class=argparse.RawDescriptionHelpFormatter,
        description="The benchmark suite: measures the cases, merges their figures into a "
                    "JSON record and writes BENCHMARKS.md from it.",
        epilog=f"cases:\n{listing}\n\nexamples:\n  python -m morphlab.bench --cases "
               "compile,startup --repeats 3 --quick --report\n  python -m morphlab.bench "
               "--report      (rewrite BENCHMARKS.md from the record, run nothing)")
    ap.add_argument("--cases", default=None,
                    help="comma-separated cases to run (default: all, unless --report alone)")
    ap.add_argument("--repeats", type=int, default=None,
                    help="timed runs per figure (default 5; --quick: 3)")
    ap.add_argument("--quick", action="store_true",
                    help="reduced sizes (recorded as such: not reference figures)")
    ap.add_argument("--report", action="store_true",
                    help="rewrite the Markdown page from the record (after running the cases "
                         "given, if any)")
    ap.add_argument("--out", default="benchmarks.json", help="the JSON record (merged)")
    ap.add_argument("--markdown", default="BENCHMARKS.md",
                    help="the page --report writes (and docs/benchmarks-detail.md beside it)")
    return ap


def _fail(message: str) -> int:
    print(f"morphlab.bench: error: {message}", file=sys.stderr)
    return 2


def _load() -> tuple | None:
    try:
        return os.getloadavg()
    except (AttributeError, OSError):  # not on this platform
        return None


def run_cases(chosen: list[str], repeats: int, quick: bool, out: str, command: str) -> dict:
    """Run ``chosen`` cases and merge each into the record ``out`` as it finishes (a later
    failure or an interrupt keeps the finished ones). Returns the new entries."""
    rec = record.load(out)
    context = record.run_context()
    done: dict = {}
    for c in chosen:
        fn = _case(c)
        print(f"[{c}: running]", file=sys.stderr, flush=True)
        load0, t0 = _load(), time.perf_counter()
        result, error = None, None
        try:
            result = fn(repeats, quick)
        except KeyboardInterrupt:
            error = "interrupted"
        except Exception as exc:  # keep the other cases' figures; the error is recorded
            where = traceback.extract_tb(exc.__traceback__)[-1]
            error = (f"{type(exc).__name__}: {exc} (at {os.path.basename(where.filename)}:"
                     f"{where.lineno} in {where.name})")[:2000]
        load1 = _load()
        done[c] = record.entry(result, command=command, repeats=repeats, quick=quick,
                               seconds=time.perf_counter() - t0, error=error,
                               load=(load0[0], load1[0]) if load0 and load1 else None,
                               context=context)
        rec = record.merge(rec, {c: done[c]})
        record.save(rec, out)
        print(f"[{c}: {'failed: ' + error if error else 'done'}, "
              f"{done[c]['seconds']:.0f} s]", file=sys.stderr, flush=True)
        if error == "interrupted":
            raise KeyboardInterrupt
    return done


def main(argv: list[str] | None = None) -> int:
    """Entry point; returns the exit status (2: bad input, 1: a case failed, 130: Ctrl-C)."""
    argv = list(sys.argv[1:] if argv is None else argv)
    args = _parser().parse_args(argv)
    repeats = args.repeats if args.repeats is not None else (3 if args.quick else 5)
    if repeats < 1:
        return _fail(f"--repeats must be at least 1, got {repeats}")
    if args.cases is None:
        chosen = [] if args.report else list(CASES)
    else:
        chosen = [c.strip() for c in args.cases.split(",") if c.strip()]
        unknown = [c for c in chosen if c not in CASES]
        if unknown or not chosen:
            return _fail(f"unknown cases {unknown or [args.cases]}; choose from "
                         f"{', '.join(CASES)}")
    done: dict = {}
    try:
        record.load(args.out)  # a record that cannot be merged is refused before any run
        command = shlex.join(["python", "-m", "morphlab.bench", *argv])
        try:
            done = run_cases(chosen, repeats, args.quick, args.out, command)
        except KeyboardInterrupt:
            print("morphlab.bench: interrupted; the finished cases are in the record",
                  file=sys.stderr)
            return 130
        if done:  # the sections of the cases just run, as the page will show them
            cases = record.load(args.out)["cases"]
            print(render_detail({"cases": {c: cases[c] for c in done}}))
        if args.report:
            n, detail = write(record.load(args.out), args.markdown)
            print(f"morphlab.bench: wrote {args.markdown} ({n} lines) and {detail} from "
                  f"{args.out}", file=sys.stderr)
    except record.BenchError as exc:
        return _fail(str(exc))
    return 1 if any("error" in e for e in done.values()) else 0
