"""Helpers shared by the plotting modules (units, axes, input checks, colour choices)."""

from __future__ import annotations

import numpy as np
from matplotlib.axes import Axes
from matplotlib.figure import Figure

from ..errors import ModelError

#: Axis-label units of the morphing model (mm, t, s, N, N mm, MPa).
DEFAULT_UNITS = {"length": "mm", "time": "s", "stress": "MPa", "force": "N", "torque": "N mm",
                 "energy": "N mm"}

_SEQUENTIAL = "viridis"
_DIVERGING = "RdBu_r"
_HATCHES = ("", "//", "..", "xx", "\\\\", "oo", "--", "++")
_MARKERS = ("o", "s", "^", "D", "v", "P", "X", "*")
_LINESTYLES = ("-", "--", "-.", ":")




def _units(units) -> dict:
    out = dict(DEFAULT_UNITS)
    if units is None:
        return out
    if not isinstance(units, dict):
        raise ModelError(f"units must be a dict such as {{'length': 'm'}}, got {units!r}")
    unknown = set(units) - set(DEFAULT_UNITS)
    if unknown:
        raise ModelError(f"unknown unit keys {sorted(unknown)}; known: {sorted(DEFAULT_UNITS)}")
    out.update(units)
    return out


def _new_axes(ax, figsize=(6.0, 4.5)):
    if ax is None:
        fig = Figure(figsize=figsize, layout="constrained")
        return fig, fig.add_subplot()
    if not isinstance(ax, Axes):
        raise ModelError(f"ax must be a matplotlib Axes or None, got {type(ax).__name__}")
    return ax.figure, ax


def _real_array(x, what) -> np.ndarray:
    try:
        arr = np.real(np.asarray(x)).astype(float)
    except (TypeError, ValueError) as exc:
        raise ModelError(f"{what} must be a numeric array, got {type(x).__name__}") from exc
    return arr


def _check_shape(arr, shape, what):
    """``shape`` may hold None for a free size."""
    ok = arr.ndim == len(shape) and all(s is None or s == n for s, n in zip(shape, arr.shape))
    if not ok:
        want = "(" + ", ".join("n" if s is None else str(s) for s in shape) + ")"
        raise ModelError(f"{what} must have shape {want}, got {arr.shape}")


def _points(x, what, n=None) -> np.ndarray:
    arr = _real_array(x, what)
    _check_shape(arr, (n, 2), what)
    if arr.shape[0] < 1:
        raise ModelError(f"{what} needs at least one point")
    if not np.all(np.isfinite(arr)):
        raise ModelError(f"{what} has non-finite coordinates")
    return arr


def _times(t, what="t") -> np.ndarray:
    t = _real_array(t, what)
    _check_shape(t, (None,), what)
    if t.shape[0] < 2:
        raise ModelError(f"{what} needs at least two times for a space-time map, got {t.shape[0]}")
    if not np.all(np.isfinite(t)) or np.any(np.diff(t) <= 0):
        raise ModelError(f"{what} must be finite and strictly increasing")
    return t


def _check_result(result):
    if not (hasattr(result, "system") and hasattr(result, "t") and hasattr(result, "q")):
        raise ModelError(f"expected a morphlab Result, got {type(result).__name__}")
    return result


def _edges(centres: np.ndarray) -> np.ndarray:
    """Cell edges halfway between centres, extrapolated by half a cell at both ends."""
    mid = 0.5 * (centres[1:] + centres[:-1])
    first = centres[0] - (mid[0] - centres[0]) if mid.size else centres[0] - 0.5
    last = centres[-1] + (centres[-1] - mid[-1]) if mid.size else centres[-1] + 0.5
    return np.concatenate([[first], mid, [last]])


def _signed_max(a: np.ndarray, axis) -> np.ndarray:
    """Signed value of the largest magnitude over ``axis`` (a tuple of trailing axes)."""
    flat = a.reshape(a.shape[: a.ndim - len(axis)] + (-1,))
    k = np.argmax(np.abs(flat), axis=-1)
    return np.take_along_axis(flat, k[..., None], axis=-1)[..., 0]


def arc_coordinate(nodes) -> np.ndarray:
    """Arc length from the first node to every node of a polyline.

    Parameters
    ----------
    nodes : array_like, shape (n_nodes, 2)
        Node positions [mm].

    Returns
    -------
    ndarray, shape (n_nodes,)
        Cumulative arc length [mm], 0 at the first node; usable as ``arc`` of
        :func:`stress_map` and :func:`sensitivity_map`.
    """
    X = _points(nodes, "nodes")
    return np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(X, axis=0).T))])
