"""Charts of arrays from studies: space-time stress and sensitivity maps, profiles with
per-node errors, node sensitivities, timing bars and growth curves."""

from __future__ import annotations

import numpy as np
from matplotlib import colormaps
from matplotlib.axes import Axes
from matplotlib.figure import Figure
from matplotlib.ticker import MaxNLocator

from ..errors import ModelError
from ._common import (
    _DIVERGING,
    _HATCHES,
    _LINESTYLES,
    _MARKERS,
    _SEQUENTIAL,
    _check_shape,
    _edges,
    _new_axes,
    _points,
    _real_array,
    _signed_max,
    _times,
    _units,
)


def _space_time_map(fig, ax, t, values, arc, *, signed, label, u):
    """Draw ``values`` (n_t, n_elem) over element (x) and time (y) with a colorbar."""
    n_t, n_elem = values.shape
    if arc is None:
        xc = np.arange(n_elem, dtype=float)
        xe = _edges(xc)
        ax.set_xlabel("element index [-]")
    else:
        arc = _real_array(arc, "arc")
        if arc.ndim != 1 or arc.shape[0] not in (n_elem, n_elem + 1):
            raise ModelError(
                f"arc must hold the arc length of the {n_elem + 1} nodes (cell edges) or of the "
                f"{n_elem} element centres, got shape {arc.shape}"
            )
        if not np.all(np.isfinite(arc)) or np.any(np.diff(arc) <= 0):
            raise ModelError("arc must be finite and strictly increasing")
        if arc.shape[0] == n_elem + 1:
            xe, xc = arc, 0.5 * (arc[1:] + arc[:-1])
        else:
            xc, xe = arc, _edges(arc)
        ax.set_xlabel(f"arc length s [{u['length']}]")
    te = _edges(t)
    if signed:
        vmax = float(np.max(np.abs(values))) or 1.0
        mesh = ax.pcolormesh(xe, te, values, cmap=_DIVERGING, vmin=-vmax, vmax=vmax,
                             shading="flat")
        if n_t >= 2 and n_elem >= 2 and np.ptp(values) > 0:
            levels = MaxNLocator(nbins=8, symmetric=True).tick_values(-vmax, vmax)
            levels = levels[(levels > -vmax) & (levels < vmax)]
            if levels.size:
                styles = ["dashed" if lv < 0 else "solid" for lv in levels]
                widths = [1.2 if lv == 0 else 0.6 for lv in levels]
                ax.contour(xc, t, values, levels=levels, colors="k", linestyles=styles,
                           linewidths=widths)
    else:
        mesh = ax.pcolormesh(xe, te, values, cmap=_SEQUENTIAL, shading="flat")
    ax.set_ylabel(f"time t [{u['time']}]")
    fig.colorbar(mesh, ax=ax, label=label)
    return mesh


def stress_map(t, stress, ax=None, arc=None, fibre="max", *, units=None) -> Figure:
    """Space-time map of the normal stress of a beam (figure 6 of the paper).

    Parameters
    ----------
    t : array_like, shape (n_t,)
        Times [s], strictly increasing.
    stress : array_like, shape (n_t, n_elem, 2, 2)
        Stress at both ends and both outer fibres of every element, as from
        :meth:`Result.stress <morphlab.results.result.Result.stress>` [MPa].
    ax : matplotlib Axes, optional
    arc : array_like, shape (n_elem + 1,) or (n_elem,), optional
        Arc length of the nodes (cell edges) or of the element centres [mm], e.g.
        :func:`arc_coordinate` of the beam nodes; default the element index.
    fibre : {'max', 'abs', 0, 1}
        How each element and time is reduced to one value: ``'max'`` the signed value of the
        largest magnitude over both ends and both fibres; ``'abs'`` that magnitude; ``0`` or
        ``1`` one fibre (left/right of the element direction), signed value of the larger
        magnitude of its two ends.
    units : dict, optional
        Overrides of :data:`DEFAULT_UNITS`.

    Returns
    -------
    Figure

    Notes
    -----
    Signed maps use ``RdBu_r`` symmetric about zero with black contours (dashed negative, solid
    positive, thick zero) so the sign survives grey printing; ``'abs'`` uses ``viridis``.
    """
    u = _units(units)
    t = _times(t)
    s = _real_array(stress, "stress")
    _check_shape(s, (t.shape[0], None, 2, 2), "stress (n_t, n_elem, 2 ends, 2 fibres)")
    if s.shape[1] < 1:
        raise ModelError("stress has no elements")
    if isinstance(fibre, str) and fibre == "max":
        v, what = _signed_max(s, (2, 3)), "largest |σ| of ends and fibres, signed"
    elif isinstance(fibre, str) and fibre == "abs":
        v, what = np.max(np.abs(s), axis=(2, 3)), "largest |σ| of ends and fibres"
    elif not isinstance(fibre, (str, bool)) and fibre in (0, 1):
        v, what = _signed_max(s[:, :, :, int(fibre)], (2,)), f"fibre {int(fibre)}, signed"
    else:
        raise ModelError(f"fibre must be 'max', 'abs', 0 or 1, got {fibre!r}")
    fig, ax = _new_axes(ax)
    _space_time_map(fig, ax, t, v, arc, signed=fibre != "abs",
                    label=f"stress σ [{u['stress']}] ({what})", u=u)
    ax.set_title("beam stress")
    return fig


