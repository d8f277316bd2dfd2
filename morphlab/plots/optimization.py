"""Charts of a design optimization (:func:`morphlab.studies.optimize`): the objective and the
constraint violation per iteration, and the path of the design variables."""

from __future__ import annotations

import numpy as np
from matplotlib import colormaps
from matplotlib.axes import Axes
from matplotlib.figure import Figure
from matplotlib.ticker import MaxNLocator

from ..errors import ModelError
from ._common import (
    _LINESTYLES,
    _MARKERS,
    _SEQUENTIAL,
    _new_axes,
)


def _iterations(result):
    """Iteration records of an :class:`~morphlab.studies.OptimizationResult` (duck-typed: the
    plots stage comes before the studies)."""
    hist = getattr(result, "history", None)
    if hist is None or not hasattr(hist, "iterations") or not hasattr(result, "info"):
        raise ModelError(f"expected an OptimizationResult, got {type(result).__name__}")
    if not hist.iterations:
        raise ModelError("the optimization history has no iterations to draw")
    return hist


def optimization_history(result, ax=None) -> Figure:
    """Objective, largest constraint violation and runs per iteration of an optimization.

    Parameters
    ----------
    result : OptimizationResult
        From :func:`morphlab.studies.optimize`.
    ax : sequence of two matplotlib Axes, optional
        Axes for the objective (its twin carries the violation) and for the runs; default a
        new two-panel figure.

    Returns
    -------
    Figure

    Notes
    -----
    Objective: solid line with circles (left axis); violation: dashed line with squares on a
    symmetric-log right axis (linear up to the feasibility tolerance, drawn dotted); runs so
    far: a black step line with triangles in the lower panel. Iteration 0 is the start.
    """
    hist = _iterations(result)
    k = hist.column("iterations", "iteration")
    obj = hist.column("iterations", "objective")
    viol = hist.column("iterations", "max_violation")
    runs = hist.column("iterations", "runs")
    if ax is None:
        fig = Figure(figsize=(7.0, 5.5), layout="constrained")
        ax1, ax2 = fig.subplots(2, 1, sharex=True, gridspec_kw={"height_ratios": [2.0, 1.0]})
    else:
        try:
            ax1, ax2 = ax
        except (TypeError, ValueError):
            raise ModelError("ax must be a pair of Axes (objective, runs) or None") from None
        if not (isinstance(ax1, Axes) and isinstance(ax2, Axes)):
            raise ModelError("ax must be a pair of Axes (objective, runs) or None")
        fig = ax1.figure
    colour = colormaps[_SEQUENTIAL](0.3)
    name = result.info.get("objective", "objective")
    ax1.plot(k, obj, "-", marker=_MARKERS[0], color=colour, label=f"objective ({name})")
    ax1.set_ylabel(f"objective {name}")
    tw = ax1.twinx()
    tol = float(result.info.get("feasibility_tol", 1e-6)) or 1e-12
    tw.plot(k, viol, "--", marker=_MARKERS[1], color="k", markerfacecolor="none",
            label="max constraint violation")
    tw.axhline(tol, color="0.4", linestyle=":", linewidth=1.0, label="feasibility tolerance")
    tw.set_yscale("symlog", linthresh=tol)
    tw.set_ylim(bottom=0.0)
    tw.set_ylabel("max constraint violation [-]")
    lines = ax1.get_lines() + tw.get_lines()
    ax1.legend(lines, [ln.get_label() for ln in lines], loc="upper right", fontsize=8)
    ax1.set_title(f"{result.optimizer}: {result.status}, {result.n_runs} runs")
    ax2.step(k, runs, where="post", color="k", marker=_MARKERS[2], markersize=4)
    ax2.set_xlabel("iteration [-]")
    ax2.set_ylabel("runs so far [-]")
    ax2.xaxis.set_major_locator(MaxNLocator(integer=True))
    return fig


def design_path(result, variables=None, ax=None) -> Figure:
    """Design variables per iteration, normalised to their bounds.

    Parameters
    ----------
    result : OptimizationResult
        From :func:`morphlab.studies.optimize`.
    variables : list of str, optional
        Variables to draw (default: all).
    ax : matplotlib Axes, optional

    Returns
    -------
    Figure

    Notes
    -----
    A variable with finite bounds is drawn as ``(p - low) / (high - low)`` (0 and 1 are the
    bounds, dotted); one with an open bound as ``p / |p_start|``. Lines differ in marker and
    line style as well as colour.
    """
    hist = _iterations(result)
    names = list(hist.variables) if variables is None else list(variables)
    unknown = [v for v in names if v not in hist.variables]
    if unknown or not names:
        raise ModelError(f"variables {unknown or '[]'} are not design variables of the "
                         f"result (known: {hist.variables})")
    k = hist.column("iterations", "iteration")
    design = hist.column("iterations", "design")
    bounds = result.info.get("bounds") or [(None, None)] * len(hist.variables)
    fig, ax = _new_axes(ax, figsize=(7.0, 4.5))
    colours = colormaps[_SEQUENTIAL](np.linspace(0.0, 0.85, len(names)))
    scaled_by_start = False
    for i, v in enumerate(names):
        j = hist.variables.index(v)
        lo, hi = bounds[j]
        p = design[:, j]
        if lo is not None and hi is not None and np.isfinite(lo) and np.isfinite(hi):
            y, label = (p - lo) / (hi - lo), v
        else:
            y, label = p / (abs(p[0]) or 1.0), f"{v} / |{v} start|"
            scaled_by_start = True
        ax.plot(k, y, marker=_MARKERS[i % len(_MARKERS)],
                linestyle=_LINESTYLES[i % len(_LINESTYLES)], color=colours[i], label=label)
    for b in (0.0, 1.0):
        ax.axhline(b, color="0.4", linestyle=":", linewidth=1.0)
    ax.set_xlabel("iteration [-]")
    ax.set_ylabel("(p - low) / (high - low) [-]" + (" or p / |p start|" if scaled_by_start
                                                    else ""))
    ax.xaxis.set_major_locator(MaxNLocator(integer=True))
    ax.legend(loc="best", fontsize=8, title="design variable")
    return fig
