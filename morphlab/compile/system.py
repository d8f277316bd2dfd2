"""The compiled system: flat arrays for the kernels, index tables for the user side, and the
time-dependent data (profiles evaluated at the times of a run)."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np
import scipy.sparse as sp

from ..errors import ModelError, MorphlabError, ProfileError
from ..kernels import assemble as kassemble
from ..kernels import joints as kjoints
from ..kernels.system import DESIGN_FIELDS, SystemArrays
from ..model import Model


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
    node_ref : (n_node, 3) int64 or None
        Beams: reference DOFs ``R_x, R_y, theta`` of the frame that holds each node (a node
        shared by two frames belongs to the one that starts there). ``ref``, ``angle0`` are
        those of the first frame.
    node_angle0 : (n_node,) or None
        Beams: initial angle of the frame that holds each node.
    frame_ref : (n_frames, 3) int64 or None
        Beams: reference DOFs of each frame.
    frame_offsets : (n_frames + 1,) int64 or None
        Beams: first element of each frame, then the number of elements.

    Beams saved before several frames existed have ``None`` in the last four (one frame).
    """

    name: str
    index: int
    ref: np.ndarray
    angle0: object
    kind: str
    node_dofs: np.ndarray | None = None
    X: np.ndarray | None = None
    elements: slice | None = None
    node_ref: np.ndarray | None = None
    node_angle0: np.ndarray | None = None
    frame_ref: np.ndarray | None = None
    frame_offsets: np.ndarray | None = None

    @property
    def n_frames(self) -> int:
        """Number of floating frames (1 for a rigid body)."""
        return 1 if self.frame_ref is None else int(self.frame_ref.shape[0])


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
    # force elements (kernels.forces, kernels.loads); ``None`` in a file written before them
    spring_kind: np.ndarray | None = None
    spring_dofs: np.ndarray | None = None
    spring_u0: np.ndarray | None = None
    spring_par: np.ndarray | None = None
    spring_map: np.ndarray | None = None
    line_off: np.ndarray | None = None
    line_elem: np.ndarray | None = None
    line_u0: np.ndarray | None = None
    line_N: np.ndarray | None = None
    line_map: np.ndarray | None = None
    spring_names: list = field(default_factory=list)
    bodies: dict = field(default_factory=dict)
    load_names: list = field(default_factory=list)
    torque_names: list = field(default_factory=list)
    dof_names: list = field(default_factory=list)
    con_names: list = field(default_factory=list)
    con_joint: list = field(default_factory=list)
    #: (n_con,) sign with which each row's multiplier pushes the body its joint holds
    #: (``morphlab.results.reactions``)
    con_sign: np.ndarray = field(default_factory=lambda: np.zeros(0))
    length_scale: float = 1.0

    def __post_init__(self):
        """Empty force-element tables where none were given (a system saved before them)."""
        n_load = self.load_dofs.shape[0]
        empty = {"spring_kind": ((0,), np.int64), "spring_dofs": ((0, 2, 6), np.int64),
                 "spring_u0": ((0, 2, 2), self.dtype), "spring_par": ((0, 4), self.dtype),
                 "spring_map": ((0, 2, 2, 6, 6), np.int64),
                 "line_off": ((n_load + 1,), np.int64), "line_elem": ((0,), np.int64),
                 "line_u0": ((0, 3), self.dtype), "line_N": ((0, 2, 6), self.dtype),
                 "line_map": ((0, 7, 7), np.int64)}
        for name, (shape, dtype) in empty.items():
            if getattr(self, name) is None:
                setattr(self, name, np.zeros(shape, dtype=dtype))

    @property
    def n(self) -> int:
        """Size of the saddle-point system, ``n_dof + n_con``."""
        return self.n_dof + self.n_con

    @property
    def unknown_names(self) -> list[str]:
        """Name of each equation / unknown of a step: the DOFs, then ``"constraint <row>"``."""
        return self.dof_names + [f"constraint {c}" for c in self.con_names]

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

    def time_arrays(self, t: float) -> TimeArrays:
        """Time-dependent data at ``t`` (:class:`TimeArrays`)."""
        return table_at(time_table(self, np.array([float(t)])), 0)

    def constraint_violation(self, q, v, t):
        """``(phi, phid)``: position- and velocity-level violation of every row at time t."""
        c, cd, _, _, _ = self.time_arrays(t)
        dt = np.result_type(self.dtype, q.dtype)
        phi = np.zeros(self.n_con, dtype=dt)
        phid = np.zeros(self.n_con, dtype=dt)
        kjoints.constraint_values(extra_items(self), q.astype(dt), v.astype(dt),
                                  c.astype(dt), cd.astype(dt), self.con_kind, self.con_dofs,
                                  self.con_u0.astype(dt), phi, phid)
        return phi, phid

    def constraint_matrix(self, q, sparse: bool = False):
        """Constraint Jacobian (n_con, n_dof) at ``q``, dense (or a SciPy CSR matrix when
        ``sparse``): the constraint rows of the step matrix with only their ``J a`` term
        weighted (the kernel the solver compiles anyway)."""
        dt = np.result_type(self.dtype, q.dtype)
        n = self.n
        data = np.zeros(self.nnz, dtype=dt)
        zero = np.zeros(self.n_dof, dtype=dt)
        kassemble.step_matrix(kernel_arrays(self, dt), np.zeros(n, dtype=dt), q.astype(dt), zero,
                              0.0, 0.0, 1.0, np.array([0.0, 1.0, 0.0, 1.0, 0.0]), 0.0, 0.0,
                              np.zeros((self.load_dofs.shape[0], 2), dtype=dt), data)
        A = sp.csc_matrix((data, self.indices, self.indptr), shape=(n, n))
        J = A[self.n_dof:, :self.n_dof]
        return J.tocsr() if sparse else J.toarray()


