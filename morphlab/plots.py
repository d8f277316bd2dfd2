"""Figures of models, motions, stresses, shape errors, sensitivities, timings and energy.

Every function returns a :class:`matplotlib.figure.Figure` and never calls ``plt.show``. Without
an ``ax`` argument the figure is a bare :class:`~matplotlib.figure.Figure` (not registered with
pyplot, so there is nothing to close); with ``ax`` the drawing goes into that axes and its
figure is returned. Inputs may be complex (complex-step runs): their real parts are drawn.

Units
-----
The library is unit-agnostic; axis labels use the morphing model's units by default
(:data:`DEFAULT_UNITS`: mm, s, MPa, N, N mm). Pass ``units={"length": "m", ...}`` to change
any of them.

Colour maps
-----------
Figures must stay readable when printed in grey:

* sequential data (times of the snapshots, stress magnitudes) use ``viridis``/``cividis``, whose
  lightness changes monotonically;
* signed data (stress, sensitivities) use the diverging ``RdBu_r`` with limits symmetric about
  zero, so white is zero. Red and blue of equal magnitude have about the same grey value, so
  the sign is also drawn with black contour lines: solid for positive levels, dashed for
  negative levels and a thicker solid line at zero;
* bars and lines of several series differ in hatching, marker and line style as well as in
  colour.
"""

from __future__ import annotations

import itertools
from pathlib import Path

import numpy as np
from matplotlib import colormaps
from matplotlib.axes import Axes
from matplotlib.cm import ScalarMappable
from matplotlib.colors import ListedColormap, Normalize
from matplotlib.figure import Figure
from matplotlib.patches import FancyArrowPatch, Polygon, Rectangle
from matplotlib.ticker import MaxNLocator

from .compile import System
from .errors import ModelError
from .model import Beam, Drive, Fix, Ground, Model, Revolute, RigidBody, Weld

__all__ = [
    "DEFAULT_UNITS", "animate", "arc_coordinate", "energy", "model", "node_sensitivities",
    "profile_comparison", "sensitivity_map", "snapshots", "stress_map", "timing_bars",
    "timing_curves",
]

#: Axis-label units of the morphing model (mm, t, s, N, N mm, MPa).
DEFAULT_UNITS = {"length": "mm", "time": "s", "stress": "MPa", "force": "N", "torque": "N mm",
                 "energy": "N mm"}

_SEQUENTIAL = "viridis"
_DIVERGING = "RdBu_r"
_HATCHES = ("", "//", "..", "xx", "\\\\", "oo", "--", "++")
_MARKERS = ("o", "s", "^", "D", "v", "P", "X", "*")
_LINESTYLES = ("-", "--", "-.", ":")


# --------------------------------------------------------------------------- helpers
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


def _attachment_points(m: Model) -> dict:
    """Global initial points where joints and loads attach, per body name (deduplicated)."""
    pts: dict[str, list] = {}
    tol = 1e-9 * max(_model_size(m, with_points=False), 1.0)

    def add(body, at):
        if at is None or isinstance(body, Ground):
            return
        p = np.real(np.asarray(at, dtype=complex)).astype(float)
        lst = pts.setdefault(body.name, [])
        if not any(np.hypot(*(p - q)) <= tol for q in lst):
            lst.append(p)

    for j in m.joints:
        if isinstance(j, (Revolute, Weld)):
            add(j.a, j.at)
            add(j.b, j.at)
        elif isinstance(j, (Fix, Drive)):
            add(j.body, j.at)
    for ld in list(m.forces) + list(m.torques):
        add(ld.body, ld.at)
    return pts


def _model_size(m: Model, with_points=True) -> float:
    xy = []
    for b in m.bodies:
        xy.append(np.real(b.nodes) if isinstance(b, Beam) else np.real(b.position)[None])
    if with_points:
        for j in m.joints:
            if getattr(j, "at", None) is not None:
                xy.append(np.real(np.asarray(j.at))[None])
    if not xy:
        return 1.0
    xy = np.concatenate(xy).astype(float)
    return float(np.ptp(xy, axis=0).max()) or 1.0


