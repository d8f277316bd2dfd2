"""Joint reactions and drive effort, from the Lagrange multipliers of a run.

The equations of motion are ``M q'' + J^T lam = Q``: a constraint row ``g = g_P - g_Q`` (side 0
minus side 1, ``morphlab.kernels.joints``) pushes side 0's point with ``-lam dg_P/dr`` and side
1's with ``+lam dg_Q/dr``. A joint's **reaction** is the sum over its rows of the force and
moment on the body it holds: on ``b`` for a two-body joint (the action of ``a`` on ``b``; if
``b`` is the ground, minus the action on ``a``), on ``body`` for a fix or a drive (the action of
the ground). Forces act at the joint's point on that body (the slider's point for a prismatic
joint); the moment is the couple the joint transmits (zero for a revolute). The force and
moment of a unit multiplier of a row are the row kind's own (its
:attr:`~morphlab.kernels.schema.Kind.reactions`), so a new kind of constraint needs nothing
here.

Everything is written with NumPy operations that keep complex values, so responses built on
reactions can be differentiated by complex step.
"""

from __future__ import annotations

import numpy as np

from ..errors import ModelError
from ..kernels.schema import KINDS
from ..kernels.system import KIND_NAMES, TIMED_NAMES


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


def _directions(system, rows, q, arrays=None) -> np.ndarray:
    """``(n_t, n_rows, 3)``: the force (x, y) and moment of a unit multiplier of each row on
    its held side, at the times of ``q`` (n_t, n_dof) (``arrays``: the kinds' arrays to read,
    by default the system's)."""
    arrays = system.arrays if arrays is None else arrays
    out = np.zeros((q.shape[0], rows.size, 3), dtype=np.result_type(q, system.dtype))
    kinds = np.asarray(system.con_kind)[rows]
    for k in np.unique(kinds):
        sel = np.flatnonzero(kinds == k)
        name = KIND_NAMES[int(k)]
        items = np.asarray(system.con_item)[rows[sel]]
        sides = np.asarray(system.con_side)[rows[sel]]
        out[:, sel] = KINDS[name].reactions(getattr(arrays, name), items, sides, q)
    return out


def _rotation_to(system, frame: str | None, q):
    """``(c, s)`` of the angle of ``frame``'s body frame at each time ((n_t,) each), or None
    for the global frame."""
    if frame is None:
        return None
    th = q[:, system.body(frame).ref[2]]
    return np.cos(th), np.sin(th)


def _reaction(system, name, frame, q, lam, arrays=None):
    rows, signs = reaction_rows(system, name)
    dirs = _directions(system, rows, q, arrays)
    out = np.einsum("tkc,tk->tc", dirs, lam[:, rows] * signs)
    rot = _rotation_to(system, frame, q)
    if rot is not None:
        c, sn = rot
        out = np.stack([c * out[:, 0] + sn * out[:, 1], -sn * out[:, 0] + c * out[:, 1],
                        out[:, 2]], axis=-1)
    return out


def reaction(result, name: str, frame: str | None = None) -> np.ndarray:
    """Force and moment joint ``name`` transmits to the body it holds (module docstring),
    (n_t, 3): ``F_x, F_y`` [force] in the global frame, or in the frame of body ``frame``, and
    the moment [force·length] (counter-clockwise positive)."""
    if result.lam is None or result.q is None:
        raise ModelError("reactions need the histories of lam and q: run with store "
                         "including 'lam' and 'q'")
    return _reaction(result.system, name, frame, result.q, result.lam)


def reaction_vjp(result, name: str, component: int, n: int, frame: str | None = None):
    """Derivatives of ``reaction(result, name, frame)[n, component]`` (real parts), by complex
    step of :func:`reaction` at time index ``n``: with respect to ``q`` (n_dof,) and ``lam``
    (n_con,) there, and to the design data of the joint's row kinds (``{"<kind>.u0":
    array shaped like that field}``); the component's column of :func:`reaction_partials` and
    :func:`reaction_data_gradient` at that one time."""
    s = result.system
    q, lam = result.q[n][None], result.lam[n][None]
    _, dofs, dF_dq, rows, dF_dlam = reaction_partials(s, name, frame, q, lam)
    dq = np.zeros(s.n_dof)
    dq[dofs] = dF_dq[0, :, component]
    dlam = np.zeros(s.n_con)
    dlam[rows] = dF_dlam[0, :, component]
    G = np.zeros((1, 3))
    G[0, component] = 1.0
    return dq, dlam, reaction_data_gradient(s, name, frame, q, lam, G)


def _drive_rows(result, name: str) -> np.ndarray:
    """The rows of drive ``name``: a joint whose rows are all driven (time-dependent)."""
    s = result.system
    rows, _ = reaction_rows(s, name)
    driven = set(_driven(s).tolist())
    if not set(rows.tolist()) <= driven:
        drives = dict.fromkeys(s.con_joint[row] for row in sorted(driven))
        raise ModelError(f"joint {name!r} is not a drive (drives: "
                         f"{', '.join(map(repr, drives)) or 'none'})")
    return rows


def _driven(s) -> np.ndarray:
    """The constraint rows with a time profile (the drives' rows)."""
    out = []
    for name in TIMED_NAMES:
        table = s.table(name)
        if table is None or not hasattr(table, "con"):
            continue
        out += [int(table.con[i]) for i, _ in s.time_profiles.get(name, ())]
    return np.array(sorted(out), dtype=np.int64)


