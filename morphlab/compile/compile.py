"""Model -> System: DOF numbering, invariants, constraint rows and the fixed CSC pattern.

Compiling is done once per model (and once per perturbed model in a sensitivity run). The
:class:`System` holds flat NumPy arrays only, all of one floating dtype (float64, or complex128
when a design variable carries a complex-step perturbation), plus the index tables that map
names to DOFs. Nothing here is in an inner loop: this is model-building code, kept in NumPy.
"""

from __future__ import annotations

import numpy as np

from ..errors import ModelError
from ..kernels import beam as kbeam
from ..model.model import Beam, Body, Drive, Fix, Ground, Model, Revolute, RigidBody, Weld
from ..model.profiles import Profile
from .checks import check_initial, check_rank, constraint_rank  # noqa: F401 (public)
from .pattern import newton_pattern
from .system import BodyInfo, System


def _dtype_of(model: Model):
    """complex128 if any number of the model is complex, else float64."""
    def cplx(x):
        return np.iscomplexobj(np.asarray(x))

    for b in model.bodies:
        vals = ([b.nodes, b.E, b.rho, b.area, b.second_moment, b.fibre, b.damping]
                if isinstance(b, Beam) else
                [b.mass, b.inertia, b.position, b.angle, b.velocity, b.angular_velocity])
        if any(cplx(v) for v in vals):
            return np.dtype(np.complex128)
    for j in model.joints:
        if cplx(getattr(j, "at", None) if getattr(j, "at", None) is not None else 0.0):
            return np.dtype(np.complex128)
        if isinstance(j, Drive) and _profile_is_complex(j.profile):
            return np.dtype(np.complex128)
    for f in model.forces:
        if cplx(f.at) or cplx(f.force) or _profile_is_complex(f.profile):
            return np.dtype(np.complex128)
    for t in model.torques:
        if cplx(t.magnitude) or _profile_is_complex(t.profile):
            return np.dtype(np.complex128)
    if cplx(model.gravity):
        return np.dtype(np.complex128)
    return np.dtype(np.float64)


def _profile_is_complex(prof: Profile) -> bool:
    vals = [getattr(prof, k) for k in getattr(prof, "__dataclass_fields__", {})]
    return any(isinstance(v, complex) or np.iscomplexobj(np.asarray(v)) for v in vals
               if isinstance(v, (int, float, complex, np.ndarray, np.number)))


def _rot(th):
    c, s = np.cos(th), np.sin(th)
    return np.array([[c, -s], [s, c]])


# what the Newton pattern is built from, and what it consists of (morphlab.pattern)
_TOPOLOGY_KEYS = ("n_dof", "n_con", "body_ref", "flex_off", "flex_dof", "elem_fdof", "con_kind",
                  "con_dofs", "load_dofs")
_PATTERN_KEYS = ("indptr", "indices", "border_off", "border_map", "elem_map", "con_map_row",
                 "con_map_col", "con_map_H", "load_map")


def _same_topology(sysd: dict, like: System) -> bool:
    return all(np.array_equal(sysd[k], getattr(like, k)) for k in _TOPOLOGY_KEYS)