def kernel_arrays(system: System, dtype=None) -> SystemArrays:
    """The arrays of ``system`` the kernels read (:class:`~morphlab.kernels.system.SystemArrays`),
    the design data cast to ``dtype`` (default: the system's)."""
    dt = np.dtype(dtype) if dtype is not None else system.dtype
    design = set(DESIGN_FIELDS)
    arrays = {name: np.ascontiguousarray(getattr(system, name),
                                         dtype=dt if name in design else None)
              for name in SystemArrays._fields if name != "extra_items"}
    return SystemArrays(**arrays, extra_items=extra_items(system))


def extra_items(system: System) -> bool | None:
    """The switch ``extra_items`` of the kernels (``morphlab.kernels.system``): True if the
    system has slide rows, point forces, spring-dampers or line loads, else None."""
    points = (system.load_dofs[:, 0] >= 0) | (system.load_dofs[:, 2] >= 0)  # line loads: -1
    extra = (np.any(system.con_kind == kjoints.ROW_SLIDE) or np.any(points)
             or system.spring_kind.shape[0] > 0 or system.line_elem.shape[0] > 0)
    return True if extra else None


class TimeArrays(NamedTuple):
    """Time-dependent data at one time: constraint targets ``c`` and their first and second
    time derivatives ``cd``, ``cdd`` (n_con,), point forces ``F`` (n_load, 2), torques ``T``
    (n_torque,)."""

    c: np.ndarray
    cd: np.ndarray
    cdd: np.ndarray
    F: np.ndarray
    T: np.ndarray


class TimeTable(NamedTuple):
    """:class:`TimeArrays` at every time of a run, each with a leading axis n_t."""

    C: np.ndarray
    CD: np.ndarray
    CDD: np.ndarray
    F: np.ndarray
    T: np.ndarray


def time_table(system: System, times: np.ndarray, dtype=None, cache: dict | None = None
               ) -> TimeTable:
    """Time-dependent data at every time of ``times`` (:class:`TimeTable`): profiles are
    evaluated once per run (vectorized where the profile allows), not inside the Newton loop.
    ``cache`` shares profile tables between systems with equal profiles (the perturbed designs
    of a sensitivity run)."""
    dt = system.dtype if dtype is None else np.dtype(dtype)
    times = np.asarray(times, dtype=float)
    cache = {} if cache is None else cache

    def tab(prof, owner):
        try:
            key = (prof, times.size, float(times[0]), float(times[-1]))
            hit = cache.get(key)
        except TypeError:  # unhashable profile
            key, hit = None, None
        if hit is None:
            hit = _profile_table(prof, times, owner)
            if key is not None:
                cache[key] = hit
        return hit

    n_t = times.size
    C = np.repeat(system.con_c0[None, :].astype(dt), n_t, axis=0)
    CD = np.zeros_like(C)
    CDD = np.zeros_like(C)
    for row, prof in system.con_drive:
        f, f1, f2 = tab(prof, f"drive {system.con_joint[row]!r}")
        C[:, row] += f
        CD[:, row] = f1
        CDD[:, row] = f2
    F = np.repeat(system.load_F0[None].astype(dt), n_t, axis=0)
    for i, prof in enumerate(system.load_prof):
        F[:, i, :] *= tab(prof, f"force {system.load_names[i]!r}")[0][:, None]
    T = np.repeat(system.torque_T0[None].astype(dt), n_t, axis=0)
    for i, prof in enumerate(system.torque_prof):
        T[:, i] *= tab(prof, f"torque {system.torque_names[i]!r}")[0]
    return TimeTable(*(np.ascontiguousarray(x) for x in (C, CD, CDD, F, T)))


def _profile_table(prof, times: np.ndarray, owner: str) -> tuple:
    """``prof.table(times)``, or a :class:`ProfileError` at the first time where the profile
    (a user's function perhaps) raises or gives a NaN or Inf, naming ``owner``."""
    try:
        out = prof.table(times)
        bad = ~np.all([np.isfinite(x) for x in np.broadcast_arrays(*out)], axis=0)
        cause = None
    except MorphlabError:  # the library's own (a profile not saved in a file)
        raise
    except Exception as exc:  # a user's function: find the first time it fails at
        cause = exc
        bad = np.zeros(times.size, dtype=bool)
        for k, t in enumerate(times):
            try:
                vals = (prof.value(float(t)), prof.d1(float(t)), prof.d2(float(t)))
            except Exception as exc_k:
                cause, bad[k] = exc_k, True
                break
            if not np.all(np.isfinite(vals)):
                bad[k] = True
                break
    if not bad.any():
        if cause is not None:  # a table that fails where every time alone does not
            raise ProfileError(f"the profile of {owner} failed: {type(cause).__name__}: "
                               f"{cause}", time=float(times[0]), step=0) from cause
        return out
    k = int(np.argmax(bad))
    what = (f"raised {type(cause).__name__}: {cause}" if cause is not None
            else "gave a NaN or Inf (value or derivative)")
    raise ProfileError(f"the profile of {owner} {what} at t={times[k]:.6g}", time=float(times[k]),
                       step=k) from cause


def table_at(table: TimeTable, k: int) -> TimeArrays:
    """The time arrays of entry ``k`` of a :func:`time_table`."""
    return TimeArrays(*(x[k] for x in table))
