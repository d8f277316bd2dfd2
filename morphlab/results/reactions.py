"""Joint reactions and drive effort, from the Lagrange multipliers of a run.

The equations of motion are ``M q'' + J^T lam = Q``: a constraint row ``g = g_P - g_Q`` (side 0
minus side 1, ``morphlab.kernels.joints``) pushes side 0's point with ``-lam dg_P/dr`` and side
1's with ``+lam dg_Q/dr`` (for a slide row both along the guide's normal ``n``, applied at the
slider's point). A joint's **reaction** is the sum over its rows of the force and moment on the
body it holds: on ``b`` for a two-body joint (the action of ``a`` on ``b``; if ``b`` is the
ground, minus the action on ``a``), on ``body`` for a fix or a drive (the action of the
ground). Forces act at the joint's point on that body (the slider's point for a prismatic
joint); the moment is the couple the joint transmits (zero for a revolute).

Everything is written with NumPy operations that keep complex values, so responses built on
reactions can be differentiated by complex step.
"""

from __future__ import annotations

import numpy as np

from ..compile.system import extra_items
from ..errors import ModelError
from ..kernels.joints import ROW_ANGLE, ROW_SLIDE, ROW_X, ROW_Y, constraint_values


def reaction_rows(system, name: str) -> tuple[np.ndarray, np.ndarray]:
    """The constraint rows of joint ``name`` and the sign ``s_i`` (+1 or -1) with which each
    row's multiplier pushes the held body (module docstring; ``System.con_sign``, set by
    ``compile``): ``(rows, signs)``."""
    rows = np.array([i for i, jn in enumerate(system.con_joint) if jn == name], dtype=np.int64)
    if rows.size == 0:
        known = ", ".join(dict.fromkeys(map(repr, system.con_joint))) or "none"
        raise ModelError(f"no joint {name!r} in model {system.model.name!r} (joints: {known})")
    signs = np.asarray(system.con_sign)[rows]
    if not np.all(np.isfinite(signs)):
        raise ModelError(f"joint {name!r} holds no body whose reaction could be given")
    return rows, signs


def _directions(system, rows, q) -> np.ndarray:
    """``(n_t, n_rows, 3)``: the force (x, y) and moment of a unit multiplier of each row on
    side 1 (the global normal of a slide row at the times of ``q`` (n_t, n_dof))."""
    kind = system.con_kind[rows]
    out = np.zeros((q.shape[0], rows.size, 3), dtype=np.result_type(q, system.dtype))
    out[:, kind == ROW_X, 0] = 1.0
    out[:, kind == ROW_Y, 1] = 1.0
    out[:, kind == ROW_ANGLE, 2] = 1.0
    for k in np.flatnonzero(kind == ROW_SLIDE):
        i = rows[k]
        psi = system.con_u0[i, 1, 2] + 0.0 * q[:, 0]
        for d in system.con_dofs[i, 1, [2, 5]]:
            if d >= 0:
                psi = psi + q[:, d]
        out[:, k, 0], out[:, k, 1] = np.cos(psi), np.sin(psi)
    return out


def _rotation_to(system, frame: str | None, q):
    """``(c, s)`` of the angle of ``frame``'s body frame at each time ((n_t,) each), or None
    for the global frame."""
    if frame is None:
        return None
    th = q[:, system.body(frame).ref[2]]
    return np.cos(th), np.sin(th)


def reaction(result, name: str, frame: str | None = None) -> np.ndarray:
    """Force and moment joint ``name`` transmits to the body it holds (module docstring),
    (n_t, 3): ``F_x, F_y`` [force] in the global frame, or in the frame of body ``frame``, and
    the moment [force·length] (counter-clockwise positive)."""
    if result.lam is None or result.q is None:
        raise ModelError("reactions need the histories of lam and q: run with store "
                         "including 'lam' and 'q'")
    s = result.system
    rows, signs = reaction_rows(s, name)
    dirs = _directions(s, rows, result.q)
    out = np.einsum("tkc,tk->tc", dirs, result.lam[:, rows] * signs)
    rot = _rotation_to(s, frame, result.q)
    if rot is not None:
        c, sn = rot
        out = np.stack([c * out[:, 0] + sn * out[:, 1], -sn * out[:, 0] + c * out[:, 1],
                        out[:, 2]], axis=-1)
    return out