def compile_model(model: Model, dtype=None, *, like: System | None = None) -> System:
    """Compile ``model`` into a :class:`System`.

    Parameters
    ----------
    model : Model
    dtype : numpy dtype, optional
        Force float64 or complex128; by default complex128 exactly when the model holds complex
        numbers (a complex-step perturbation).
    like : System, optional
        A system of the same topology (a perturbed design of a sensitivity run): its Newton
        pattern and scatter maps are reused when the DOF, element, joint and load tables are
        equal (they are compared, and the pattern is built afresh when they are not).

    Raises
    ------
    ModelError
        Empty model; initial configuration violating the constraints beyond ``1e-9`` of the
        model size, or initial velocities violating them; redundant or conflicting constraints
        (rank-deficient constraint Jacobian at the initial configuration, see
        :func:`constraint_rank`).
    """
    if not isinstance(model, Model):
        raise ModelError(f"compile_model expects a Model, got {type(model).__name__}")
    if not model.bodies:
        raise ModelError(f"model {model.name!r} has no bodies")
    dt = np.dtype(dtype) if dtype is not None else _dtype_of(model)

    # ---- DOF numbering and body data
    bodies: dict[str, BodyInfo] = {}
    dof_names: list[str] = []
    body_ref, body_scal, body_damp = [], [], []
    flex_off = [0]
    flex_dof: list[int] = []
    flex_IS, flex_I0S, flex_I0IS = [], [], []
    elem_body, elem_fdof, elem_dofs = [], [], []
    elem_M, elem_St, elem_K, elem_B = [], [], [], []
    q0: list = []
    v0: list = []
    n_elem_total = 0
    for bi, body in enumerate(model.bodies):
        base = len(dof_names)
        ref = np.array([base, base + 1, base + 2], dtype=np.int64)
        dof_names += [f"{body.name}.x", f"{body.name}.y", f"{body.name}.theta"]
        body_ref.append(ref)
        if isinstance(body, RigidBody):
            q0 += [body.position[0], body.position[1], body.angle]
            v0 += [body.velocity[0], body.velocity[1], body.angular_velocity]
            body_scal.append([body.mass, 0.0, 0.0, body.inertia])
            body_damp.append(0.0)
            flex_off.append(flex_off[-1])
            bodies[body.name] = BodyInfo(body.name, bi, ref, body.angle, "rigid")
            continue
        # beam: body frame at the reference node, x axis along its element
        X = body.nodes
        r = body.reference_node
        n_node = X.shape[0]
        nb = r + 1 if r < n_node - 1 else r - 1
        dc = X[max(r, nb)] - X[min(r, nb)]
        d = np.real(dc)
        th0 = float(np.arctan2(d[1], d[0]))
        if np.iscomplexobj(dc):
            # analytic continuation of the tangent angle (complex step through build): the
            # frame follows the reference element exactly as a real perturbation would make it
            th0 = th0 + np.arctan((d[0] * dc[1] - d[1] * dc[0]) / (d[0] * dc[0] + d[1] * dc[1]))
        A0 = _rot(th0)
        Xb = (X - X[r]) @ A0  # A0^T (X - X_r) for each row
        q0 += [X[r][0], X[r][1], th0]
        v0 += [0.0, 0.0, 0.0]
        node_dofs = -np.ones((n_node, 3), dtype=np.int64)
        for k in range(n_node):
            if k == r:
                continue
            for j, lab in enumerate("uvr"):
                node_dofs[k, j] = len(dof_names)
                dof_names.append(f"{body.name}.node{k}.{'phi' if lab == 'r' else lab}")
                q0.append(0.0)
                v0.append(0.0)
        nf = int((node_dofs >= 0).sum())
        f0 = flex_off[-1]
        flat = node_dofs.ravel()
        flex_index = -np.ones(flat.shape, dtype=np.int64)
        keep = flat >= 0
        flex_index[keep] = f0 + np.arange(nf)
        flex_dof += list(flat[keep])
        flex_off.append(f0 + nf)
        n_el = n_node - 1
        conn = np.stack([np.arange(n_el), np.arange(1, n_node)], axis=1).astype(np.int64)
        ones = np.ones(n_el, dtype=dt)
        scal = np.zeros(4, dtype=dt)
        IS = np.zeros((n_el, 2, 6), dtype=dt)
        I0S = np.zeros((n_el, 6), dtype=dt)
        I0IS = np.zeros((n_el, 6), dtype=dt)
        Me = np.zeros((n_el, 6, 6), dtype=dt)
        Se = np.zeros((n_el, 6, 6), dtype=dt)
        Ke = np.zeros((n_el, 6, 6), dtype=dt)
        Be = np.zeros((n_el, 2, 2, 6), dtype=dt)
        kbeam.beam_element_arrays(
            np.ascontiguousarray(Xb, dtype=dt), conn,
            ones * (body.rho * body.area), ones * (body.E * body.area),
            ones * (body.E * body.second_moment), ones * body.E, ones * body.fibre,
            scal, IS, I0S, I0IS, Me, Se, Ke, Be,
        )
        body_scal.append(list(scal))
        body_damp.append(body.damping)
        # sum element invariants into the body's flex coordinates
        fIS = np.zeros((nf, 2), dtype=dt)
        fI0S = np.zeros(nf, dtype=dt)
        fI0IS = np.zeros(nf, dtype=dt)
        efd = np.stack([flex_index.reshape(n_node, 3)[conn[:, 0]],
                        flex_index.reshape(n_node, 3)[conn[:, 1]]], axis=1).reshape(n_el, 6)
        edofs = np.stack([node_dofs[conn[:, 0]], node_dofs[conn[:, 1]]], axis=1).reshape(n_el, 6)
        m_ok = efd >= 0
        loc = efd - f0
        np.add.at(fIS[:, 0], loc[m_ok], IS[:, 0, :][m_ok])
        np.add.at(fIS[:, 1], loc[m_ok], IS[:, 1, :][m_ok])
        np.add.at(fI0S, loc[m_ok], I0S[m_ok])
        np.add.at(fI0IS, loc[m_ok], I0IS[m_ok])
        flex_IS.append(fIS)
        flex_I0S.append(fI0S)
        flex_I0IS.append(fI0IS)
        elem_body.append(np.full(n_el, bi, dtype=np.int64))
        elem_fdof.append(efd)
        elem_dofs.append(edofs)
        elem_M.append(Me)
        elem_St.append(Se)
        elem_K.append(Ke)
        elem_B.append(Be)
        bodies[body.name] = BodyInfo(body.name, bi, ref, th0, "beam", node_dofs, Xb,
                                     slice(n_elem_total, n_elem_total + n_el))
        n_elem_total += n_el
    n_dof = len(dof_names)

    def cat(lst, shape, dtype_=dt):
        return np.ascontiguousarray(np.concatenate(lst) if lst else np.zeros(shape, dtype_),
                                    dtype=dtype_)

    # ---- points
    def point(body: Body, at):
        """(dofs (6,), u0 (2,), angle0) of the material point of ``body`` at global ``at``."""
        dofs = -np.ones(6, dtype=np.int64)
        if isinstance(body, Ground):
            return dofs, np.zeros(2, dtype=dt), 0.0
        info = bodies[body.name]
        dofs[:3] = info.ref
        if isinstance(body, RigidBody):
            u0 = _rot(body.angle).T @ (np.asarray(at) - body.position)
            return dofs, u0, body.angle
        k, _ = body.nearest_node(at)
        dofs[3:] = info.node_dofs[k]
        return dofs, info.X[k], info.angle0

    con_kind, con_dofs, con_u0, con_c0, con_names, con_joint = [], [], [], [], [], []
    con_drive = []

    def add_row(kind, joint, label, pa, pb, c0):
        con_kind.append(kind)
        con_dofs.append(np.stack([pa[0], pb[0]]))
        con_u0.append(np.stack([pa[1], pb[1]]))
        con_c0.append(c0)
        con_names.append(f"{joint.name}.{label}")
        con_joint.append(joint.name)

    ground_pt = (-np.ones(6, dtype=np.int64), np.zeros(2, dtype=dt), 0.0)
    for j in model.joints:
        if isinstance(j, (Revolute, Weld)):
            pa, pb = point(j.a, j.at), point(j.b, j.at)
            # ground sides contribute their fixed coordinate to c: g = r_P - r_Q
            ca = np.asarray(j.at) if isinstance(j.a, Ground) else np.zeros(2)
            cb = np.asarray(j.at) if isinstance(j.b, Ground) else np.zeros(2)
            add_row(0, j, "x", pa, pb, -ca[0] + cb[0])
            add_row(1, j, "y", pa, pb, -ca[1] + cb[1])
            if isinstance(j, Weld):
                add_row(2, j, "r", pa, pb, pa[2] - pb[2])
        elif isinstance(j, Fix):
            pa = point(j.body, j.at)
            for lab in j.dofs:
                kind = "xyr".index(lab)
                c0 = pa[2] if kind == 2 else np.asarray(j.at)[kind]
                add_row(kind, j, lab, pa, ground_pt, c0)
        elif isinstance(j, Drive):
            at = j.at if j.at is not None else (
                j.body.position if isinstance(j.body, RigidBody) else None)
            pa = point(j.body, at)
            add_row(2, j, "r", pa, ground_pt, pa[2])
            con_drive.append((len(con_kind) - 1, j.profile))
        else:  # pragma: no cover - new joint types must be added here
            raise ModelError(f"joint {j.name!r}: unsupported type {type(j).__name__}")
    n_con = len(con_kind)

    load_dofs, load_u0, load_F0, load_prof = [], [], [], []
    for f in model.forces:
        pd, pu, _ = point(f.body, f.at)
        load_dofs.append(pd)
        load_u0.append(pu)
        load_F0.append(np.asarray(f.force))
        load_prof.append(f.profile)
    torque_dofs, torque_T0, torque_prof = [], [], []
    for t in model.torques:
        info = bodies[t.body.name]
        td = np.array([info.ref[2], -1], dtype=np.int64)
        if t.at is not None and isinstance(t.body, Beam):
            k, _ = t.body.nearest_node(t.at)
            td[1] = info.node_dofs[k, 2]
        torque_dofs.append(td)
        torque_T0.append(t.magnitude)
        torque_prof.append(t.profile)

    sysd = dict(
        model=model, dtype=dt, n_dof=n_dof, n_con=n_con,
        q0=np.array(q0, dtype=dt), v0=np.array(v0, dtype=dt),
        gravity=np.asarray(model.gravity, dtype=dt),
        body_ref=np.array(body_ref, dtype=np.int64).reshape(-1, 3),
        body_scal=np.array(body_scal, dtype=dt).reshape(-1, 4),
        body_damp=np.array(body_damp, dtype=dt),
        flex_off=np.array(flex_off, dtype=np.int64),
        flex_dof=np.array(flex_dof, dtype=np.int64),
        flex_IS=cat(flex_IS, (0, 2)), flex_I0S=cat(flex_I0S, (0,)),
        flex_I0IS=cat(flex_I0IS, (0,)),
        elem_body=cat(elem_body, (0,), np.int64), elem_fdof=cat(elem_fdof, (0, 6), np.int64),
        elem_dofs=cat(elem_dofs, (0, 6), np.int64),
        elem_M=cat(elem_M, (0, 6, 6)), elem_St=cat(elem_St, (0, 6, 6)),
        elem_K=cat(elem_K, (0, 6, 6)), elem_B=cat(elem_B, (0, 2, 2, 6)),
        con_kind=np.array(con_kind, dtype=np.int64),
        con_dofs=np.array(con_dofs, dtype=np.int64).reshape(-1, 2, 6),
        con_u0=np.array(con_u0, dtype=dt).reshape(-1, 2, 2),
        con_c0=np.array(con_c0, dtype=dt), con_drive=con_drive,
        load_dofs=np.array(load_dofs, dtype=np.int64).reshape(-1, 6),
        load_u0=np.array(load_u0, dtype=dt).reshape(-1, 2),
        load_F0=np.array(load_F0, dtype=dt).reshape(-1, 2), load_prof=load_prof,
        torque_dofs=np.array(torque_dofs, dtype=np.int64).reshape(-1, 2),
        torque_T0=np.array(torque_T0, dtype=dt), torque_prof=torque_prof,
        bodies=bodies, dof_names=dof_names, con_names=con_names, con_joint=con_joint,
    )
    extent = np.concatenate([np.real(np.asarray(b.nodes)) if isinstance(b, Beam)
                             else np.real(np.asarray(b.position))[None] for b in model.bodies])
    for j in model.joints:
        if getattr(j, "at", None) is not None:
            extent = np.vstack([extent, np.real(np.asarray(j.at))[None]])
    # model size for the Newton test; a model whose bodies and joints share one point has no
    # extent: fall back to 1 (a unit-agnostic "no scale")
    size = float(np.ptp(extent, axis=0).max())
    sysd["length_scale"] = size if size > 0 else 1.0
    if like is not None and _same_topology(sysd, like):
        sysd.update({k: getattr(like, k) for k in _PATTERN_KEYS})
    else:
        sysd.update(newton_pattern(sysd))
    system = System(**sysd)
    check_initial(system)
    check_rank(system)
    return system
