"""Where the compiled kernels are cached, and the notice of their first compilation.

Numba compiles the kernels on their first call in an environment and caches the machine code
on disk: in ``$NUMBA_CACHE_DIR`` when that is set, else next to the kernels' sources (their
``__pycache__``) when writable, else in the user's cache folder. Later processes load it in
about a second.
"""

from __future__ import annotations

import os

from ..kernels.steps import run_steps


def kernel_cache_dir() -> str | None:
    """The folder Numba caches the kernels in (None if Numba does not say)."""
    try:
        return run_steps._cache._cache_path
    except AttributeError:  # pragma: no cover - another Numba layout
        return None


def kernels_cached(*kernels) -> bool:
    """Has each of ``kernels`` (default: the time loop, the last kernel a run compiles) been
    compiled in this process or cached for some kind of model already?"""
    for k in kernels or (run_steps,):
        try:
            path = k._cache._cache_file._index_path
        except AttributeError:  # pragma: no cover - another Numba layout: assume cached
            continue
        if not (k.signatures or os.path.exists(path)):
            return False
    return True
