"""Model -> System: DOF numbering, invariants, constraint rows and the fixed CSC pattern.

Compiling is done once per model (and once per perturbed model in a sensitivity run). The
:class:`System` holds flat NumPy arrays only, all of one floating dtype (float64, or complex128
when a design variable carries a complex-step perturbation), plus the index tables that map
names to DOFs. Nothing here is in an inner loop: this is model-building code, kept in NumPy.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .errors import ModelError
from .kernels import beam as kbeam
from .kernels import joints as kjoints
from .model import Beam, Body, Drive, Fix, Ground, Model, Revolute, RigidBody, Weld
from .profiles import Profile

# entries of a side's 6 x 6 Hessian that can be nonzero (theta-theta, theta-w, w-theta)
_HESS_ENTRIES = ((2, 2), (2, 3), (3, 2), (2, 4), (4, 2))


@dataclass
class BodyInfo:
    """Where a body lives in the system arrays.

    Attributes
    ----------
    index : int
        Position in ``body_ref`` / ``body_scal``.
    ref : (3,) int64
        Global DOFs of ``R_x, R_y, theta``.
    angle0 : float
        Initial angle of the body frame.
    node_dofs : (n_node, 3) int64 or None
        Beams: global DOF of ``u, v, phi`` of each node in the body frame (``-1`` removed).
    X : (n_node, 2) or None
        Beams: node positions in the body frame.
    elements : slice
        Beams: rows of the element arrays.
    """

    name: str
    index: int
    ref: np.ndarray
    angle0: object
    kind: str
    node_dofs: np.ndarray | None = None
    X: np.ndarray | None = None
    elements: slice | None = None


@dataclass
class System:
    """Compiled model: flat arrays for the kernels and index tables for the user side.

    All floating arrays share ``dtype``. The kernel-facing arrays are listed in the module
    ``morphlab.kernels.assemble`` (:func:`kernel_args`).
    """

    model: Model
    dtype: np.dtype
    n_dof: int
    n_con: int
    q0: np.ndarray
    v0: np.ndarray
    gravity: np.ndarray
    body_ref: np.ndarray
    body_scal: np.ndarray
    body_damp: np.ndarray
    flex_off: np.ndarray
    flex_dof: np.ndarray
    flex_IS: np.ndarray
    flex_I0S: np.ndarray
    flex_I0IS: np.ndarray
    elem_body: np.ndarray
    elem_fdof: np.ndarray
    elem_dofs: np.ndarray
    elem_M: np.ndarray
    elem_St: np.ndarray
    elem_K: np.ndarray
    elem_B: np.ndarray
    con_kind: np.ndarray
    con_dofs: np.ndarray
    con_u0: np.ndarray
    con_c0: np.ndarray
    con_drive: list
    load_dofs: np.ndarray
    load_u0: np.ndarray
    load_F0: np.ndarray
    load_prof: list
    torque_dofs: np.ndarray
    torque_T0: np.ndarray
    torque_prof: list
    indptr: np.ndarray
    indices: np.ndarray
    border_off: np.ndarray
    border_map: np.ndarray
    elem_map: np.ndarray
    con_map_row: np.ndarray
    con_map_col: np.ndarray
    con_map_H: np.ndarray
    load_map: np.ndarray
    bodies: dict = field(default_factory=dict)
    dof_names: list = field(default_factory=list)
    con_names: list = field(default_factory=list)
    con_joint: list = field(default_factory=list)
    length_scale: float = 1.0

    @property
    def n(self) -> int:
        """Size of the saddle-point system, ``n_dof + n_con``."""
        return self.n_dof + self.n_con

    @property
    def nnz(self) -> int:
        return int(self.indices.shape[0])

    def body(self, name: str) -> BodyInfo:
        """Index information of the body called ``name``."""
        try:
            return self.bodies[name]
        except KeyError:
            known = ", ".join(repr(k) for k in self.bodies)
            raise ModelError(f"no body {name!r} in model (bodies: {known})") from None

    def time_arrays(self, t: float):
        """Time-dependent data at ``t``: ``(c, cd, cdd, F, T)``.

        ``c, cd, cdd`` (n_con,) are the constraint targets and their derivatives, ``F``
        (n_load, 2) the point forces and ``T`` (n_torque,) the torques.
        """
        c = self.con_c0.copy()
        cd = np.zeros_like(c)
        cdd = np.zeros_like(c)
        for row, prof in self.con_drive:
            c[row] = c[row] + prof.value(t)
            cd[row] = prof.d1(t)
            cdd[row] = prof.d2(t)
        F = self.load_F0.copy()
        for i, prof in enumerate(self.load_prof):
            F[i] = F[i] * prof.value(t)
        T = self.torque_T0.copy()
        for i, prof in enumerate(self.torque_prof):
            T[i] = T[i] * prof.value(t)
        return c, cd, cdd, F, T

    def constraint_violation(self, q, v, t):
        """``(phi, phid)``: position- and velocity-level violation of every row at time t."""
        c, cd, _, _, _ = self.time_arrays(t)
        dt = np.result_type(self.dtype, q.dtype)
        phi = np.zeros(self.n_con, dtype=dt)
        phid = np.zeros(self.n_con, dtype=dt)
        kjoints.constraint_values(q.astype(dt), v.astype(dt), c.astype(dt), cd.astype(dt),
                                  self.con_kind, self.con_dofs, self.con_u0.astype(dt), phi, phid)
        return phi, phid

    def constraint_matrix(self, q):
        """Dense constraint Jacobian (n_con, n_dof) at ``q``."""
        dt = np.result_type(self.dtype, q.dtype)
        Jc = np.zeros((self.n_con, self.n_dof), dtype=dt)
        kjoints.constraint_jacobian_matrix(q.astype(dt), self.con_kind, self.con_dofs,
                                           self.con_u0.astype(dt), self.n_dof, Jc)
        return Jc


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


def compile_model(model: Model, dtype=None) -> System:
    """Compile ``model`` into a :class:`System`.

    Parameters
    ----------
    model : Model
    dtype : numpy dtype, optional
        Force float64 or complex128; by default complex128 exactly when the model holds complex
        numbers (a complex-step perturbation).

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
    def snapped(j, *sides):
        """The joint point: a beam node if a side is a beam (add-time validation accepted
        ``at`` within a tolerance of it), so every side of the joint sees one point."""
        for b in sides:
            if isinstance(b, Beam):
                return b.nodes[b.nearest_node(j.at)[0]]
        return j.at

    for j in model.joints:
        if isinstance(j, (Revolute, Weld)):
            j_at = snapped(j, j.a, j.b)
            pa, pb = point(j.a, j_at), point(j.b, j_at)
            # ground sides contribute their fixed coordinate to c: g = r_P - r_Q
            ca = np.asarray(j_at) if isinstance(j.a, Ground) else np.zeros(2)
            cb = np.asarray(j_at) if isinstance(j.b, Ground) else np.zeros(2)
            add_row(0, j, "x", pa, pb, -ca[0] + cb[0])
            add_row(1, j, "y", pa, pb, -ca[1] + cb[1])
            if isinstance(j, Weld):
                add_row(2, j, "r", pa, pb, pa[2] - pb[2])
        elif isinstance(j, Fix):
            j_at = snapped(j, j.body)
            pa = point(j.body, j_at)
            for lab in j.dofs:
                kind = "xyr".index(lab)
                c0 = pa[2] if kind == 2 else np.asarray(j_at)[kind]
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
    sysd.update(_pattern(sysd))
    system = System(**sysd)
    _check_initial(system)
    _check_rank(system)
    return system


