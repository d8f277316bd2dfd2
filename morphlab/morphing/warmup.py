"""The main command's kernels compiled ahead of need: ``morphlab warmup``, and the compile
helper of the main command's first use.

``python -m morphlab.morphing.warmup GROUP ...`` compiles the named groups (the helper
process of :func:`helper`).

Which groups a kernel cache holds is recorded beside it (:func:`mark_compiled`,
:func:`compiled_groups`): a finished warm-up or main command marks the groups it ran, for
the kernels' sources, Numba and the processor of that moment. Numba's own index cannot tell
it: a kernel's index lists the signatures of every kind of model run before (the quickstart,
the tests), not whether the morphing model's are among them.
"""

from __future__ import annotations

import hashlib
import json
import os
import platform
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
    statics of the flight loads (:func:`morphlab.morphing.aeroelastic.warm_statics`), and
    mark them compiled (:func:`mark_compiled`). ``report`` and the returned wall seconds per
    group as for ``warmup_for``."""
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
    mark_compiled(list(seconds))
    return seconds


#: The file beside the kernel cache that records the groups it holds (:func:`mark_compiled`).
MARK = "morphlab-main-command.json"


def _stamp() -> str:
    """What decides whether cached kernels are still valid: morphlab's and Numba's versions,
    the processor Numba compiles for, and the name, size and modification time of every
    source file of the kernels (Numba compiles again when one of them changes)."""
    import numba

    from .. import __version__
    from ..kernels import __file__ as kernels_init
    from ..kernels.steps import run_steps

    try:
        target = str(run_steps.targetctx.codegen().magic_tuple())
    except AttributeError:  # pragma: no cover - another Numba layout
        target = platform.machine()
    digest = hashlib.sha256(f"{__version__} {numba.__version__} {target}".encode())
    folder = os.path.dirname(kernels_init)
    for name in sorted(os.listdir(folder)):
        if name.endswith(".py"):
            st = os.stat(os.path.join(folder, name))
            digest.update(f"{name} {st.st_size} {st.st_mtime_ns}".encode())
    return digest.hexdigest()


def _mark_path() -> str | None:
    from ..jit.cache import kernel_cache_dir

    folder = kernel_cache_dir()
    return None if folder is None else os.path.join(folder, MARK)


def compiled_groups() -> set:
    """The groups (:data:`GROUPS`) whose kernels the cache holds, as marked by a finished
    warm-up or main command with the current kernels (:func:`_stamp`); empty when there is no
    mark, it is unreadable or it was made for other kernels."""
    path = _mark_path()
    return set() if path is None else _held(path, _stamp())


def _held(path: str, stamp: str) -> set:
    """The groups the mark at ``path`` holds for kernels of ``stamp`` (:func:`compiled_groups`)."""
    try:
        with open(path, encoding="utf-8") as fh:
            data = json.load(fh)
    except (OSError, ValueError):
        return set()
    if not isinstance(data, dict) or data.get("stamp") != stamp:
        return set()
    return set(data.get("groups") or ()) & set(GROUPS)


def mark_compiled(groups) -> None:
    """Record that the cache holds the kernels of ``groups`` (added to those marked before,
    for the current kernels). The file is replaced whole, so a reader sees the old or the new
    mark; a mark that cannot be written is left out (it only spares a later first use its
    helper)."""
    _check(groups)
    path = _mark_path()
    if path is None:
        return
    stamp = _stamp()
    data = {"stamp": stamp, "groups": sorted(_held(path, stamp) | set(groups))}
    tmp = f"{path}.{os.getpid()}.tmp"
    try:
        with open(tmp, "w", encoding="utf-8") as fh:
            json.dump(data, fh)
        os.replace(tmp, path)
    except OSError:
        try:
            os.remove(tmp)
        except OSError:
            pass


def helper(groups) -> CompileHelper:
    """A second process compiling ``groups`` (:data:`GROUPS`) into the shared cache
    (:class:`morphlab.jit.helper.CompileHelper`)."""
    _check(groups)
    return CompileHelper(__name__, groups)


if __name__ == "__main__":
    warmup(sys.argv[1:], report=lambda text: print(text, flush=True))