def _ground_points(m: Model) -> list:
    """(point, clamp) of every joint to the ground: pins draw a triangle, clamps a block."""
    out = []
    for j in m.joints:
        if isinstance(j, (Revolute, Weld)) and (isinstance(j.a, Ground) or isinstance(j.b, Ground)):
            out.append((np.real(j.at).astype(float), isinstance(j, Weld), j))
        elif isinstance(j, Fix):
            out.append((np.real(j.at).astype(float), "r" in j.dofs, j))
    return out


def _ground_symbol(ax, p, size, clamp):
    """Hatched ground below ``p``: a pin triangle on it, or a clamp block directly."""
    x, y = p
    artists = []
    if not clamp:
        tri = Polygon([[x, y], [x - 0.5 * size, y - 0.8 * size], [x + 0.5 * size, y - 0.8 * size]],
                      closed=True, facecolor="white", edgecolor="k", linewidth=1.0, zorder=3)
        ax.add_patch(tri)
        artists.append(tri)
        y = y - 0.8 * size
    hatch = Rectangle((x - 0.8 * size, y - 0.35 * size), 1.6 * size, 0.35 * size, fill=False,
                      hatch="////", edgecolor="k", linewidth=0.0, zorder=2)
    ax.add_patch(hatch)
    (line,) = ax.plot([x - 0.8 * size, x + 0.8 * size], [y, y], color="k", linewidth=1.2,
                      zorder=3)
    artists += [hatch, line]
    for a in artists:
        a.set_gid("ground")
    return artists


def _curved_arrow(ax, centre, radius, positive, **kw):
    """A curved arrow around ``centre``: counter-clockwise if ``positive``."""
    c = np.asarray(centre, dtype=float)
    a = c + radius * np.array([np.cos(-np.pi / 4), np.sin(-np.pi / 4)])
    b = c + radius * np.array([np.cos(3 * np.pi / 4), np.sin(3 * np.pi / 4)])
    # arc3 puts the Bezier control point at +rad x (dy, -dx) from the chord midpoint
    if not positive:
        a, b = b, a
    arrow = FancyArrowPatch(a, b, connectionstyle=f"arc3,rad={0.9 if positive else -0.9}",
                            arrowstyle="-|>", mutation_scale=12, **kw)
    ax.add_patch(arrow)
    return arrow