def sensitivity_map(t, dvalue, name, ax=None, arc=None, *, quantity="σ", quantity_unit=None,
                    variable_unit=None, units=None) -> Figure:
    """Space-time map of a design sensitivity per element (figure 8 of the paper).

    Parameters
    ----------
    t : array_like, shape (n_t,)
        Times [s], strictly increasing.
    dvalue : array_like, shape (n_t, n_elem)
        Derivative of an element quantity with respect to the design variable ``name``.
    name : str
        Design variable, e.g. ``"t_w"``.
    ax : matplotlib Axes, optional
    arc : array_like, shape (n_elem + 1,) or (n_elem,), optional
        As in :func:`stress_map`.
    quantity : str
        Symbol of the differentiated quantity (colorbar label).
    quantity_unit : str, optional
        Its unit; default the stress unit.
    variable_unit : str, optional
        Unit of the design variable; default "unit of <name>".
    units : dict, optional
        Overrides of :data:`DEFAULT_UNITS`.

    Returns
    -------
    Figure

    Notes
    -----
    Diverging ``RdBu_r`` with limits symmetric about 0 and black contours (dashed negative).
    """
    u = _units(units)
    if not isinstance(name, str) or not name:
        raise ModelError(f"name must be the design variable's name, got {name!r}")
    t = _times(t)
    d = _real_array(dvalue, "dvalue")
    _check_shape(d, (t.shape[0], None), "dvalue (n_t, n_elem)")
    if d.shape[1] < 1:
        raise ModelError("dvalue has no elements")
    qu = quantity_unit or u["stress"]
    vu = variable_unit or f"unit of {name}"
    fig, ax = _new_axes(ax)
    _space_time_map(fig, ax, t, d, arc, signed=True,
                    label=f"d{quantity}/d{name} [{qu} / {vu}]", u=u)
    ax.set_title(f"sensitivity with respect to {name}")
    return fig


# --------------------------------------------------------------------------- shape error
def profile_comparison(undeformed, target, simulated, ax=None, *, units=None) -> Figure:
    """Undeformed, target and simulated profiles, and the error per node (figure 7a/7b).

    Parameters
    ----------
    undeformed, target, simulated : array_like, shape (n_nodes, 2)
        Node positions [mm]; node k of each set corresponds.
    ax : sequence of two matplotlib Axes, optional
        Axes for the profiles and the error bars; default a new 2-panel figure.
    units : dict, optional
        Overrides of :data:`DEFAULT_UNITS`.

    Returns
    -------
    Figure

    Notes
    -----
    Error per node, eq. (41): ``e_k = |x_s^k - x_t^k|`` (Euclidean); root-mean-square error,
    eq. (42): ``e_rms = sqrt(mean(e_k^2))``. Both and the largest error are annotated, and the
    node of the largest error is marked on the profile.
    """
    u = _units(units)
    X0 = _points(undeformed, "undeformed")
    n = X0.shape[0]
    Xt = _points(target, "target", n)
    Xs = _points(simulated, "simulated", n)
    if ax is None:
        fig = Figure(figsize=(10.0, 4.2), layout="constrained")
        ax1, ax2 = fig.subplots(1, 2, gridspec_kw={"width_ratios": [1.2, 1.0]})
    else:
        try:
            ax1, ax2 = ax
        except (TypeError, ValueError):
            raise ModelError("ax must be a pair of Axes (profiles, errors) or None") from None
        if not (isinstance(ax1, Axes) and isinstance(ax2, Axes)):
            raise ModelError("ax must be a pair of Axes (profiles, errors) or None")
        fig = ax1.figure
    e = np.hypot(*(Xs - Xt).T)
    rms = float(np.sqrt(np.mean(e**2)))
    k = int(np.argmax(e))
    L = u["length"]

    ax1.plot(X0[:, 0], X0[:, 1], ":", color="0.5", linewidth=1.5, label="undeformed")
    ax1.plot(Xt[:, 0], Xt[:, 1], "--", color="k", linewidth=1.5, label="target")
    ax1.plot(Xs[:, 0], Xs[:, 1], "-", color=colormaps[_SEQUENTIAL](0.35), linewidth=1.5,
             marker="o", markersize=3, label="simulated")
    ax1.plot([Xs[k, 0]], [Xs[k, 1]], "o", markersize=10, markerfacecolor="none",
             markeredgecolor="k", label=f"largest error (node {k})")
    ax1.set_aspect("equal", adjustable="datalim")
    ax1.set_xlabel(f"x [{L}]")
    ax1.set_ylabel(f"y [{L}]")
    ax1.legend(loc="best", fontsize=8)
    ax1.set_title("profiles")

    bars = ax2.bar(np.arange(n), e, width=0.8, color=colormaps[_SEQUENTIAL](0.35),
                   edgecolor="k", linewidth=0.5, label="e_k")
    bars[k].set_hatch("//")
    ax2.axhline(rms, color="k", linestyle="--", linewidth=1.0, label=f"RMS {rms:.4g} {L}")
    ax2.text(0.02, 0.97, f"max e = {e[k]:.4g} {L} (node {k}, hatched)\nRMS e = {rms:.4g} {L}",
             transform=ax2.transAxes, va="top", fontsize=8, gid="error-summary")
    ax2.set_xlabel("node k [-]")
    ax2.set_ylabel(f"error e_k [{L}]")
    ax2.set_ylim(0.0, 1.3 * max(float(e.max()), 1e-300))
    ax2.legend(loc="upper right", fontsize=8)
    ax2.set_title("error per node")
    return fig


