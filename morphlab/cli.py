"""Command line: ``morphlab morphing --out DIR`` (the paper's study) and friends.

Every failure ends with one line on stderr (``--traceback`` shows the stack) and an exit
status: 2 for bad input (an ``--out`` folder that cannot be written, an invalid ``--set``),
found before any computing; 1 for a failure while computing; 130 for an interrupt (Ctrl-C).
The results are written into a temporary folder ``.<name>.partial-*`` next to ``--out`` and
moved into place at the end, so an interrupted or failed run leaves no output that looks
complete (the temporary folder is removed).
"""

from __future__ import annotations

import argparse
import os
import shutil
import sys
import tempfile

from .errors import MorphlabError, SolverError


class UsageError(MorphlabError):
    """Bad command-line input (exit status 2)."""


#: The command's description in its help (plain text: the help is no reST).
DESCRIPTION = ("morphlab: planar flexible multibody dynamics with design sensitivities. "
               "'morphlab morphing --out DIR' runs the paper's morphing leading-edge study "
               "and its flight loads and aerodynamics; "
               "'morphlab warmup' compiles the numerical kernels ahead of time.")


class _HelpFormatter(argparse.ArgumentDefaultsHelpFormatter):
    """Every option's default in its help, except the "False" of on/off flags and a None
    (no default: the help says what happens)."""

    def _get_help_string(self, action):
        if action.default is None or (action.nargs == 0 and action.default is False):
            return action.help
        return super()._get_help_string(action)


def _parser() -> argparse.ArgumentParser:
    fmt = _HelpFormatter
    p = argparse.ArgumentParser(prog="morphlab", description=DESCRIPTION, formatter_class=fmt)
    p.add_argument("--traceback", action="store_true", help="show the Python traceback on errors")
    sub = p.add_subparsers(dest="command", required=True)
    m = sub.add_parser("morphing", help="run the morphing leading-edge study (paper §4)",
                       description="Run the morphing leading-edge study of the paper (§4): "
                       "tables, figures and morphing.json in the output folder; then the "
                       "skin in flight (high speed and thermalling): aeroelastic equilibria, "
                       "CL, CD, transition, deflection, flight_loads.json.",
                       formatter_class=fmt)
    m.add_argument("--out", default="morphing-out", help="output folder (figures, JSON)")
    m.add_argument("--quick", action="store_true",
                   help="coarser time step and fewer timing repeats (for smoke tests)")
    m.add_argument("--no-figures", action="store_true", help="skip the figures")
    m.add_argument("--no-timing", action="store_true",
                   help="skip the finite-difference timing runs (Table 2)")
    m.add_argument("--set", action="append", default=None, metavar="NAME=VALUE",
                   help="override a design variable, e.g. --set t_w=2.5 (repeatable; default: "
                   "the study's design)")
    m.add_argument("--progress", action="store_true", help="show a progress bar")
    m.add_argument("--no-aero", action="store_true",
                   help="skip the flight loads and aerodynamics (flight_loads.json, figures "
                   "10-11: CL, CD, transition, the skin's deflection under the air load)")
    w = sub.add_parser("warmup", help="compile the kernels the morphing study needs",
                       description="Compile the numerical kernels the morphing study "
                       "(morphlab morphing) needs: its time loop, its sensitivity methods and "
                       "its flight loads' statics, over a few steps, in two processes (fills "
                       "the Numba cache next to the kernels, or NUMBA_CACHE_DIR; later runs "
                       "load them).", formatter_class=fmt)
    w.set_defaults()
    return p


def _overrides(items) -> dict:
    out = {}
    for item in items:
        name, sep, value = item.partition("=")
        if not sep or not name:
            raise UsageError(f"--set expects NAME=VALUE, got {item!r}")
        try:
            out[name.strip()] = float(value)
        except ValueError:
            raise UsageError(f"--set {name}: {value!r} is not a number") from None
    return out


def _check_design(overrides: dict) -> None:
    """Build the model at the overridden design once (milliseconds): a wrong name or value is
    bad input, reported before the study computes."""
    from .morphing import leading_edge as morphing

    unknown = sorted(set(overrides) - set(morphing.DEFAULTS))
    if unknown:
        raise UsageError(f"--set: unknown design variable {unknown[0]!r}; known: "
                         f"{sorted(morphing.DEFAULTS)}")
    try:
        morphing.build({**morphing.DEFAULTS, **overrides})
    except MorphlabError as exc:
        raise UsageError(f"--set: {str(exc).splitlines()[0]}") from exc


def _staging(out: str) -> str:
    """A new temporary folder next to ``out`` (which must be a writable folder, or a name
    that can become one): proves ``out`` can be written before anything is computed."""
    if not out or not out.strip():
        raise UsageError("--out must name a folder, got an empty string")
    target = os.path.abspath(out)
    if os.path.exists(target) and not os.path.isdir(target):
        raise UsageError(f"--out {out!r} exists and is not a folder")
    parent = os.path.dirname(target)
    try:
        os.makedirs(parent, exist_ok=True)
        return tempfile.mkdtemp(prefix=f".{os.path.basename(target)}.partial-", dir=parent)
    except OSError as exc:
        raise UsageError(f"--out {out!r} cannot be written: {exc.strerror or exc}") from exc


def _publish(staging: str, out: str) -> None:
    """Move the finished results from ``staging`` into ``out`` (the folder itself when it does
    not exist yet, else file by file, replacing files of the same name)."""
    target = os.path.abspath(out)
    if not os.path.exists(target):
        os.replace(staging, target)
        return
    for name in sorted(os.listdir(staging)):
        dst = os.path.join(target, name)
        if os.path.isdir(dst) and not os.path.islink(dst):
            shutil.rmtree(dst)
        os.replace(os.path.join(staging, name), dst)
    os.rmdir(staging)