# --------------------------------------------------------------------------- model
def model(model_or_system, ax=None, show_nodes=True, labels=True, *, units=None) -> Figure:
    """Draw a model in its initial configuration, before running it.

    Parameters
    ----------
    model_or_system : Model, System or Result
        The mechanism; a compiled :class:`~morphlab.compile.System` or a
        :class:`~morphlab.results.Result` is drawn through its ``model``.
    ax : matplotlib Axes, optional
        Axes to draw into; default a new figure.
    show_nodes : bool
        Dots at the beam nodes.
    labels : bool
        Names of bodies, joints and loads next to them.
    units : dict, optional
        Overrides of :data:`DEFAULT_UNITS` (``length``, ``force``, ``torque``).

    Returns
    -------
    Figure

    Notes
    -----
    Beams are polylines through their nodes (n_nodes, 2) [length]. A rigid body is a square at
    its centre of mass with lines to the points where its joints and loads attach (taken from
    ``model.joints``, ``model.forces`` and ``model.torques``). Joints: open circle = revolute,
    filled square = weld, joints to the ground and :class:`~morphlab.model.Fix` constraints
    stand on a hatched ground symbol (a triangle for a pin, a block when the rotation is held),
    a drive is a dashed curved arrow. Forces are arrows of fixed length (a fraction of the model
    size) pointing at their point, torques solid curved arrows (counter-clockwise when positive).
    Drawn artists carry a ``gid`` (``"beam:<name>"``, ``"body:<name>"``, ``"joint:<name>"``,
    ``"ground"``, ``"force:<name>"``, ``"torque:<name>"``) so that they can be found again.
    """
    u = _units(units)
    m = model_or_system
    if isinstance(getattr(m, "system", None), System):
        m = m.system
    if isinstance(m, System):
        m = m.model
    if not isinstance(m, Model):
        raise ModelError(
            f"expected a Model, System or Result, got {type(model_or_system).__name__}"
        )
    fig, ax = _new_axes(ax)
    size = _model_size(m)
    sym = 0.04 * size
    off = 0.015 * size
    pts = _attachment_points(m)
    text_kw = dict(fontsize=8, zorder=6)

    for b in m.bodies:
        if isinstance(b, Beam):
            X = np.real(b.nodes).astype(float)
            (ln,) = ax.plot(X[:, 0], X[:, 1], "-", color="0.25", linewidth=2.0, zorder=2,
                            marker="o" if show_nodes else None, markersize=3,
                            markerfacecolor="k", gid=f"beam:{b.name}")
            if labels:
                k = X.shape[0] // 2
                ax.text(X[k, 0] + off, X[k, 1] + off, b.name, color="0.25", style="italic",
                        gid=f"label:{b.name}", **text_kw)
        elif isinstance(b, RigidBody):
            c = np.real(b.position).astype(float)
            for p in pts.get(b.name, []):
                ax.plot([c[0], p[0]], [c[1], p[1]], "-", color="0.45", linewidth=3.0,
                        solid_capstyle="round", zorder=1, gid=f"body:{b.name}")
            ax.plot([c[0]], [c[1]], "s", color="k", markersize=6, zorder=4,
                    gid=f"body:{b.name}:com")
            if labels:
                ax.text(c[0] + off, c[1] - 2 * off, b.name, color="0.25", style="italic",
                        gid=f"label:{b.name}", **text_kw)

    for p, clamp, _j in _ground_points(m):
        _ground_symbol(ax, p, sym, clamp)

    for j in m.joints:
        if isinstance(j, Drive):
            at = j.at if j.at is not None else j.body.position
            p = np.real(np.asarray(at)).astype(float)
            _curved_arrow(ax, p, 1.6 * sym, True, color="0.3", linestyle="--",
                          gid=f"joint:{j.name}", zorder=5)
            label = f"{j.name} (drive)"
        else:
            p = np.real(np.asarray(j.at)).astype(float)
            if isinstance(j, Revolute):
                ax.plot([p[0]], [p[1]], "o", markersize=7, markerfacecolor="white",
                        markeredgecolor="k", zorder=5, gid=f"joint:{j.name}")
            elif isinstance(j, Weld):
                ax.plot([p[0]], [p[1]], "s", markersize=6, color="k", zorder=5,
                        gid=f"joint:{j.name}")
            else:
                ax.plot([p[0]], [p[1]], "o", markersize=4, color="k", zorder=5,
                        gid=f"joint:{j.name}")
            label = f"{j.name} ({j.dofs})" if isinstance(j, Fix) else j.name
        if labels:
            ax.text(p[0] - off, p[1] + off, label, ha="right", fontweight="bold",
                    gid=f"label:{j.name}", **text_kw)

    for f in m.forces:
        p = np.real(np.asarray(f.at)).astype(float)
        F = np.real(np.asarray(f.force)).astype(float)
        mag = float(np.hypot(*F))
        d = F / mag if mag > 0 else np.array([0.0, -1.0])
        tail = p - 0.12 * size * d
        ax.annotate("", xy=p, xytext=tail, gid=f"force:{f.name}", zorder=6,
                    arrowprops=dict(arrowstyle="-|>", color="k", linewidth=1.5,
                                    mutation_scale=12))
        if labels:
            ax.text(tail[0], tail[1], f"{f.name} ({mag:.3g} {u['force']})", ha="center",
                    va="bottom" if d[1] <= 0 else "top", gid=f"label:{f.name}", **text_kw)
    for tq in m.torques:
        at = tq.at if tq.at is not None else tq.body.position
        p = np.real(np.asarray(at)).astype(float)
        mag = float(np.real(tq.magnitude))
        _curved_arrow(ax, p, 2.2 * sym, mag >= 0, color="k", linewidth=1.5,
                      gid=f"torque:{tq.name}", zorder=6)
        if labels:
            ax.text(p[0] + 2.4 * sym, p[1] + 1.6 * sym, f"{tq.name} ({mag:.3g} {u['torque']})",
                    gid=f"label:{tq.name}", **text_kw)

    ax.set_aspect("equal", adjustable="datalim")
    ax.autoscale_view()
    ax.set_xlabel(f"x [{u['length']}]")
    ax.set_ylabel(f"y [{u['length']}]")
    ax.set_title(m.name)
    return fig


