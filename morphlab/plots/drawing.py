"""Drawing a model in its initial configuration: bodies, joints, loads and the ground symbols
that the figures of a run reuse."""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
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
    Spring,
    Weld,
)
from ._common import _new_axes, _units
from ._sliders import _block, _unit


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
    for sp in m.springs:
        add(sp.a, sp.at_a)
        add(sp.b, sp.at_b)
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



_TEXT = dict(fontsize=8, zorder=6)


class _Scale(NamedTuple):
    """Sizes of a model drawing [length]: the model's extent, a symbol and a label offset."""

    size: float
    sym: float
    off: float


def _as_model(obj) -> Model:
    """The Model of a Model, a System or a Result."""
    m = obj
    if isinstance(getattr(m, "system", None), System):
        m = m.system
    if isinstance(m, System):
        m = m.model
    if not isinstance(m, Model):
        raise ModelError(f"expected a Model, System or Result, got {type(obj).__name__}")
    return m


def _draw_bodies(ax, m: Model, sc: _Scale, show_nodes: bool, labels: bool) -> None:
    """Beams as polylines through their nodes; rigid bodies as a square at the centre of mass
    with lines to their attachment points."""
    pts = _attachment_points(m)
    for b in m.bodies:
        if isinstance(b, Beam):
            X = np.real(b.nodes).astype(float)
            ax.plot(X[:, 0], X[:, 1], "-", color="0.25", linewidth=2.0, zorder=2,
                    marker="o" if show_nodes else None, markersize=3, markerfacecolor="k",
                    gid=f"beam:{b.name}")
            where = X[X.shape[0] // 2] + [sc.off, sc.off]
        elif isinstance(b, RigidBody):
            c = np.real(b.position).astype(float)
            for p in pts.get(b.name, []):
                ax.plot([c[0], p[0]], [c[1], p[1]], "-", color="0.45", linewidth=3.0,
                        solid_capstyle="round", zorder=1, gid=f"body:{b.name}")
            ax.plot([c[0]], [c[1]], "s", color="k", markersize=6, zorder=4,
                    gid=f"body:{b.name}:com")
            where = c + [sc.off, -2 * sc.off]
        else:
            continue
        if labels:
            ax.text(where[0], where[1], b.name, color="0.25", style="italic",
                    gid=f"label:{b.name}", **_TEXT)


def _draw_joint(ax, j, sym: float) -> tuple[np.ndarray, str]:
    """The symbol of one joint or drive; its point (2,) and label."""
    if isinstance(j, Drive):
        at = j.at if j.at is not None else j.body.position
        p = np.real(np.asarray(at)).astype(float)
        _curved_arrow(ax, p, 1.6 * sym, True, color="0.3", linestyle="--",
                      gid=f"joint:{j.name}", zorder=5)
        return p, f"{j.name} (drive)"
    p = np.real(np.asarray(j.at)).astype(float)
    if isinstance(j, Revolute):
        ax.plot([p[0]], [p[1]], "o", markersize=7, markerfacecolor="white",
                markeredgecolor="k", zorder=5, gid=f"joint:{j.name}")
    elif isinstance(j, Weld):
        ax.plot([p[0]], [p[1]], "s", markersize=6, color="k", zorder=5, gid=f"joint:{j.name}")
    elif isinstance(j, Prismatic):
        e = _unit(j.axis)
        ends = np.array([p - 4 * sym * e, p + 4 * sym * e])
        ax.plot(ends[:, 0], ends[:, 1], "-", color="0.3", linewidth=1.0, zorder=3,
                gid=f"joint:{j.name}:guide")
        ax.add_patch(Polygon(_block(p, e, sym), closed=True, facecolor="white",
                             edgecolor="k", linewidth=1.0, zorder=5, gid=f"joint:{j.name}"))
    else:
        ax.plot([p[0]], [p[1]], "o", markersize=4, color="k", zorder=5, gid=f"joint:{j.name}")
    return p, (f"{j.name} ({j.dofs})" if isinstance(j, Fix) else j.name)


def _draw_joints(ax, m: Model, sc: _Scale, labels: bool) -> None:
    """Ground symbols under the joints to the ground, then every joint's symbol."""
    for p, clamp, _j in _ground_points(m):
        _ground_symbol(ax, p, sc.sym, clamp)
    for j in m.joints:
        p, label = _draw_joint(ax, j, sc.sym)
        if labels:
            ax.text(p[0] - sc.off, p[1] + sc.off, label, ha="right", fontweight="bold",
                    gid=f"label:{j.name}", **_TEXT)


def _draw_loads(ax, m: Model, sc: _Scale, labels: bool, u: dict) -> None:
    """Forces as arrows of fixed length pointing at their point, torques as curved arrows."""
    for f in m.forces:
        p = np.real(np.asarray(f.at)).astype(float)
        F = np.real(np.asarray(f.force)).astype(float)
        mag = float(np.hypot(*F))
        d = F / mag if mag > 0 else np.array([0.0, -1.0])
        tail = p - 0.12 * sc.size * d
        ax.annotate("", xy=p, xytext=tail, gid=f"force:{f.name}", zorder=6,
                    arrowprops=dict(arrowstyle="-|>", color="k", linewidth=1.5,
                                    mutation_scale=12))
        if labels:
            ax.text(tail[0], tail[1], f"{f.name} ({mag:.3g} {u['force']})", ha="center",
                    va="bottom" if d[1] <= 0 else "top", gid=f"label:{f.name}", **_TEXT)
    for tq in m.torques:
        at = tq.at if tq.at is not None else tq.body.position
        p = np.real(np.asarray(at)).astype(float)
        mag = float(np.real(tq.magnitude))
        _curved_arrow(ax, p, 2.2 * sc.sym, mag >= 0, color="k", linewidth=1.5,
                      gid=f"torque:{tq.name}", zorder=6)
        if labels:
            ax.text(p[0] + 2.4 * sc.sym, p[1] + 1.6 * sc.sym,
                    f"{tq.name} ({mag:.3g} {u['torque']})", gid=f"label:{tq.name}", **_TEXT)


def _zigzag(p0, p1, width: float, n: int = 6) -> np.ndarray:
    """Points (2 n + 4, 2) of a spring symbol from ``p0`` to ``p1``: straight ends and ``n``
    teeth of half-width ``width`` over the middle 70 %."""
    d = p1 - p0
    length = float(np.hypot(*d))
    if length == 0.0:
        return np.array([p0, p1])
    t, nrm = d / length, np.array([-d[1], d[0]]) / length
    s = np.r_[0.0, 0.15, 0.15 + 0.7 * (np.arange(2 * n) + 0.5) / (2 * n), 0.85, 1.0]
    side = np.r_[0.0, 0.0, width * (-1.0) ** np.arange(2 * n), 0.0, 0.0]
    return p0 + np.outer(s * length, t) + np.outer(side, nrm)


def _draw_springs(ax, m: Model, sc: _Scale, labels: bool) -> None:
    """Spring-dampers as zigzags between their points, rotational ones as a spiral at theirs,
    line loads as a row of arrows along the loaded elements."""
    for sp in m.springs:
        if isinstance(sp, Spring):
            p0, p1 = (np.real(np.asarray(x)).astype(float) for x in (sp.at_a, sp.at_b))
            xy = _zigzag(p0, p1, 0.5 * sc.sym)
            at = 0.5 * (p0 + p1)
        else:  # rotational: a spiral around its point (a beam node, or the body's centre)
            at = np.real(np.asarray(sp.at_a if sp.at_a is not None else sp.a.position,
                                    dtype=complex)).astype(float)
            ang = np.linspace(0.0, 4.0 * np.pi, 80)
            r = sc.sym * (0.3 + 0.9 * ang / ang[-1])
            xy = at + np.c_[r * np.cos(ang), r * np.sin(ang)]
        ax.plot(xy[:, 0], xy[:, 1], color="tab:green", linewidth=1.2, zorder=5,
                gid=f"spring:{sp.name}")
        if labels:
            ax.text(at[0] + sc.off, at[1] + sc.off, sp.name, gid=f"label:{sp.name}", **_TEXT)
    for ld in m.line_loads:
        nodes = np.real(np.asarray(ld.beam.nodes)).astype(float)
        q = np.real(np.asarray(ld.q)).astype(float)
        mag = float(np.hypot(*q))
        d = q / mag if mag > 0 else np.array([0.0, -1.0])
        heads = np.concatenate([0.5 * (nodes[e] + nodes[e + 1])[None] for e in ld.elements])
        for h in heads:
            ax.annotate("", xy=h, xytext=h - 0.06 * sc.size * d, zorder=6,
                        gid=f"line_load:{ld.name}", arrowprops=dict(
                            arrowstyle="-|>", color="tab:blue", linewidth=1.0,
                            mutation_scale=8))
        if labels and heads.size:
            tail = heads[len(heads) // 2] - 0.06 * sc.size * d
            ax.text(tail[0], tail[1], ld.name, ha="center", va="bottom" if d[1] <= 0 else "top",
                    gid=f"label:{ld.name}", **_TEXT)


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
    Spring-dampers are zigzags between their points, rotational springs spirals at theirs, line
    loads a row of arrows at the middle of the loaded elements. Drawn artists carry a ``gid``
    (``"beam:<name>"``, ``"body:<name>"``, ``"joint:<name>"``, ``"ground"``,
    ``"force:<name>"``, ``"torque:<name>"``, ``"spring:<name>"``, ``"line_load:<name>"``) so
    that they can be found again.
    """
    u = _units(units)
    m = _as_model(model_or_system)
    fig, ax = _new_axes(ax)
    size = _model_size(m)
    sc = _Scale(size, 0.04 * size, 0.015 * size)
    _draw_bodies(ax, m, sc, show_nodes, labels)
    _draw_joints(ax, m, sc, labels)
    _draw_loads(ax, m, sc, labels, u)
    _draw_springs(ax, m, sc, labels)
    ax.set_aspect("equal", adjustable="datalim")
    ax.autoscale_view()
    ax.set_xlabel(f"x [{u['length']}]")
    ax.set_ylabel(f"y [{u['length']}]")
    ax.set_title(m.name)
    return fig
