"""The compiled system: one table of arrays per kind of item for the kernels, index tables for
the user side, and the time-dependent data (profiles evaluated at the times of a run)."""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import cached_property

import numpy as np
import scipy.sparse as sp

from ..errors import ModelError, MorphlabError, ProfileError
from ..kernels import assemble as kassemble
from ..kernels import joints as kjoints
from ..kernels import slides as kslides
from ..kernels.ffrf import scratch
from ..kernels.schema import KINDS
from ..kernels.system import KIND_NAMES, TIMED_NAMES, SystemArrays, Times, all_parts
from ..kernels.types import Level, Weights
from ..model import Model
from .design import layout


@dataclass
class BodyInfo:
    """Where a body lives in the system arrays.

    Attributes
    ----------
    index : int
        Row of its (first) frame in the ``bodies`` table.
    ref : (3,) int64
        Global DOFs of ``R_x, R_y, theta``.
    angle0 : float
        Initial angle of the body frame.
    node_dofs : (n_node, 3) int64 or None
        Beams: global DOF of ``u, v, phi`` of each node in the body frame (``-1`` removed).
    X : (n_node, 2) or None
        Beams: node positions in the body frame.
    elements : slice
        Beams: rows of the ``elements`` table.
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
    """A compiled model.

    Attributes
    ----------
    model : Model
    dtype : numpy dtype
        Of every floating-point array (complex128 for a complex-step design).
    n_dof, n_con : int
        Generalized coordinates and constraint rows; the step's unknowns number ``n``.
    q0, v0 : (n_dof,)
        Initial state.
    arrays : SystemArrays
        One table per kind of item (:mod:`morphlab.kernels.schema`), what the kernels read.
    design : (n_design,)
        The design data of every kind, flat: the design fields of ``arrays`` are views into it.
    time_base : dict
        Per kind with time values, the constant of each item's time values (its first time
        field's shape): a constraint's target, a load's vector, a torque's magnitude.
    time_profiles : dict
        Per kind with time values, ``[(item, profile), ...]``: the time profiles
        (:attr:`~morphlab.kernels.schema.Kind.timing` says how they combine with the base).
    names : dict
        Per kind, the name of each item (for messages and accessors).
    indices, indptr : int64 arrays
        The CSC pattern of the step matrix.
    bodies : dict
        Body name -> :class:`BodyInfo`.
    dof_names : list of str
        The name of each coordinate.
    con_names, con_joint : list of str
        Per constraint row (multiplier): ``"<joint>.<label>"`` and its joint's name.
    con_kind, con_item : (n_con,) int64
        The kind (position in :data:`~morphlab.kernels.system.KIND_NAMES`) and the item of
        each constraint row.
    con_sign, con_side : (n_con,)
        The sign with which each row's multiplier pushes the body its joint holds, and the
        side (0 or 1) of the row that body is (``morphlab.results.reactions``).
    length_scale : float
        Size of the model (Newton's test, the checks).
    """

    model: Model
    dtype: np.dtype
    n_dof: int
    n_con: int
    q0: np.ndarray
    v0: np.ndarray
    arrays: SystemArrays
    design: np.ndarray
    time_base: dict
    time_profiles: dict
    names: dict
    indices: np.ndarray
    indptr: np.ndarray
    bodies: dict = field(default_factory=dict)
    dof_names: list = field(default_factory=list)
    con_names: list = field(default_factory=list)
    con_joint: list = field(default_factory=list)
    con_kind: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))
    con_item: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))
    con_sign: np.ndarray = field(default_factory=lambda: np.zeros(0))
    con_side: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))
    length_scale: float = 1.0
    #: What each beam contributed, for the compiles of other designs of this model
    #: (:mod:`morphlab.compile.record`): beam name -> :class:`~morphlab.compile.record.Entry`.
    record: dict = field(default_factory=dict, repr=False)

    @property
    def n(self) -> int:
        """Size of the saddle-point system, ``n_dof + n_con``."""
        return self.n_dof + self.n_con

    @property
    def nnz(self) -> int:
        return int(self.indices.shape[0])

    @property
    def unknown_names(self) -> list[str]:
        """Name of each equation / unknown of a step: the DOFs, then ``"constraint <row>"``."""
        return self.dof_names + [f"constraint {c}" for c in self.con_names]

    @cached_property
    def slots(self) -> list:
        """Where each design field lies in :attr:`design` (:func:`~morphlab.compile.design.
        layout` of :attr:`arrays`, formed once)."""
        return layout(self.arrays)

    def table(self, kind: str):
        """The arrays of ``kind`` (None if the model has none)."""
        return getattr(self.arrays, kind)

    def count(self, kind: str) -> int:
        """Number of items of ``kind``."""
        t = self.table(kind)
        return 0 if t is None else int(t[0].shape[0])

    def owner(self, kind: str, i: int) -> str:
        """How messages name the model item behind row ``i`` of the table ``kind``: the item's
        kind and name (``"force 'F'"``, ``"drive 'motor'"``: a constraint row by its joint),
        the row's kind and name when no item has that name."""
        name = self.names.get(kind, [""] * (i + 1))[i]
        table = self.table(kind)
        if table is not None and hasattr(table, "con"):  # a constraint row: its joint
            name = self.con_joint[int(table.con[i])]
        from .compile import items_of  # here: compile imports this module

        for item in items_of(self.model):
            if getattr(item, "name", None) == name:
                return getattr(item, "owner", f"{type(item).__name__} {name!r}")
        return f"{kind} item {name!r}" if name else f"{kind} item {i}"

    def body(self, name: str) -> BodyInfo:
        """Index information of the body called ``name``."""
        try:
            return self.bodies[name]
        except KeyError:
            known = ", ".join(repr(k) for k in self.bodies)
            raise ModelError(f"no body {name!r} in model (bodies: {known})") from None

    def time_arrays(self, t: float) -> Times:
        """Time values at ``t`` (table 0, time index 0)."""
        return time_table(self, np.array([float(t)]))

    def constraint_violation(self, q, v, t):
        """``(phi, phid)``: position- and velocity-level violation of every row at time t."""
        dt = np.result_type(self.dtype, q.dtype)
        phi = np.zeros(self.n_con, dtype=dt)
        phid = np.zeros(self.n_con, dtype=dt)
        A = self.arrays_as(dt)
        q, v = np.ascontiguousarray(q, dtype=dt), np.ascontiguousarray(v, dtype=dt)
        T = time_table(self, np.array([float(t)]), dt)
        kjoints.values(A.rows, q, v, T.rows, 0, phi, phid)
        kslides.values(A.slides, q, v, T.slides, 0, phi, phid)
        return phi, phid

    def arrays_as(self, dtype) -> SystemArrays:
        """:attr:`arrays` with the design data in ``dtype`` (the arrays themselves when the
        dtypes agree)."""
        dt = np.dtype(dtype)
        if dt == self.dtype:
            return self.arrays
        return SystemArrays(self.arrays.gravity.astype(dt), *(
            None if t is None else type(t)(*(
                a.astype(dt) if a.dtype.kind in "fc" else a for a in t))
            for t in self.arrays[1:]))

    def constraint_matrix(self, q, sparse: bool = False):
        """Constraint Jacobian (n_con, n_dof) at ``q``, dense (or a SciPy CSR matrix when
        ``sparse``): the constraint rows of the step matrix with only their ``J a`` term
        weighted."""
        dt = np.result_type(self.dtype, q.dtype)
        zero = np.zeros(self.n_dof, dtype=dt)
        x = Level(np.ascontiguousarray(q, dtype=dt), zero, zero, np.zeros(self.n_con, dt))
        data = np.zeros((1, self.nnz), dtype=dt)
        w = Weights(0.0, 1.0, 0.0, 1.0, 0.0, 1.0, 0.0, 0.0)
        kassemble.matrix(self.arrays_as(dt), x, w, time_table(self, np.zeros(1), dt), 0, 0,
                         np.array([[1.0, 0.0, 0.0]]), data, scratch(self.count("flex"), zero))
        A = sp.csc_matrix((data[0], self.indices, self.indptr), shape=(self.n, self.n))
        J = A[self.n_dof:, :self.n_dof]
        return J.tocsr() if sparse else J.toarray()

    def parts(self):
        """:class:`~morphlab.kernels.system.Parts` covering every item."""
        return all_parts(self.arrays)


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



def real_parts(tree):
    """``tree`` (an array, or tuples and named tuples of them; None and other leaves kept)
    with every complex array replaced by a C-ordered copy of its real part: a complex system's
    kernel arrays or time values as the real system's of the same types (a complex run's real
    step matrix, :class:`~morphlab.solve.newton.NewtonSolver`)."""
    if isinstance(tree, np.ndarray):
        return np.ascontiguousarray(tree.real) if tree.dtype.kind == "c" else tree
    if isinstance(tree, tuple):
        parts = [real_parts(t) for t in tree]
        return type(tree)(*parts) if hasattr(tree, "_fields") else tuple(parts)
    return tree


def time_table(system: System, times: np.ndarray, dtype=None, cache: dict | None = None
               ) -> Times:
    """Time values at every time of ``times`` (:data:`~morphlab.kernels.system.Times`, each
    array (1, n_t, n, ...): one table): profiles are evaluated once per run (vectorized where
    the profile allows), not inside the Newton loop. ``cache`` shares profile tables between
    systems with equal profiles (the perturbed designs of a sensitivity run)."""
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
    out = []
    for name in TIMED_NAMES:
        kind = KINDS[name]
        if system.table(name) is None:
            out.append(None)
            continue
        base = np.asarray(system.time_base[name]).astype(dt)
        fields = [f for f in kind.fields if f.role == "time"]
        if kind.timing == "drive":
            c = np.repeat(base[None], n_t, axis=0)
            cd, cdd = np.zeros_like(c), np.zeros_like(c)
            for i, prof in system.time_profiles.get(name, ()):
                f, f1, f2 = tab(prof, system.owner(name, i))
                c[:, i] += f
                cd[:, i] = f1
                cdd[:, i] = f2
            arrays = [c, cd, cdd]
        else:
            x = np.repeat(base[None], n_t, axis=0)
            for i, prof in system.time_profiles.get(name, ()):
                f = np.asarray(tab(prof, system.owner(name, i))[0])
                x[:, i] *= f.reshape((n_t,) + (1,) * (x.ndim - 2))
            arrays = [x]
        out.append(kind.times(*(np.ascontiguousarray(a[None]) for a in arrays[:len(fields)])))
    return Times(*out)


def kind_of_con(system: System, i: int) -> str:
    """The name of the kind that holds constraint row ``i``."""
    return KIND_NAMES[int(system.con_kind[i])]
