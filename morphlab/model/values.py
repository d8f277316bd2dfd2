"""Validation of the numbers, points, names and profiles a model is built from: every check
refuses bad input with a :class:`~morphlab.errors.ModelError` naming the item and what would be
valid (finite numbers of the right shape, no strings, ``None``, booleans, NaN or Inf). Values
may be complex (a complex step through ``build(p)``); the checks look at the real parts."""

from __future__ import annotations

import cmath

import numpy as np

from ..errors import ModelError
from .profiles import as_profile


def _real(x):
    return np.real(np.asarray(x))


def _show(value, limit=60) -> str:
    """Short ``repr`` of a user value for error messages."""
    text = repr(value)
    return text if len(text) <= limit else text[: limit - 3] + "..."


def _upcast(value):
    """NumPy values of less than double precision as float64/complex128 (the same numbers):
    joint geometry and the compiled system are computed in double precision, and a float32
    angle would put its round-off (~1e-7) into the initial constraint violation."""
    if isinstance(value, (np.ndarray, np.generic)):
        kind, size = value.dtype.kind, value.dtype.itemsize
        if kind == "f" and size < 8:
            return value.astype(np.float64)
        if kind == "c" and size < 16:
            return value.astype(np.complex128)
    return value


def _has_bool(value) -> bool:
    """True for a bool, or a list/tuple holding one (NumPy would silently turn it into 0/1)."""
    if isinstance(value, (bool, np.bool_)):
        return True
    return isinstance(value, (list, tuple)) and any(_has_bool(v) for v in value)


_PLAIN = (int, float, complex, np.float64, np.complex128, np.int64)


def _plain_numbers(value, shape) -> bool | None:
    """For a Python number (``shape == ()``) or a tuple of them of length ``shape[0]``: are
    they all finite? None for anything else (bool is not a number here)."""
    if shape == ():
        items = (value,)
    elif len(shape) == 1 and type(value) is tuple and len(value) == shape[0]:
        items = value
    else:
        return None
    if not all(type(x) in _PLAIN for x in items):
        return None
    return all(cmath.isfinite(x) for x in items)


def _numeric(value, what, owner, shape=(), expect="a finite number"):
    """``value`` as a numeric (integer, real or complex) array of ``shape``, all entries finite.

    Rejects what NumPy would otherwise let through or fail on later with an unrelated message:
    strings, ``None``, booleans, objects, ragged sequences, wrong shapes, NaN and Inf (real or
    imaginary part). Complex values are allowed (complex-step differentiation).
    """
    fast = _plain_numbers(value, shape)
    if fast is not None:  # Python numbers (the common case, without NumPy's reductions)
        if fast:
            return np.asarray(value)
        raise ModelError(f"{owner}: {what} must be {expect} (no NaN or Inf), got {_show(value)}")
    try:
        arr = None if _has_bool(value) else np.asarray(value)
    except (TypeError, ValueError, OverflowError):  # ragged or unconvertible sequences
        arr = None
    if arr is None or arr.dtype.kind not in "iufc" or arr.shape != shape:
        raise ModelError(f"{owner}: {what} must be {expect}, got {_show(value)}")
    if not np.all(np.isfinite(arr)):
        raise ModelError(f"{owner}: {what} must be {expect} (no NaN or Inf), got {_show(value)}")
    return _upcast(arr)


def _finite_positive(value, what, owner):
    v = _real(_numeric(value, what, owner, expect="a finite positive number"))
    if not v > 0:
        raise ModelError(f"{owner}: {what} must be a finite positive number, got {_show(value)}")
    return _upcast(value)


def _section_positive(value, what, owner, n_elem):
    """A positive section/material value: a scalar, or one value per element (n_elem,)."""
    if np.ndim(value) == 1 and not isinstance(value, (str, bytes)):
        arr = _numeric(value, what, owner, shape=(n_elem,),
                       expect=f"a finite positive number or an array of {n_elem} of them "
                              "(one per element)")
        if not np.all(_real(arr) > 0):
            k = int(np.flatnonzero(~(_real(arr) > 0))[0])
            raise ModelError(f"{owner}: {what} of element {k} must be positive, got "
                             f"{_show(arr[k])}")
        return arr
    return _finite_positive(value, what, owner)


def _point(at, what, owner):
    return _numeric(at, what, owner, shape=(2,), expect="a finite pair (x, y) of numbers")


def _check_name(name, kind):
    """A user-given name must be a non-empty string."""
    if not isinstance(name, str) or not name:
        raise ModelError(f"{kind} names must be non-empty strings, got {_show(name)}")
    return name


def _profile(obj, owner):
    """``obj`` as a :class:`Profile` whose value at ``t = 0`` is a finite number."""
    if isinstance(obj, (bool, np.bool_)):
        raise ModelError(f"{owner}: profile must be a Profile, a number or a callable f(t), "
                         f"got {obj!r}")
    prof = as_profile(obj, owner)
    try:
        f0 = prof.value(0.0)
    except Exception as exc:  # a user callable: report which one failed, keep the cause
        raise ModelError(f"{owner}: evaluating the profile at t=0 failed: "
                         f"{type(exc).__name__}: {exc}") from exc
    _numeric(f0, "the profile value at t=0", owner)
    return prof
