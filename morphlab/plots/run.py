"""Figures of a model and of a run: model drawing, motion snapshots, animation, energy."""

from __future__ import annotations

import itertools
from pathlib import Path

import numpy as np
from matplotlib import colormaps
from matplotlib.cm import ScalarMappable
from matplotlib.colors import ListedColormap, Normalize
from matplotlib.figure import Figure
from matplotlib.patches import FancyArrowPatch, Polygon, Rectangle

from ..compile.system import System
from ..errors import ModelError
from ..model import (
    Beam,
    Drive,
    Fix,
    Ground,
    Model,
    Prismatic,
    Revolute,
    RigidBody,
    Weld,
)
from ._common import (
    _LINESTYLES,
    _SEQUENTIAL,
    _check_result,
    _new_axes,
    _points,
    _real_array,
    _units,
)
from ._sliders import _block, _sliders, _unit


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
        if isinstance(j, (Revolute, Weld, Prismatic)):
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
        :class:`~morphlab.results.result.Result` is drawn through its ``model``.
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
    filled square = weld, a block on a guide line = prismatic, joints to the ground and
    :class:`~morphlab.model.Fix` constraints
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
            elif isinstance(j, Prismatic):
                e = _unit(j.axis)
                ends = np.array([p - 4 * sym * e, p + 4 * sym * e])
                ax.plot(ends[:, 0], ends[:, 1], "-", color="0.3", linewidth=1.0, zorder=3,
                        gid=f"joint:{j.name}:guide")
                ax.add_patch(Polygon(_block(p, e, sym), closed=True, facecolor="white",
                                     edgecolor="k", linewidth=1.0, zorder=5,
                                     gid=f"joint:{j.name}"))
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
def _magnified(pos: np.ndarray, X0: np.ndarray, factor: float) -> np.ndarray:
    """Node positions ``pos`` (n_t, n, 2) of a beam (undeformed nodes ``X0`` (n, 2)) with
    their deformation relative to the beam's chord motion multiplied by ``factor``: the chord
    motion is the rigid motion taking node 0 to its position and the line from the first to
    the last node onto theirs (the first element's line for a closed beam). It does not
    depend on how many floating frames carry the beam."""
    if factor == 1.0:
        return pos
    k = X0.shape[0] - 1
    if np.hypot(*(X0[k] - X0[0])) < 1e-9 * max(np.ptp(X0), 1.0):
        k = 1
    d0 = X0[k] - X0[0]
    d = pos[:, k] - pos[:, 0]
    ang = np.arctan2(d[:, 1], d[:, 0]) - np.arctan2(d0[1], d0[0])
    c, s = np.cos(ang)[:, None], np.sin(ang)[:, None]
    u = X0 - X0[0]
    rigid = pos[:, :1] + np.stack([c * u[:, 0] - s * u[:, 1], s * u[:, 0] + c * u[:, 1]],
                                  axis=-1)
    return rigid + factor * (pos - rigid)


def _check_magnify(magnify) -> float:
    if isinstance(magnify, bool) or not isinstance(magnify, (int, float, np.integer,
                                                             np.floating)) \
            or not np.isfinite(magnify) or magnify < 0:
        raise ModelError(f"magnify must be a finite number >= 0 (1: true scale), got {magnify!r}")
    return float(magnify)


def _outlines(result, magnify: float = 1.0):
    """Per body: (name, xy (n_t, k, 2), closed, is_beam) drawn as a polyline at each time;
    beams with their deformation scaled by ``magnify`` relative to their chord motion."""
    m = result.system.model
    pts = _attachment_points(m)
    out = []
    for b in m.bodies:
        if isinstance(b, Beam):
            pos = np.real(result.node_positions(b.name))
            out.append((b.name, _magnified(pos, np.real(b.nodes), magnify), False, True))
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
    triangles; a prismatic joint is its guide line (grey) and a slider block per snapshot.
    """
    u = _units(units)
    _check_result(result)
    idx = _time_indices(result, times, n)
    magnify = _check_magnify(magnify)
    outlines = _outlines(result, magnify)
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
    sym = 0.03 * _model_size(result.system.model)
    for j, P, d, ends in _sliders(result, _model_size(result.system.model)):
        for i, k in enumerate(idx):
            if i == 0 or not isinstance(j.a, Ground):
                ax.plot(ends[k, :, 0], ends[k, :, 1], "-", color="0.5", linewidth=1.0,
                        gid=f"guide:{j.name}")
            ax.add_patch(Polygon(_block(P[k], d[k], sym), closed=True, fill=False,
                                 edgecolor=cmap(norm(t[k])), linewidth=1.2,
                                 gid=f"snapshot:{i}:{j.name}"))
    g = [p for p, _, _ in _ground_points(result.system.model)]
    if g:
        g = np.array(g)
        ax.plot(g[:, 0], g[:, 1], "^", color="k", markersize=7, linestyle="none", gid="ground",
                label="ground joints")
    if magnify != 1.0:
        ax.set_title(f"beam deformation magnified {magnify:g}x")
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


def animate(result, path, fps=20, n_frames=60, target=None, *, dpi=80, units=None,
            magnify: float = 1.0) -> Path:
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
    magnify : float
        Scale of the beams' deformation relative to their chord motion (as in
        :func:`snapshots`).

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
    outlines = _outlines(result, _check_magnify(magnify))
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
    sym = 0.03 * _model_size(result.system.model)
    sliders = []
    for _j, P, d, ends in _sliders(result, _model_size(result.system.model)):
        (guide,) = ax.plot(ends[0, :, 0], ends[0, :, 1], "-", color="0.5", linewidth=1.0)
        block = Polygon(_block(P[0], d[0], sym), closed=True, facecolor="white",
                        edgecolor="k", linewidth=1.0, zorder=4)
        ax.add_patch(block)
        sliders.append((guide, block, P, d, ends))
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
            for guide, block, P, d, ends in sliders:
                guide.set_data(ends[k, :, 0], ends[k, :, 1])
                block.set_xy(_block(P[k], d[k], sym))
            title.set_text(f"t = {t[k]:.4g} {u['time']}" + (
                f", deformation x{magnify:g}" if magnify != 1.0 else ""))
            writer.grab_frame()
    return path


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