def _pattern(s) -> dict:
    """Fixed CSC pattern of the Newton matrix and the scatter map of every contribution."""
    n_dof, n_con = s["n_dof"], s["n_con"]
    n = n_dof + n_con
    rows: list[np.ndarray] = []
    cols: list[np.ndarray] = []

    def add(r, c):
        r = np.asarray(r, dtype=np.int64).ravel()
        c = np.asarray(c, dtype=np.int64).ravel()
        rows.append(r)
        cols.append(c)
        return sum(x.size for x in rows) - r.size

    # body borders
    body_ref, flex_off, flex_dof = s["body_ref"], s["flex_off"], s["flex_dof"]
    border_off = [0]
    starts = []
    for b in range(body_ref.shape[0]):
        ref = body_ref[b]
        fd = flex_dof[flex_off[b]:flex_off[b + 1]]
        r3, c3 = np.meshgrid(ref, ref, indexing="ij")
        starts.append(add(r3, c3))
        add(np.repeat(ref, fd.size), np.tile(fd, 3))
        add(np.repeat(fd, 3), np.tile(ref, fd.size))
        border_off.append(border_off[-1] + 9 + 6 * fd.size)
    n_border = border_off[-1]
    border_start = starts[0] if starts else 0
    # elements
    efd = s["elem_fdof"]
    gd = np.where(efd >= 0, flex_dof[np.maximum(efd, 0)] if flex_dof.size else -1, -1)
    er = np.repeat(gd[:, :, None], 6, axis=2)
    ec = np.repeat(gd[:, None, :], 6, axis=1)
    elem_start = add(er, ec)
    # constraints
    cd = s["con_dofs"]
    crow = np.broadcast_to((n_dof + np.arange(n_con))[:, None, None], cd.shape)
    row_start = add(crow, cd)
    col_start = add(cd, crow)
    Hr = -np.ones((n_con, 2, 6, 6), dtype=np.int64)
    Hc = -np.ones((n_con, 2, 6, 6), dtype=np.int64)
    for (j, k) in _HESS_ENTRIES:
        point_rows = (s["con_kind"] != 2)[:, None]
        Hr[:, :, j, k] = np.where(point_rows, cd[:, :, j], -1)
        Hc[:, :, j, k] = np.where(point_rows, cd[:, :, k], -1)
    H_start = add(Hr, Hc)
    ld = s["load_dofs"]
    Lr = -np.ones((ld.shape[0], 6, 6), dtype=np.int64)
    Lc = -np.ones((ld.shape[0], 6, 6), dtype=np.int64)
    for (j, k) in _HESS_ENTRIES:
        Lr[:, j, k] = ld[:, j]
        Lc[:, j, k] = ld[:, k]
    load_start = add(Lr, Lc)

    R = np.concatenate(rows)
    C = np.concatenate(cols)
    valid = (R >= 0) & (C >= 0)
    key = C[valid] * n + R[valid]
    ukey, inv = np.unique(key, return_inverse=True)
    full_map = -np.ones(R.size, dtype=np.int64)
    full_map[valid] = inv
    indices = (ukey % n).astype(np.int64)
    colidx = ukey // n
    indptr = np.zeros(n + 1, dtype=np.int64)
    np.add.at(indptr, colidx + 1, 1)
    indptr = np.cumsum(indptr)

    def seg(start, shape):
        size = int(np.prod(shape))
        return np.ascontiguousarray(full_map[start:start + size].reshape(shape))

    return dict(
        indptr=indptr, indices=indices,
        border_off=np.array(border_off, dtype=np.int64),
        border_map=seg(border_start, (n_border,)),
        elem_map=seg(elem_start, efd.shape + (6,)),
        con_map_row=seg(row_start, cd.shape),
        con_map_col=seg(col_start, cd.shape),
        con_map_H=seg(H_start, (n_con, 2, 6, 6)),
        load_map=seg(load_start, (ld.shape[0], 6, 6)),
    )


