"""The geometry of a run that its figures draw: body outlines at every step (beams with their
deformation magnified), the steps to draw, the target, the ground joints, the sliders and the
spring-dampers."""

from __future__ import annotations

import numpy as np

from ..errors import ModelError
from ..model import Beam, Ground, Spring
from ._common import _points, _real_array
from ._sliders import _sliders
from .drawing import _attachment_points, _ground_points, _model_size, _zigzag


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


def _check_target(target, outlines):
    if target is None:
        return None
    tgt = _points(target, "target")
    counts = [xy.shape[1] for _, xy, _, is_beam in outlines if is_beam]
    if counts and tgt.shape[0] not in counts:
        raise ModelError(f"target has {tgt.shape[0]} points but the beams have {counts} nodes; "
                         "give the target nodes of one beam, shape (n_nodes, 2)")
    return tgt


def _checked_outlines(result, magnify, target) -> tuple[float, list, np.ndarray | None]:
    """``magnify`` checked, the outlines of the run (``_outlines``) and the target checked
    against them (None without a target)."""
    magnify = _check_magnify(magnify)
    outlines = _outlines(result, magnify)
    return magnify, outlines, _check_target(target, outlines)


def _mark_ground_joints(ax, m, **kw) -> bool:
    """Black triangles at the joints of model ``m`` to the ground; whether there are any."""
    g = np.array([p for p, _, _ in _ground_points(m)]).reshape(-1, 2)
    if len(g):
        ax.plot(g[:, 0], g[:, 1], "^", color="k", markersize=7, linestyle="none", **kw)
    return bool(len(g))


def _slider_tracks(result) -> tuple[float, list]:
    """The size of a slider block [length] and the sliders of the run (``_sliders``)."""
    size = _model_size(result.system.model)
    return 0.03 * size, _sliders(result, size)


def _spring_tracks(result, outlines) -> list:
    """Per translational spring-damper: (spring, zigzags (n_t, k, 2)) between its two points,
    a beam's point taken from its drawn (magnified) outline so that the spring meets it."""
    beams = {name: xy for name, xy, _, is_beam in outlines if is_beam}
    width = 0.02 * _model_size(result.system.model)  # as in the model drawing
    n_t = np.real(result.t).shape[0]

    def track(body, at):
        if isinstance(body, Ground):
            return np.repeat(np.real(np.asarray(at, dtype=complex))[None], n_t, axis=0)
        if isinstance(body, Beam):
            return beams[body.name][:, body.nearest_node(at)[0]]
        return np.real(result.point_positions(body.name, at))

    out = []
    for sp in result.system.model.springs:
        if isinstance(sp, Spring):
            A, B = track(sp.a, sp.at_a), track(sp.b, sp.at_b)
            out.append((sp, np.stack([_zigzag(a, b, width) for a, b in zip(A, B)])))
    return out