# --------------------------------------------------------------------------- motion
def _outlines(result):
    """Per body: (name, xy (n_t, k, 2), closed, is_beam) drawn as a polyline at each time."""
    m = result.system.model
    pts = _attachment_points(m)
    out = []
    for b in m.bodies:
        if isinstance(b, Beam):
            out.append((b.name, np.real(result.node_positions(b.name)), False, True))
            continue
        p = pts.get(b.name, [])
        if len(p) == 0:
            xy = np.real(result.reference(b.name)[0])[:, None, :]
        elif len(p) == 1:
            xy = np.stack([np.real(result.reference(b.name)[0]),
                           np.real(result.point_positions(b.name, p[0]))], axis=1)
        else:
            xy = np.stack([np.real(result.point_positions(b.name, q)) for q in p], axis=1)
        out.append((b.name, xy, len(p) > 2, False))
    return out


def _time_indices(result, times, n):
    t = np.real(result.t)
    if times is None:
        if not isinstance(n, (int, np.integer)) or n < 1:
            raise ModelError(f"n must be a positive integer, got {n!r}")
        return np.unique(np.round(np.linspace(0, t.shape[0] - 1, min(n, t.shape[0]))).astype(int))
    times = _real_array(times, "times").ravel()
    if times.size == 0:
        raise ModelError("times must hold at least one time")
    slack = 1e-9 * max(abs(t[-1] - t[0]), 1e-300)
    bad = times[(times < t[0] - slack) | (times > t[-1] + slack)]
    if bad.size:
        raise ModelError(f"times {bad.tolist()} lie outside the run [{t[0]:.6g}, {t[-1]:.6g}] s")
    return np.unique(np.argmin(np.abs(t[None, :] - times[:, None]), axis=1))


def _snapshot_cmap():
    # viridis reversed and cut before its lightest yellow: early = light, late = dark
    return ListedColormap(colormaps[_SEQUENTIAL](np.linspace(0.85, 0.0, 256)))


def _check_target(target, outlines):
    if target is None:
        return None
    tgt = _points(target, "target")
    counts = [xy.shape[1] for _, xy, _, is_beam in outlines if is_beam]
    if counts and tgt.shape[0] not in counts:
        raise ModelError(f"target has {tgt.shape[0]} points but the beams have {counts} nodes; "
                         "give the target nodes of one beam, shape (n_nodes, 2)")
    return tgt


