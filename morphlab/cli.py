"""Command line: ``morphlab morphing --out DIR`` (the paper's study) and friends.

Bad input ends with exit status 2 and a one-line message (``--traceback`` shows the stack);
a solver failure ends with status 1.
"""

from __future__ import annotations

import argparse
import sys

from .errors import MorphlabError, SolverError


def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="morphlab", description=__doc__.splitlines()[0])
    p.add_argument("--traceback", action="store_true", help="show the Python traceback on errors")
    sub = p.add_subparsers(dest="command", required=True)
    m = sub.add_parser("morphing", help="run the morphing leading-edge study (paper §4)")
    m.add_argument("--out", default="morphing-out", help="output folder (figures, JSON)")
    m.add_argument("--quick", action="store_true",
                   help="coarser time step and fewer timing repeats (for smoke tests)")
    m.add_argument("--no-figures", action="store_true", help="skip the figures")
    m.add_argument("--no-timing", action="store_true",
                   help="skip the finite-difference timing runs (Table 2)")
    m.add_argument("--set", action="append", default=[], metavar="NAME=VALUE",
                   help="override a design variable, e.g. --set t_w=2.5 (repeatable)")
    m.add_argument("--progress", action="store_true", help="show a progress bar")
    w = sub.add_parser("warmup", help="compile all kernels (fills the Numba cache)")
    w.set_defaults()
    return p


def _overrides(items) -> dict:
    out = {}
    for item in items:
        name, sep, value = item.partition("=")
        if not sep or not name:
            raise MorphlabError(f"--set expects NAME=VALUE, got {item!r}")
        try:
            out[name.strip()] = float(value)
        except ValueError:
            raise MorphlabError(f"--set {name}: {value!r} is not a number") from None
    return out


def main(argv: list[str] | None = None) -> int:
    """Entry point of the ``morphlab`` command; returns the exit status."""
    args = _parser().parse_args(argv)
    try:
        if args.command == "warmup":
            from .warmup import warmup

            warmup()
            print("morphlab: kernels compiled")
            return 0
        from .morphing import leading_edge as morphing

        report = morphing.study(out=args.out, overrides=_overrides(args.set), quick=args.quick,
                                figures=not args.no_figures, timing=not args.no_timing,
                                progress=args.progress)
        print(report)
        return 0
    except SolverError as exc:
        if args.traceback:
            raise
        print(f"morphlab: solver failed: {str(exc).splitlines()[0]}", file=sys.stderr)
        return 1
    except (MorphlabError, OSError) as exc:
        if args.traceback:
            raise
        print(f"morphlab: error: {str(exc).splitlines()[0]}", file=sys.stderr)
        return 2


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