def node_sensitivities(dvalues, ax=None, *, kind="bars", normalize=False, quantity="e_k",
                       quantity_unit=None, variable_units=None, units=None) -> Figure:
    """Sensitivities of a nodal quantity for several design variables (figure 9 of the paper).

    Parameters
    ----------
    dvalues : dict of str -> array_like, shape (n_nodes,)
        Derivative of the nodal quantity with respect to each design variable.
    ax : matplotlib Axes, optional
    kind : {'bars', 'lines'}
        Grouped bars (one hatched colour per variable) or one line with markers per variable.
    normalize : bool
        Divide every series by its largest magnitude (derivatives with respect to variables of
        different units then share one axis).
    quantity : str
        Symbol of the nodal quantity (axis label).
    quantity_unit : str, optional
        Its unit; default the length unit.
    variable_units : dict of str -> str, optional
        Unit of each design variable, shown in the legend.
    units : dict, optional
        Overrides of :data:`DEFAULT_UNITS`.

    Returns
    -------
    Figure
    """
    u = _units(units)
    if not isinstance(dvalues, dict) or not dvalues:
        raise ModelError("dvalues must be a non-empty dict {design variable: (n_nodes,) array}")
    arrs = {}
    n = None
    for name, val in dvalues.items():
        a = _real_array(val, f"dvalues[{name!r}]")
        _check_shape(a, (n,), f"dvalues[{name!r}] (n_nodes,)")
        n = a.shape[0]
        arrs[name] = a
    if kind not in ("bars", "lines"):
        raise ModelError(f"kind must be 'bars' or 'lines', got {kind!r}")
    vunits = variable_units or {}
    qu = quantity_unit or u["length"]
    fig, ax = _new_axes(ax, figsize=(8.0, 4.5))
    nodes = np.arange(n)
    nv = len(arrs)
    colours = colormaps[_SEQUENTIAL](np.linspace(0.0, 0.85, nv))
    width = 0.8 / nv
    for i, (name, a) in enumerate(arrs.items()):
        if normalize:
            a = a / (np.max(np.abs(a)) or 1.0)
        label = name + (f" [{qu}/{vunits[name]}]" if name in vunits and not normalize else "")
        if kind == "bars":
            ax.bar(nodes - 0.4 + (i + 0.5) * width, a, width=width, color=colours[i],
                   hatch=_HATCHES[i % len(_HATCHES)], edgecolor="k", linewidth=0.4, label=label)
        else:
            ax.plot(nodes, a, marker=_MARKERS[i % len(_MARKERS)],
                    linestyle=_LINESTYLES[i % len(_LINESTYLES)], color=colours[i], label=label)
    ax.axhline(0.0, color="k", linewidth=0.6)
    ax.set_xlabel("node k [-]")
    if normalize:
        ax.set_ylabel(f"d{quantity}/dp / max|d{quantity}/dp| [-]")
    else:
        ax.set_ylabel(f"d{quantity}/dp [{qu} / unit of p]")
    ax.legend(loc="best", fontsize=8, title="design variable p")
    return fig