def _joint_hint(system: System, joint_name: str) -> str:
    """Where the joint sits relative to the nodes of the beams it connects (for messages)."""
    joint = next((j for j in system.model.joints if j.name == joint_name), None)
    if joint is None or getattr(joint, "at", None) is None:
        return ""
    sides = [getattr(joint, k) for k in ("a", "b", "body") if hasattr(joint, k)]
    parts = []
    for body in sides:
        if isinstance(body, Beam):
            k, dist = body.nearest_node(joint.at)
            parts.append(f"its point is {dist:.3g} from node {k} of beam {body.name!r}")
    return ("; " + "; ".join(parts)) if parts else ""


def _check_initial(system: System) -> None:
    """The initial configuration must satisfy every constraint row (to 1e-9 of model size),
    and the initial velocities the velocity-level rows."""
    if system.n_con == 0:
        return
    phi, phid = system.constraint_violation(system.q0, system.v0, 0.0)
    tol = 1e-9 * system.length_scale
    bad = np.flatnonzero(np.abs(np.real(phi)) > tol)
    if bad.size:
        i = int(bad[np.argmax(np.abs(np.real(phi[bad])))])
        joint = system.con_joint[i]
        raise ModelError(
            f"initial configuration violates constraint {system.con_names[i]!r} of joint "
            f"{joint!r} by {abs(np.real(phi[i])):.6g} (tolerance {tol:.3g} = 1e-9 of the model "
            f"size){_joint_hint(system, joint)}; place joints exactly at beam nodes and at "
            "coinciding points of the bodies they connect"
        )
    vscale = max(float(np.max(np.abs(np.real(system.v0)))), 1e-300)
    badv = np.flatnonzero(np.abs(np.real(phid)) > 1e-9 * vscale * max(1.0, system.length_scale))
    if badv.size:
        i = int(badv[np.argmax(np.abs(np.real(phid[badv])))])
        raise ModelError(
            f"initial velocities violate constraint {system.con_names[i]!r} of joint "
            f"{system.con_joint[i]!r} at velocity level by {abs(np.real(phid[i])):.6g}; give "
            "initial velocities consistent with the joints (a drive whose angle'(0) is not 0 "
            "needs the matching initial angular velocity of the driven body)"
        )