def drive_torque(result, name: str) -> np.ndarray:
    """Torque [force·length] the drive ``name`` applies to its body, (n_t,)."""
    _drive_rows(result, name)
    return reaction(result, name)[:, 2]


def drive_power(result, name: str) -> np.ndarray:
    """Power [force·length/time] the drive ``name`` delivers to the mechanism: its torque
    times the rate of the driven angle, (n_t,)."""
    rows = _drive_rows(result, name)
    s = result.system
    i = rows[0]
    table = s.table(KIND_NAMES[int(s.con_kind[i])])
    rate = 0.0 * result.v[:, 0]
    for d in table.dofs[s.con_item[i], 0, [2, 5]]:
        if d >= 0:
            rate = rate + result.v[:, d]
    return drive_torque(result, name) * rate


def drive_power_total(result) -> np.ndarray:
    """Power of every driven constraint row together, ``-sum lam_i (J q')_i``, (n_t,) (real
    parts: the energy balance; NaN when the run did not keep ``lam``)."""
    s = result.system
    driven = _driven(s)
    out = np.zeros(result.n_t)
    if driven.size == 0:
        return out
    if result.lam is None:
        return out * np.nan
    for k in range(result.n_t):
        # J q' - c' + c' at the time of step k: the velocity-level rows with the target rate
        _, Jv = s.constraint_violation(result.q[k], result.v[k], result.t[k])
        _, cd = s.constraint_violation(result.q[k], 0.0 * result.v[k], result.t[k])
        out[k] = -np.real(np.sum(result.lam[k, driven] * (Jv[driven] - cd[driven])))
    return out


def reaction_partials(system, name: str, frame: str | None, q, lam):
    """The reactions of joint ``name`` at the times of ``q`` (k, n_dof), ``lam`` (k, n_con)
    (real parts) and their partial derivatives there, by complex step of :func:`_reaction`
    over all the times at once (the reaction at a time reads only that time's ``q`` and
    ``lam``): ``(F, dofs, dF_dq, rows, dF_dlam)`` with ``F`` (k, 3), ``dF_dq`` (k, len(dofs),
    3) over the coordinates ``dofs`` it reads, ``dF_dlam`` (k, len(rows), 3) over the joint's
    constraint ``rows``."""
    rows, _ = reaction_rows(system, name)
    dofs = _touched(system, rows, frame)
    qc = np.real(np.asarray(q)).astype(complex)
    lc = np.real(np.asarray(lam)).astype(complex)
    F = np.real(_reaction(system, name, frame, qc, lc))
    h = 1e-30
    dq = np.zeros((qc.shape[0], dofs.size, 3))
    for j, d in enumerate(dofs):
        qc[:, d] += 1j * h
        dq[:, j] = np.imag(_reaction(system, name, frame, qc, lc)) / h
        qc[:, d] = np.real(qc[:, d])
    dl = np.zeros((qc.shape[0], rows.size, 3))
    for j, i in enumerate(rows):
        lc[:, i] += 1j * h
        dl[:, j] = np.imag(_reaction(system, name, frame, qc, lc)) / h
        lc[:, i] = np.real(lc[:, i])
    return F, dofs, dq, rows, dl


def reaction_data_gradient(system, name: str, frame: str | None, q, lam, G) -> dict:
    """``sum_n sum_c G[n, c] dF[n, c]/du`` over the design data ``u`` of the joint's row
    kinds (``{"<kind>.u0": array shaped like that field}``), ``F`` the reactions at the times
    of ``q``, ``lam`` and ``G`` (k, 3) their weights (complex step of :func:`_reaction`)."""
    rows, _ = reaction_rows(system, name)
    qc = np.real(np.asarray(q)).astype(complex)
    lc = np.real(np.asarray(lam)).astype(complex)
    G = np.real(np.asarray(G))
    h = 1e-30
    arrays = system.arrays_as(complex)
    kinds = np.asarray(system.con_kind)[rows]
    data = {}
    for k in np.unique(kinds):
        kind = KIND_NAMES[int(k)]
        table = getattr(arrays, kind)
        u0 = np.array(table.u0)
        du = np.zeros(u0.shape)
        for i in np.unique(np.asarray(system.con_item)[rows[kinds == k]]):
            for idx in np.ndindex(u0.shape[1:]):
                up = u0.copy()
                up[(i,) + idx] += 1j * h
                pert = arrays._replace(**{kind: table._replace(u0=up)})
                dF = np.imag(_reaction(system, name, frame, qc, lc, pert)) / h
                du[(i,) + idx] = float(np.sum(G * dF))
        data[f"{kind}.u0"] = du
    return data


def _touched(system, rows, frame) -> np.ndarray:
    """The coordinates the reaction of the constraint ``rows`` reads (their items' DOFs, and
    the angle of the body ``frame`` it is expressed in)."""
    touched = set()
    for i in rows:
        table = system.table(KIND_NAMES[int(system.con_kind[i])])
        touched.update(int(d) for d in table.dofs[system.con_item[i]].ravel() if d >= 0)
    if frame is not None:
        touched.add(int(system.body(frame).ref[2]))
    return np.array(sorted(touched), dtype=np.int64)
