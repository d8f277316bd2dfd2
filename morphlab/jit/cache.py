"""Where the compiled kernels are cached, and the notice of their first compilation.

Numba compiles the kernels on their first call in an environment and caches the machine code
on disk: in ``$NUMBA_CACHE_DIR`` when that is set, else next to the kernels' sources (their
``__pycache__``) when writable, else in the user's cache folder. Later processes load it in
about a second.
"""

from __future__ import annotations

from ..kernels.steps import run_steps


def kernel_cache_dir() -> str | None:
    """The folder Numba caches the kernels in (None if Numba does not say)."""
    try:
        return run_steps._cache._cache_path
    except AttributeError:  # pragma: no cover - another Numba layout
        return None