# relative singular-value threshold of the rank test. The scaled Jacobian has O(1) entries built
# from cos/sin of the initial angles, so an exactly dependent set of rows shows singular values
# of round-off size (~1e-16); a mechanism whose constraint Jacobian is conditioned worse than
# 1e10 cannot be solved to the Newton tolerance either, so it is reported as well.
RANK_RTOL = 1e-10


def constraint_rank(system: System, q=None):
    """Numerical rank of the constraint Jacobian and the rows that are linearly dependent.

    Parameters
    ----------
    system : System
    q : (n_dof,), optional
        Configuration (default: the initial one, ``system.q0``).

    Returns
    -------
    rank : int
        Numerical rank of ``J`` (n_con, n_dof).
    dependent : (n_con,) float
        Participation of every row in the null space of ``J^T``: the norm of the row's
        components over an orthonormal basis of that null space, in [0, 1]. Rows with a value
        above ~1e-6 belong to a redundant or conflicting set; 0 for all rows when ``J`` has full
        row rank.
    sigma : (min(n_con, n_used),) float
        Singular values of the scaled Jacobian, largest first.

    Notes
    -----
    ``J`` mixes lengths and angles: translation rows have entries 1 in ``R`` and ``u, v`` and
    lengths (a lever arm) in ``theta``; rotation rows have entries 1 in ``theta`` and ``phi``.
    The test uses ``D_r J D_c`` with ``D_c = 1/L`` on rotational columns and ``D_r = L`` on
    rotation rows (``L = system.length_scale``), so every entry is O(1) whatever the units, and
    counts singular values above ``RANK_RTOL`` times the largest (Golub & Van Loan, *Matrix
    Computations*, sec. 5.4.1, numerical rank by the SVD). Only the real part is used (a
    complex-step perturbation does not change the topology). The left singular vectors of the
    zero singular values span the null space of ``J^T``: the combinations of rows that repeat
    (or, with a different right-hand side, contradict) each other.
    """
    n_con = system.n_con
    if n_con == 0:
        return 0, np.zeros(0), np.zeros(0)
    q = np.real(system.q0 if q is None else np.asarray(q))
    J = np.real(system.constraint_matrix(q.astype(float)))
    L = system.length_scale
    rot = np.zeros(system.n_dof, dtype=bool)
    for info in system.bodies.values():
        rot[info.ref[2]] = True
        if info.node_dofs is not None:
            nd = info.node_dofs[:, 2]
            rot[nd[nd >= 0]] = True
    col = np.where(rot, 1.0 / L, 1.0)
    row = np.where(system.con_kind == 2, L, 1.0)
    Js = row[:, None] * J * col[None, :]
    used = np.flatnonzero(np.any(Js != 0.0, axis=0))
    if used.size == 0:
        return 0, np.ones(n_con), np.zeros(0)
    U, sigma, _ = np.linalg.svd(Js[:, used], full_matrices=True)
    rank = int(np.sum(sigma > RANK_RTOL * sigma[0])) if sigma[0] > 0 else 0
    null = U[:, rank:]
    return rank, np.sqrt(np.sum(null * null, axis=1)), sigma


def _check_rank(system: System) -> None:
    """Redundant or conflicting constraints: a rank-deficient Jacobian at ``q0``.

    A singular constraint Jacobian makes the saddle-point matrix singular (the multipliers of
    the dependent rows are not determined), whether the rows repeat each other (a Fix and a
    Drive on the same rotation, two revolutes at one point, a closed loop that is over-
    constrained in the plane) or the mechanism starts at a dead point.
    """
    rank, dep, _ = constraint_rank(system)
    n_con = system.n_con
    if rank == n_con:
        return
    rows = np.flatnonzero(dep > 1e-6)
    rows = rows[np.argsort(-dep[rows], kind="stable")]
    names = [system.con_names[i] for i in rows]
    joints = list(dict.fromkeys(system.con_joint[i] for i in rows))
    shown = ", ".join(repr(n) for n in names[:12]) + (", ..." if len(names) > 12 else "")
    raise ModelError(
        f"model {system.model.name!r}: redundant or conflicting constraints at the initial "
        f"configuration: the constraint Jacobian has rank {rank} for {n_con} rows, so "
        f"{n_con - rank} row(s) repeat the others. Linearly dependent rows: {shown} (joints "
        f"{', '.join(repr(j) for j in joints)}). Remove the extra constraint (for example a Fix "
        "'r' and a Drive on the same rotation, two joints at the same point, a fix with more "
        "letters than needed), or move the mechanism out of a dead-point (singular) initial "
        "position."
    )