def reaction_vjp(result, name: str, component: int, n: int, frame: str | None = None):
    """Derivatives of ``reaction(result, name, frame)[n, component]`` (real parts): with
    respect to ``q`` (n_dof,) and ``lam`` (n_con,) at time index ``n``, and to ``con_u0``
    (the angle of a slide row's guide): ``(dq, dlam, dcon_u0)``."""
    s = result.system
    rows, signs = reaction_rows(s, name)
    q = np.real(result.q[n])[None]
    lam = np.real(result.lam[n, rows]) * signs
    dirs = _directions(s, rows, q)[0].real  # (k, 3)
    # d dir/d psi of slide rows: the guide's tangent (-sin psi, cos psi, 0)
    tang = np.stack([-dirs[:, 1], dirs[:, 0], 0.0 * dirs[:, 0]], axis=1)
    slide = s.con_kind[rows] == ROW_SLIDE
    dq = np.zeros(s.n_dof)
    if frame is not None:
        ref = s.body(frame).ref[2]
        c, sn = np.cos(q[0, ref]), np.sin(q[0, ref])
        rot = np.array([[c, sn, 0.0], [-sn, c, 0.0], [0.0, 0.0, 1.0]])
        F = rot @ (dirs.T @ lam)
        # d(rot F)/d theta: (F'_1, -F'_0, 0)
        dq[ref] += (F[1], -F[0], 0.0)[component]
    else:
        rot = np.eye(3)
    dlam = np.zeros(s.n_con)
    dlam[rows] = signs * (dirs @ rot.T)[:, component]
    du = np.zeros(np.shape(s.con_u0))
    dpsi = lam * (tang @ rot.T)[:, component]
    for k in np.flatnonzero(slide):
        du[rows[k], 1, 2] = dpsi[k]
        for d in s.con_dofs[rows[k], 1, [2, 5]]:
            if d >= 0:
                dq[d] += dpsi[k]
    return dq, dlam, du


def _drive(result, name: str):
    """Check that ``name`` is a drive: a joint whose rows are all driven (time-dependent)."""
    s = result.system
    rows, _ = reaction_rows(s, name)
    driven = {row for row, _ in s.con_drive}
    if not set(rows.tolist()) <= driven:
        drives = dict.fromkeys(s.con_joint[row] for row, _ in s.con_drive)
        raise ModelError(f"joint {name!r} is not a drive (drives: "
                         f"{', '.join(map(repr, drives)) or 'none'})")


def drive_torque(result, name: str) -> np.ndarray:
    """Torque [force·length] the drive ``name`` applies to its body, (n_t,)."""
    _drive(result, name)
    return reaction(result, name)[:, 2]


def drive_power(result, name: str) -> np.ndarray:
    """Power [force·length/time] the drive ``name`` delivers to the mechanism: its torque
    times the rate of the driven angle, (n_t,)."""
    _drive(result, name)
    s = result.system
    rows, _ = reaction_rows(s, name)
    i = rows[0]
    rate = 0.0 * result.v[:, 0]
    for d in s.con_dofs[i, 0, [2, 5]]:
        if d >= 0:
            rate = rate + result.v[:, d]
    return drive_torque(result, name) * rate


def drive_power_total(result) -> np.ndarray:
    """Power of every driven constraint row together, ``-sum lam_i (J q')_i``, (n_t,) (real
    parts: the energy balance; NaN when the run did not keep ``lam``)."""
    s = result.system
    driven = np.array([row for row, _ in s.con_drive], dtype=np.int64)
    out = np.zeros(result.n_t)
    if driven.size == 0:
        return out
    if result.lam is None:
        return out * np.nan
    C = np.zeros(s.n_con, dtype=s.dtype)
    phi = np.zeros(s.n_con, dtype=s.dtype)
    Jv = np.zeros(s.n_con, dtype=s.dtype)
    u0 = np.ascontiguousarray(s.con_u0)
    extra = extra_items(s)
    for k in range(result.n_t):
        constraint_values(extra, result.q[k], result.v[k], C, C, s.con_kind, s.con_dofs, u0,
                          phi, Jv)
        out[k] = -np.real(np.sum(result.lam[k, driven] * Jv[driven]))
    return out
