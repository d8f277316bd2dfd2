"""The main command's kernels compiled ahead of need: ``morphlab warmup``, and the compile
helper of the main command's first use.

``python -m morphlab.morphing.warmup GROUP ...`` compiles the named groups (the helper
process of :func:`helper`).
"""

from __future__ import annotations

import sys
import time

from ..jit.helper import CompileHelper

#: The kernel groups of the main command (``morphlab morphing``), in the order it needs them:
#: the morphing model's time loop and sensitivity methods, and its flight loads' statics.
GROUPS = ("time loop", "direct", "direct-fd", "adjoint", "statics")


def _check(groups) -> None:
    unknown = [g for g in groups if g not in GROUPS]
    if unknown:
        raise ValueError(f"unknown kernel groups {unknown}; known: {list(GROUPS)}")


def warmup(groups=GROUPS, report=None) -> dict:
    """Compile the kernels of the main command's ``groups`` (:data:`GROUPS`): the time loop
    and the sensitivity methods over a few steps (:func:`morphlab.warmup.warmup_for`), the
    statics of the flight loads (:func:`morphlab.morphing.aeroelastic.warm_statics`).
    ``report`` and the returned wall seconds per group as for ``warmup_for``."""
    from ..warmup import warmup_for
    from . import leading_edge as le
    from .aeroelastic import warm_statics

    _check(groups)
    say = report or (lambda t: print(t, file=sys.stderr, flush=True))
    methods = tuple(g for g in groups if g not in ("time loop", "statics"))
    seconds = {}
    if methods or "time loop" in groups:
        seconds.update(warmup_for(le.build, le.DEFAULTS, le.RESPONSES, le.SETTINGS,
                                  methods=methods, report=say))
    if "statics" in groups:
        say("morphlab warmup: statics")
        t0 = time.perf_counter()
        warm_statics(lambda: le.build(dict(le.DEFAULTS)))
        seconds["statics"] = time.perf_counter() - t0
    return seconds


def helper(groups) -> CompileHelper:
    """A second process compiling ``groups`` (:data:`GROUPS`) into the shared cache
    (:class:`morphlab.jit.helper.CompileHelper`)."""
    _check(groups)
    return CompileHelper(__name__, groups)


if __name__ == "__main__":
    warmup(sys.argv[1:], report=lambda text: print(text, flush=True))
