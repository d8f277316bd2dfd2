"""Drawing prismatic joints: a slider block on its guide line, in the initial configuration
and along a run."""

from __future__ import annotations

import numpy as np

from ..model import Beam, Ground, Prismatic


def _block(centre, axis, size) -> np.ndarray:
    """Corners (4, 2) of a slider block at ``centre`` aligned with the unit vector ``axis``."""
    e = np.asarray(axis, dtype=float)
    n = np.array([-e[1], e[0]])
    return np.asarray(centre, dtype=float) + np.array(
        [sx * 0.9 * size * e + sy * 0.55 * size * n for sx, sy in
         ((-1, -1), (1, -1), (1, 1), (-1, 1))])


def _unit(axis) -> np.ndarray:
    d = np.real(np.asarray(axis)).astype(float)
    return d / np.hypot(*d)


def _sliders(result, size: float) -> list:
    """Per prismatic joint: (joint, slider point (n_t, 2), guide direction (n_t, 2), guide
    ends (n_t, 2, 2)); a guide on the ground spans the slider's stroke (plus 0.15 ``size``),
    one on a body (0.6 ``size`` long) turns with the body and a beam node's rotation."""
    out = []
    for j in result.system.model.joints:
        if not isinstance(j, Prismatic):
            continue
        P = np.real(result.point_positions(j.b.name, j.at))
        e0 = _unit(j.axis)
        if isinstance(j.a, Ground):
            d = np.repeat(e0[None], P.shape[0], axis=0)
            s = (P - np.real(j.at)) @ e0
            half = 0.5 * (s.max() - s.min()) + 0.15 * size
            mid = np.real(j.at) + 0.5 * (s.max() + s.min()) * e0
            ends = np.repeat(np.array([mid - half * e0, mid + half * e0])[None], P.shape[0], 0)
        else:
            rot = np.real(result.reference(j.a.name)[1]) - np.real(result.system.body(
                j.a.name).angle0)
            if isinstance(j.a, Beam):
                k, _ = j.a.nearest_node(j.at)
                rot = rot + np.real(result.deformation(j.a.name)[:, k, 2])
            c, sn = np.cos(rot), np.sin(rot)
            d = np.stack([c * e0[0] - sn * e0[1], sn * e0[0] + c * e0[1]], axis=1)
            Q = np.real(result.point_positions(j.a.name, j.at))
            half = 0.3 * size
            ends = np.stack([Q - half * d, Q + half * d], axis=1)
        out.append((j, P, d, ends))
    return out
