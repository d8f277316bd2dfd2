"""Numba kernels of morphlab (installed as ``morphlab.kernels``).

Plain-array functions compiled with ``@njit(cache=True)``; each runs for float64 and complex128
inputs alike. Nothing here imports from ``morphlab``.

Numba's on-disk cache checks only the source file that defines a function, not the files of
the kernels it calls: after an edit of ``joints.py``, the cached ``assemble.fill_matrix`` would
keep running the old joint code. :func:`_drop_stale_cache` keeps
one stamp over all kernel sources and removes the cache next to them when it changes.
"""

import hashlib
import os


def _drop_stale_cache(here: str = os.path.dirname(os.path.abspath(__file__))) -> None:
    """Remove the Numba cache files in ``here/__pycache__`` unless the stamp there matches the
    ``*.py`` sources of ``here``; then write the current stamp."""
    digest = hashlib.sha256()
    for name in sorted(os.listdir(here)):
        if name.endswith(".py"):
            with open(os.path.join(here, name), "rb") as fh:
                digest.update(name.encode() + b"\0" + fh.read())
    stamp = digest.hexdigest()
    cache = os.path.join(here, "__pycache__")
    stamp_file = os.path.join(cache, "kernels-sources.sha256")
    try:
        with open(stamp_file, encoding="ascii") as fh:
            if fh.read().strip() == stamp:
                return
    except OSError:
        pass
    try:  # a read-only install has no cache here (Numba then uses its user-wide directory)
        os.makedirs(cache, exist_ok=True)
        for name in os.listdir(cache):
            if name.endswith((".nbi", ".nbc")):
                os.remove(os.path.join(cache, name))
        with open(stamp_file, "w", encoding="ascii") as fh:
            fh.write(stamp)
    except OSError:
        pass


_drop_stale_cache()