def snapshots(result, times=None, n=6, ax=None, target=None, *, units=None) -> Figure:
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
    triangles.
    """
    u = _units(units)
    _check_result(result)
    idx = _time_indices(result, times, n)
    outlines = _outlines(result)
    tgt = _check_target(target, outlines)
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
    g = [p for p, _, _ in _ground_points(result.system.model)]
    if g:
        g = np.array(g)
        ax.plot(g[:, 0], g[:, 1], "^", color="k", markersize=7, linestyle="none", gid="ground",
                label="ground joints")
    if tgt is not None:
        ax.plot(tgt[:, 0], tgt[:, 1], "--", color="k", linewidth=1.2, gid="target",
                label="target")
    if len(g) or tgt is not None:
        ax.legend(loc="best", fontsize=8)
    fig.colorbar(ScalarMappable(norm=norm, cmap=cmap), ax=ax, label=f"time t [{u['time']}]")
    ax.set_aspect("equal", adjustable="datalim")
    ax.set_xlabel(f"x [{u['length']}]")
    ax.set_ylabel(f"y [{u['length']}]")
    return fig


def animate(result, path, fps=20, n_frames=60, target=None, *, dpi=80, units=None) -> Path:
    """Write the motion of a run as an animated GIF.

    Parameters
    ----------
    result : Result
    path : str or Path
        Output file; must end in ``.gif``.
    fps : float
        Frames per second of the GIF.
    n_frames : int
        Number of frames, taken at evenly spaced steps (at most one per step).
    target : array_like, shape (n_nodes, 2), optional
        Target node positions drawn dashed in every frame [length].
    dpi : float
        Resolution of the frames (the figure is 5 x 4 inches).
    units : dict, optional
        Overrides of :data:`DEFAULT_UNITS`.

    Returns
    -------
    Path
        ``path``.

    Notes
    -----
    Frames are drawn with the same outlines as :func:`snapshots` and written by
    :class:`matplotlib.animation.PillowWriter` (Pillow is a dependency of matplotlib).
    """
    from matplotlib.animation import PillowWriter

    u = _units(units)
    _check_result(result)
    path = Path(path)
    if path.suffix.lower() != ".gif":
        raise ModelError(f"animate writes GIF files; the path must end in .gif, got {path.name!r}")
    if not isinstance(n_frames, (int, np.integer)) or n_frames < 1:
        raise ModelError(f"n_frames must be a positive integer, got {n_frames!r}")
    if not (np.isfinite(fps) and fps > 0):
        raise ModelError(f"fps must be positive, got {fps!r}")
    outlines = _outlines(result)
    tgt = _check_target(target, outlines)
    t = np.real(result.t)
    idx = _time_indices(result, None, int(n_frames))

    fig = Figure(figsize=(5.0, 4.0), layout="constrained")
    ax = fig.add_subplot()
    allxy = np.concatenate([xy.reshape(-1, 2) for _, xy, _, _ in outlines]
                           + ([tgt] if tgt is not None else []))
    lo, hi = allxy.min(axis=0), allxy.max(axis=0)
    pad = 0.05 * max(float(np.max(hi - lo)), 1e-12)
    ax.set_xlim(lo[0] - pad, hi[0] + pad)
    ax.set_ylim(lo[1] - pad, hi[1] + pad)
    ax.set_aspect("equal", adjustable="box")
    ax.set_xlabel(f"x [{u['length']}]")
    ax.set_ylabel(f"y [{u['length']}]")
    if tgt is not None:
        ax.plot(tgt[:, 0], tgt[:, 1], "--", color="0.5", linewidth=1.2, label="target")
        ax.legend(loc="best", fontsize=8)
    g = [p for p, _, _ in _ground_points(result.system.model)]
    if g:
        g = np.array(g)
        ax.plot(g[:, 0], g[:, 1], "^", color="k", markersize=7, linestyle="none")
    lines = []
    colours = itertools.cycle(colormaps[_SEQUENTIAL](np.linspace(0.0, 0.7, 4)))
    for _, xy, _, _ in outlines:
        (ln,) = ax.plot([], [], "-", color=next(colours), linewidth=2.0,
                        marker="o" if xy.shape[1] == 1 else None)
        lines.append(ln)
    title = ax.set_title("")
    writer = PillowWriter(fps=fps)
    with writer.saving(fig, str(path), dpi):
        for k in idx:
            for ln, (_, xy, closed, _) in zip(lines, outlines):
                P = np.vstack([xy[k], xy[k][:1]]) if closed else xy[k]
                ln.set_data(P[:, 0], P[:, 1])
            title.set_text(f"t = {t[k]:.4g} {u['time']}")
            writer.grab_frame()
    return path


# --------------------------------------------------------------------------- stress, sensitivity
def stress_map(t, stress, ax=None, arc=None, fibre="max", *, units=None) -> Figure:
    """Space-time map of the normal stress of a beam (figure 6 of the paper).

    Parameters
    ----------
    t : array_like, shape (n_t,)
        Times [s], strictly increasing.
    stress : array_like, shape (n_t, n_elem, 2, 2)
        Stress at both ends and both outer fibres of every element, as from
        :meth:`Result.stress <morphlab.results.Result.stress>` [MPa].
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


# --------------------------------------------------------------------------- energy
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
    Lines: kinetic, strain, gravity, work of the applied loads and ``total - work`` with
    ``total = kinetic + strain + gravity`` (from :attr:`Result.energy`). With damping, the
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
              ("work of loads", e["work"]), ("total − work" + rel, bal)]
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
