"""A morphlab file: the ``metadata`` member (JSON) with the format's name and version, written
and read through the container; and the plain-arrays kind (``"morphlab-arrays"``)."""

from __future__ import annotations

import json
import os

import numpy as np

from .._version import __version__
from ..errors import FormatError
from .container import read_members, write_members

FORMAT_VERSION = 2
#: The first format version of this layout of the compiled system (one table per kind of
#: item); result files of version 1 hold the earlier layout and are refused.
SYSTEM_FORMAT = 2
RESULT_FORMAT = "morphlab-result"
SENSITIVITY_FORMAT = "morphlab-sensitivity"
ARRAYS_FORMAT = "morphlab-arrays"
METADATA = "metadata"


def morphlab_version() -> str:
    """The version of morphlab writing a file."""
    return __version__


def _check_key(key) -> str:
    if not isinstance(key, str) or not key:
        raise FormatError(f"array names must be non-empty strings, got {key!r}")
    if key == METADATA or key.startswith("/") or "\\" in key or ".." in key.split("/"):
        raise FormatError(
            f"array name {key!r} is not allowed ({METADATA!r} is reserved; no leading '/', "
            "backslashes or '..' parts)"
        )
    return key


def write_file(path, metadata: dict, arrays: dict) -> None:
    """Write ``metadata`` (JSON) and ``arrays`` as an ``.npz`` archive, atomically
    (:func:`~morphlab.io.container.write_members`)."""
    metadata = {**metadata, "members": sorted(arrays)}
    try:
        text = json.dumps(metadata, allow_nan=True)
    except (TypeError, ValueError) as exc:
        raise FormatError(f"metadata cannot be written as JSON: {exc}") from exc
    write_members(path, [(METADATA, np.array(text))] + list(arrays.items()))


def read_file(path, arrays_too=True) -> tuple[dict, dict]:
    """``(metadata, arrays)`` of a morphlab file (all members read into memory, or none)."""
    name = os.fspath(path)
    arrays = read_members(name, None if arrays_too else [METADATA])
    if METADATA not in arrays:
        raise FormatError(f"{name!r} is not a morphlab file (no {METADATA!r} member)")
    try:
        meta = json.loads(str(arrays.pop(METADATA)[()]))
    except (ValueError, TypeError, RecursionError) as exc:
        raise FormatError(f"{os.fspath(path)!r}: the metadata is not valid JSON: {exc}") from exc
    kinds = (RESULT_FORMAT, ARRAYS_FORMAT, SENSITIVITY_FORMAT)
    if not isinstance(meta, dict) or meta.get("format") not in kinds:
        raise FormatError(f"{os.fspath(path)!r} is not a morphlab file (format "
                          f"{meta.get('format') if isinstance(meta, dict) else None!r})")
    members = meta.get("members")
    if arrays_too and members is not None and sorted(arrays) != members:
        lost = sorted(set(members) - set(arrays)) or sorted(set(arrays) - set(members))
        raise FormatError(f"{os.fspath(path)!r} is incomplete or damaged: its directory does "
                          f"not list the members of its metadata (e.g. {lost[:3]})")
    version = meta.get("format_version")
    if not isinstance(version, int) or version > FORMAT_VERSION:
        raise FormatError(
            f"{os.fspath(path)!r} has format version {version!r}; this morphlab "
            f"({morphlab_version()}) reads versions up to {FORMAT_VERSION}: update morphlab"
        )
    return meta, arrays


def read_metadata(path) -> dict:
    """The JSON metadata of a morphlab file (either kind), as a dict."""
    return read_file(path, arrays_too=False)[0]


# ---------------------------------------------------------------------------------------------
# plain arrays
def save_arrays(path, arrays: dict, meta: dict | None = None) -> None:
    """Save a dict of arrays and a dict of metadata to ``path`` (``.npz``, atomic write).

    Parameters
    ----------
    path : str or os.PathLike
        Destination, used as given (no extension is added; ``.npz`` is customary).
    arrays : dict of str -> array_like
        Numeric, boolean or string arrays of any shape and dtype (no object arrays). Names
        may contain ``/`` to group them; ``"metadata"`` is reserved.
    meta : dict, optional
        JSON-serializable metadata (design variables, settings, units, ...).

    Raises
    ------
    FormatError
        Invalid names, object arrays, metadata that is not JSON; nothing is written then.
    """
    if not isinstance(arrays, dict):
        raise FormatError(f"arrays must be a dict of name -> array, got {type(arrays).__name__}")
    meta = {} if meta is None else meta
    if not isinstance(meta, dict):
        raise FormatError(f"meta must be a dict, got {type(meta).__name__}")
    keys = [_check_key(k) for k in arrays]
    header = {"format": ARRAYS_FORMAT, "format_version": FORMAT_VERSION,
              "morphlab_version": morphlab_version(), "arrays": keys, "meta": meta}
    write_file(path, header, arrays)


def load_arrays(path) -> tuple[dict, dict]:
    """Load a file written by :func:`save_arrays`: ``(arrays, meta)``.

    On a result file (written by :func:`save`) it returns all of its members and its whole
    metadata, for inspection.
    """
    meta, arrays = read_file(path)
    if meta["format"] == ARRAYS_FORMAT:
        return arrays, meta.get("meta", {})
    return arrays, meta