def _morphing(args, interrupts: _Interrupts) -> str:
    from .morphing import warmup

    overrides = _overrides(args.set or [])
    staging = _staging(args.out)
    try:
        _check_design(overrides)
        with _compile_helper(args):
            report = _study(args, overrides, staging, interrupts)
        if not overrides:  # the defaults' kernels are cached: a later first use needs no helper
            warmup.mark_compiled(_groups(args))
        _publish(staging, args.out)
    finally:
        shutil.rmtree(staging, ignore_errors=True)
    return report


def _groups(args) -> list:
    """The kernel groups (``morphlab.morphing.warmup.GROUPS``) the command runs."""
    return (["time loop", "direct"] + ([] if args.no_timing else ["direct-fd", "adjoint"])
            + ([] if args.no_aero else ["statics"]))


def _compile_helper(args):
    """On a first use (the cache not marked as holding them), a second process compiles the
    kernels the command needs last (the adjoint of the timing, the flight loads' statics)
    while this one compiles and runs the study (``morphlab.morphing.warmup``); else
    nothing."""
    import contextlib

    from .morphing import warmup

    held = warmup.compiled_groups()
    groups = [g for g in ("statics", "adjoint") if g in _groups(args) and g not in held]
    return warmup.helper(groups) if groups else contextlib.nullcontext()


def _study(args, overrides: dict, staging: str, interrupts: _Interrupts) -> str:
    from .morphing import leading_edge as morphing

    report = str(morphing.study(out=staging, overrides=overrides, quick=args.quick,
                                figures=not args.no_figures, timing=not args.no_timing,
                                progress=args.progress))
    interrupts.check()
    if not args.no_aero:
        report += "\n\n" + _aero(overrides, staging, not args.no_figures)
        interrupts.check()
    return report


def _aero(overrides: dict, staging: str, figures: bool) -> str:
    """The flight loads of the study's design (morphlab.morphing.flight_loads) into the
    staging folder; their text is appended to report.txt."""
    from .morphing import leading_edge as morphing
    from .morphing.flight_loads import flight_loads

    loads = flight_loads({**morphing.DEFAULTS, **overrides}, out=staging, figures=figures)
    with open(os.path.join(staging, "report.txt"), "a", encoding="utf-8") as f:
        f.write("\n" + loads.report + "\n")
    return loads.report


class _Interrupts:
    """Ctrl-C that Python drops, recorded: an interrupt landing in a weakref or import-lock
    callback is reported as "Exception ignored in ..." and lost, and the study would go on
    and publish its output. While the command runs, such a report of a KeyboardInterrupt is
    recorded instead of printed, and :meth:`check` raises it before anything is published.
    (The SIGINT handler itself stays Python's, which the time loop relies on to stop between
    steps.)"""

    def __init__(self):
        self.seen = 0
        self._hook = None

    def _unraisable(self, report) -> None:
        if isinstance(report.exc_value, KeyboardInterrupt):
            self.seen += 1
        else:
            self._hook(report)

    def __enter__(self):
        self._hook, sys.unraisablehook = sys.unraisablehook, self._unraisable
        return self

    def __exit__(self, *exc):
        sys.unraisablehook = self._hook

    def check(self) -> None:
        """Raise KeyboardInterrupt if an interrupt was dropped."""
        if self.seen:
            raise KeyboardInterrupt


def _quiet(report) -> None:
    """An unraisable-exception hook that drops the report (after an interrupt)."""


def _interrupted(exc: BaseException) -> bool:
    """A KeyboardInterrupt, or an error raised while one was under way (a compiled loop
    surfaces Ctrl-C as its own exception with the interrupt as cause or context)."""
    seen = set()
    while exc is not None and id(exc) not in seen:
        if isinstance(exc, KeyboardInterrupt):
            return True
        seen.add(id(exc))
        exc = exc.__cause__ or exc.__context__
    return False


def main(argv: list[str] | None = None) -> int:
    """Entry point of the ``morphlab`` command; returns the exit status."""
    args = _parser().parse_args(argv)
    try:
        with _Interrupts() as interrupts:
            if args.command == "warmup":
                from .morphing.warmup import helper, warmup

                with helper(["statics", "adjoint"]):  # on the second core
                    seconds = warmup(["time loop", "direct", "direct-fd"])
                interrupts.check()
                print("morphlab: kernels ready (" + ", ".join(
                    f"{k} {v:.1f} s" for k, v in seconds.items()) + ")")
                return 0
            print(_morphing(args, interrupts))
            return 0
    except BaseException as exc:
        if isinstance(exc, SystemExit) or (args.traceback and not _interrupted(exc)):
            raise
        return _report(exc, args.traceback)


def _report(exc: BaseException, traceback: bool) -> int:
    """One line on stderr and the exit status for ``exc`` (re-raised when not ours)."""
    if _interrupted(exc):
        if traceback:
            raise exc
        print("morphlab: interrupted", file=sys.stderr)
        # the process ends here: objects an interrupt left half built (a compilation's LLVM
        # handles) fail in their finalizers at exit, which Python reports as "Exception
        # ignored in ..."; that is no news after this line
        sys.unraisablehook = _quiet
        return 130
    first = (str(exc).splitlines() or [type(exc).__name__])[0]
    if isinstance(exc, UsageError):
        print(f"morphlab: error: {first}", file=sys.stderr)
        return 2
    if isinstance(exc, SolverError):
        print(f"morphlab: solver failed: {first}", file=sys.stderr)
        return 1
    if isinstance(exc, (MorphlabError, OSError)):
        print(f"morphlab: error: {first}", file=sys.stderr)
        return 1
    raise exc


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
