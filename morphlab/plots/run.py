"""Figures of a run: snapshots of its motion and its energy balance."""

from __future__ import annotations

import numpy as np
from matplotlib import colormaps
from matplotlib.cm import ScalarMappable
from matplotlib.colors import ListedColormap, Normalize
from matplotlib.figure import Figure
from matplotlib.patches import Polygon

from ..model import Ground
from ._common import _LINESTYLES, _SEQUENTIAL, _check_result, _new_axes, _units
from ._sliders import _block
from .motion import (
    _checked_outlines,
    _mark_ground_joints,
    _slider_tracks,
    _spring_tracks,
    _time_indices,
)


def _snapshot_cmap():
    # viridis reversed and cut before its lightest yellow: early = light, late = dark
    return ListedColormap(colormaps[_SEQUENTIAL](np.linspace(0.85, 0.0, 256)))


def snapshots(result, times=None, n=6, ax=None, target=None, *, units=None,
              magnify: float = 1.0) -> Figure:
    """Configurations of a run at a few times (figure 5b of the paper).

    Parameters
    ----------
    result : Result
        A run.
    times : array_like, shape (k,), optional
        Times to draw [s]; each is drawn at the nearest step. Default ``n`` evenly spaced steps
        from the first to the last.
    n : int
        Number of snapshots when ``times`` is not given.
    ax : matplotlib Axes, optional
    target : array_like, shape (n_nodes, 2), optional
        Target node positions of a beam, drawn dashed [length].
    units : dict, optional
        Overrides of :data:`DEFAULT_UNITS`.
    magnify : float
        Scale of the beams' deformation relative to their chord motion (the rigid motion of
        the line through a beam's end nodes; 1: true scale, 0: that rigid motion only); the
        title says when it is not 1.

    Returns
    -------
    Figure

    Notes
    -----
    Beams are drawn through their nodes (``result.node_positions``), rigid bodies as lines
    between the points where their joints and loads attach (``result.point_positions``; a
    closed polygon for three or more points, centre of mass to point for one). One line per
    body and snapshot, ``gid="snapshot:<i>:<body>"``. Colour runs from light (early) to dark
    (late) along reversed viridis; a colorbar gives the time. Ground joints are black
    triangles; a prismatic joint is its guide line (grey) and a slider block per snapshot, a
    spring-damper a zigzag between its points per snapshot.
    """
    u = _units(units)
    _check_result(result)
    idx = _time_indices(result, times, n)
    magnify, outlines, tgt = _checked_outlines(result, magnify, target)
    fig, ax = _new_axes(ax)
    t = np.real(result.t)
    cmap = _snapshot_cmap()
    t0, t1 = t[idx[0]], t[idx[-1]]
    norm = Normalize(t0, t1 if t1 > t0 else t0 + 1.0)
    for i, k in enumerate(idx):
        colour = cmap(norm(t[k]))
        for name, xy, closed, _ in outlines:
            P = xy[k]
            if closed:
                P = np.vstack([P, P[:1]])
            ax.plot(P[:, 0], P[:, 1], "-", color=colour, linewidth=1.4,
                    marker="o" if P.shape[0] == 1 else None, markersize=4,
                    gid=f"snapshot:{i}:{name}")
    sym, sliders = _slider_tracks(result)
    for j, P, d, ends in sliders:
        for i, k in enumerate(idx):
            if i == 0 or not isinstance(j.a, Ground):
                ax.plot(ends[k, :, 0], ends[k, :, 1], "-", color="0.5", linewidth=1.0,
                        gid=f"guide:{j.name}")
            ax.add_patch(Polygon(_block(P[k], d[k], sym), closed=True, fill=False,
                                 edgecolor=cmap(norm(t[k])), linewidth=1.2,
                                 gid=f"snapshot:{i}:{j.name}"))
    for sp, Z in _spring_tracks(result, outlines):
        for i, k in enumerate(idx):
            ax.plot(Z[k, :, 0], Z[k, :, 1], "-", color=cmap(norm(t[k])), linewidth=0.8,
                    gid=f"snapshot:{i}:{sp.name}")
    grounded = _mark_ground_joints(ax, result.system.model, gid="ground", label="ground joints")
    if magnify != 1.0:
        ax.set_title(f"beam deformation magnified {magnify:g}x")
    if tgt is not None:
        ax.plot(tgt[:, 0], tgt[:, 1], "--", color="k", linewidth=1.2, gid="target",
                label="target")
    if grounded or tgt is not None:
        ax.legend(loc="best", fontsize=8)
    fig.colorbar(ScalarMappable(norm=norm, cmap=cmap), ax=ax, label=f"time t [{u['time']}]")
    ax.set_aspect("equal", adjustable="datalim")
    ax.set_xlabel(f"x [{u['length']}]")
    ax.set_ylabel(f"y [{u['length']}]")
    return fig


def energy(result, ax=None, *, relative=True, units=None) -> Figure:
    """Energy balance of a run over time.

    Parameters
    ----------
    result : Result
    ax : matplotlib Axes, optional
    relative : bool
        Draw the gravitational potential and ``total - work`` relative to their initial values
        (potentials are defined up to a constant; otherwise a large gravity term hides the
        others).
    units : dict, optional
        Overrides of :data:`DEFAULT_UNITS` (``energy``, ``time``).

    Returns
    -------
    Figure

    Notes
    -----
    Lines: kinetic, strain, gravity, work of the applied loads, work of the drives (when a
    model has any) and ``total - work`` with ``total = kinetic + strain + gravity`` and
    ``work`` that of loads and drives (from :attr:`Result.energy`). With damping, the
    dissipated energy and ``total - work + dissipated`` are added; that last line is constant
    for an exact solution, so its drift measures the integration error.
    """
    u = _units(units)
    _check_result(result)
    e = {k: np.real(np.asarray(v, dtype=complex)) for k, v in result.energy.items()}
    t = np.real(result.t)
    fig, ax = _new_axes(ax)
    grav = e["gravity"] - e["gravity"][0] if relative else e["gravity"]
    bal = e["total"] - e["work"]
    if relative:
        bal = bal - bal[0]
    rel = " (from t0)" if relative else ""
    curves = [("kinetic", e["kinetic"]), ("strain", e["strain"]), ("gravity" + rel, grav),
              ("work of loads", e["load_work"])]
    if np.any(e["drive_work"] != 0):
        curves.append(("work of drives", e["drive_work"]))
    curves.append(("total − work" + rel, bal))
    if np.any(e["damping"] != 0):
        curves += [("dissipated (damping)", e["damping"]),
                   ("total − work + dissipated" + rel, bal + e["damping"])]
    colours = colormaps[_SEQUENTIAL](np.linspace(0.0, 0.85, len(curves)))
    for i, (label, y) in enumerate(curves):
        ax.plot(t, y, linestyle=_LINESTYLES[i % len(_LINESTYLES)], color=colours[i],
                linewidth=2.0 if label.startswith("total") else 1.3, label=label)
    ax.set_xlabel(f"time t [{u['time']}]")
    ax.set_ylabel(f"energy [{u['energy']}]")
    ax.legend(loc="best", fontsize=8)
    ax.set_title("energy balance")
    return fig