# --------------------------------------------------------------------------- timings
def timing_bars(timings, ax=None, reference=None, *, units=None) -> Figure:
    """Wall time per method as bars, with the ratio to a reference method annotated.

    Parameters
    ----------
    timings : dict of str -> float
        Wall time of each method [s], e.g. ``{"primal": 148, "semi-analytical": 212}``.
    ax : matplotlib Axes, optional
    reference : str, optional
        Method the ratios refer to; default ``"primal"`` when present (otherwise no ratios).
    units : dict, optional
        Overrides of :data:`DEFAULT_UNITS` (``time``).

    Returns
    -------
    Figure
    """
    u = _units(units)
    if not isinstance(timings, dict) or not timings:
        raise ModelError("timings must be a non-empty dict {method: wall time}")
    names = list(timings)
    vals = np.array([float(np.real(timings[k])) for k in names])
    if not np.all(np.isfinite(vals)) or np.any(vals < 0):
        raise ModelError(f"wall times must be finite and >= 0, got {dict(zip(names, vals))}")
    if reference is None and "primal" in timings:
        reference = "primal"
    if reference is not None:
        if reference not in timings:
            raise ModelError(f"reference {reference!r} is not among the methods {names}")
        ref = float(timings[reference])
        if not ref > 0:
            raise ModelError(f"reference time of {reference!r} must be > 0, got {ref}")
    fig, ax = _new_axes(ax)
    x = np.arange(len(names))
    colours = colormaps["cividis"](np.linspace(0.15, 0.85, len(names)))
    bars = ax.bar(x, vals, color=colours, edgecolor="k", linewidth=0.6)
    for i, b in enumerate(bars):
        b.set_hatch(_HATCHES[i % len(_HATCHES)])
        if reference is not None:
            ax.annotate(f"{vals[i] / ref:.2f}×", xy=(b.get_x() + b.get_width() / 2, vals[i]),
                        xytext=(0, 3), textcoords="offset points", ha="center", va="bottom",
                        fontsize=9, gid=f"ratio:{names[i]}")
    ax.set_xticks(x, names)
    ax.set_xlabel("method")
    ax.set_ylabel(f"wall time [{u['time']}]")
    ax.set_ylim(0.0, 1.15 * max(float(vals.max()), 1e-300))
    if reference is not None:
        ax.set_title(f"wall time (ratios to {reference})")
    return fig


def timing_curves(x, series, xlabel, ax=None, loglog=True, *, ylabel=None,
                  units=None) -> Figure:
    """Growth of wall time (or any cost) with a problem size.

    Parameters
    ----------
    x : array_like, shape (n,)
        Problem sizes (number of elements, of steps, of design variables, ...).
    series : dict of str -> array_like, shape (n,)
        Cost of each method at every size [s].
    xlabel : str
        Label of the x axis, with its unit (e.g. ``"number of elements [-]"``).
    ax : matplotlib Axes, optional
    loglog : bool
        Logarithmic axes; the slope of a least-squares line through (log x, log y) of each
        series, i.e. the observed growth exponent, is added to its legend entry.
    ylabel : str, optional
        Default ``"wall time [s]"``.
    units : dict, optional
        Overrides of :data:`DEFAULT_UNITS` (``time``).

    Returns
    -------
    Figure
    """
    u = _units(units)
    if not isinstance(xlabel, str) or not xlabel:
        raise ModelError("xlabel must be a non-empty string (with its unit)")
    x = _real_array(x, "x")
    _check_shape(x, (None,), "x")
    if not isinstance(series, dict) or not series:
        raise ModelError("series must be a non-empty dict {method: (n,) array}")
    data = {}
    for name, val in series.items():
        y = _real_array(val, f"series[{name!r}]")
        _check_shape(y, x.shape, f"series[{name!r}] (same length as x)")
        data[name] = y
    if loglog:
        allv = np.concatenate([x] + list(data.values()))
        if not np.all(allv > 0):
            raise ModelError("log-log axes need x and all series > 0; pass loglog=False")
    fig, ax = _new_axes(ax)
    colours = colormaps[_SEQUENTIAL](np.linspace(0.0, 0.85, len(data)))
    for i, (name, y) in enumerate(data.items()):
        label = name
        if loglog and x.shape[0] >= 2 and np.ptp(x) > 0:
            slope = np.polyfit(np.log(x), np.log(y), 1)[0]
            label = f"{name} (slope {slope:.2f})"
        ax.plot(x, y, marker=_MARKERS[i % len(_MARKERS)],
                linestyle=_LINESTYLES[i % len(_LINESTYLES)], color=colours[i], label=label)
    if loglog:
        ax.set_xscale("log")
        ax.set_yscale("log")
    ax.set_xlabel(xlabel)
    ax.set_ylabel(ylabel or f"wall time [{u['time']}]")
    ax.legend(loc="best", fontsize=8)
    return fig
