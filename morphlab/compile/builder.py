"""What compiling a model accumulates, and the registry of compile functions per item kind.

:func:`morphlab.compile.compile_model` hands every body, joint and load of a model to the
function registered for its class (:func:`compiles`); that function adds the item's DOFs and
its rows of the kinds' tables (:mod:`morphlab.kernels.schema`) to a :class:`Builder`. A new
kind of body, joint or load is one model class, one compile function registered here and,
where it adds new physics, one kernel module that declares its table.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from ..errors import ModelError
from ..kernels.schema import DESIGN, KINDS, TIME, TOPOLOGY
from ..kernels.system import KIND_NAMES, POS, SystemArrays
from ..model import Body, Ground
from ..model.profiles import Profile
from .system import BodyInfo

_COMPILERS: dict[type, Callable] = {}


def compiles(kind: type) -> Callable:
    """Register the decorated ``f(item, builder)`` as the compile function of ``kind``."""

    def register(fn: Callable) -> Callable:
        _COMPILERS[kind] = fn
        return fn

    return register


def compile_item(item, builder: Builder) -> None:
    """Add ``item`` to ``builder`` with the function registered for its class (or a base)."""
    for cls in type(item).__mro__:
        fn = _COMPILERS.get(cls)
        if fn is not None:
            fn(item, builder)
            return
    known = ", ".join(sorted(k.__name__ for k in _COMPILERS))
    name = getattr(item, "name", "")
    raise ModelError(f"{type(item).__name__} {name!r}: no compile function for this kind of "
                     f"item (known kinds: {known})")


class Table:
    """The rows of one kind's table (:class:`~morphlab.kernels.schema.Kind`), appended one or
    many at a time; ``base``, ``profiles``, ``names``: the items' time constants (a list of
    chunks of rows), time profiles and names."""

    def __init__(self, kind):
        self.kind = kind
        self.columns = {f.name: [] for f in kind.fields if f.role in (DESIGN, TOPOLOGY)}
        self.n = 0
        self.base: list = []
        self.time_shape = next((f.shape for f in kind.fields if f.role == TIME), ())
        self.profiles: list = []
        self.names: list = []

    def add(self, name: str = "", *, base=None, profile: Profile | None = None, count=None,
            **values) -> int:
        """Append rows: one (``count`` None: ``values`` hold one row each) or ``count``
        (``values``, ``base`` and ``name`` stacked: one entry per row; a ``name`` string is
        shared). Every design and topology field must be given; returns the index of the
        first row."""
        if values.keys() != self.columns.keys():
            missing = sorted(set(self.columns) - set(values))
            extra = sorted(set(values) - set(self.columns))
            raise TypeError(f"rows of {self.kind.name!r}: missing {missing}, unknown {extra}")
        first = self.n
        rows = 1 if count is None else int(count)
        for key, value in values.items():
            if count is None:
                self.columns[key].append(np.asarray(value)[None])
            else:
                self.columns[key].append(np.asarray(value))
        timed = self.kind.times is not None
        names = [name] * rows if isinstance(name, str) else list(name)
        self.names += names
        if timed:  # one chunk of rows per call: each row's constants broadcast to the shape
            shape = self.time_shape
            b = np.asarray(base if base is not None else 0.0)
            stacked = count is not None and b.ndim > 0  # one entry per row
            row = b.shape[1:] if stacked else b.shape
            lead = (b.shape[0] if stacked else 1,) + (1,) * (len(shape) - len(row))
            self.base.append(np.broadcast_to(b.reshape(lead + row), (rows,) + shape))
            if profile is not None:
                self.profiles += [(first + r, profile) for r in range(rows)]
        self.n += rows
        return first

    def arrays(self, dtype) -> tuple:
        """The kind's arrays (its named tuple; pattern fields -1 until the pattern is built),
        or None for an optional kind with no rows."""
        if self.n == 0 and self.kind.optional:
            return None
        out = []
        for f in self.kind.fields:
            if f.role == TIME:
                continue
            dt = self.kind.dtype_of(f, dtype)
            if f.role in (DESIGN, TOPOLOGY):
                chunks = self.columns[f.name]
                a = (np.concatenate([np.asarray(c).reshape((-1,) + f.shape) for c in chunks])
                     if chunks else np.zeros((0,) + f.shape))
                out.append(np.ascontiguousarray(a, dtype=dt))
            else:
                out.append(-np.ones((self.n,) + f.shape, dtype=np.int64))
        return self.kind.arrays(*out)

    def time_base(self, dtype) -> np.ndarray:
        """The items' time constants, one row per item."""
        if not self.base:
            return np.zeros((0,) + self.time_shape, dtype=dtype)
        return np.concatenate(self.base).astype(dtype)


class Builder:
    """DOF numbering, the kinds' tables and the user-side tables of a System, filled item by
    item.

    Attributes: ``tables`` (kind name -> :class:`Table`), ``dof_names``, ``q0``, ``v0``;
    per constraint row ``con_names``, ``con_joint``, ``con_sign``, ``con_kind``,
    ``con_item``; ``bodies`` (name -> :class:`BodyInfo`) and ``locate`` (name -> the function
    that finds a material point of the body, set by the body's compile function;
    :meth:`point`).
    """

    def __init__(self, model, dtype: np.dtype):
        self.model = model
        self.dtype = dtype
        self.tables = {name: Table(KINDS[name]) for name in KIND_NAMES}
        self.bodies: dict[str, BodyInfo] = {}
        self.locate: dict[str, Callable] = {}  # body name -> f(at) -> (dofs, u0, angle0)
        self.units: dict = {}  # beam name -> its element units (compile/record.py keeps them)
        self._points: dict = {}  # (body name, at) -> what locate gave (read only)
        self.dof_names: list[str] = []
        self.q0: list = []
        self.v0: list = []
        self.con_names: list[str] = []
        self.con_joint: list[str] = []
        self.con_sign: list[float] = []
        self.con_side: list[int] = []
        self.con_kind: list[int] = []
        self.con_item: list[int] = []

    def table(self, kind: str) -> Table:
        return self.tables[kind]

    # ---- DOFs and bodies
    def add_dofs(self, names: list[str], q0, v0) -> np.ndarray:
        """New DOFs with their initial values; returns their global numbers."""
        first = len(self.dof_names)
        self.dof_names += names
        self.q0 += list(q0)
        self.v0 += list(v0)
        return np.arange(first, first + len(names), dtype=np.int64)

    def add_body(self, name: str, q0, v0, scal, damping, n_flex: int = 0) -> tuple:
        """A body frame (reference coordinates ``x, y, theta`` at ``q0`` (3,) moving with
        ``v0``) with its invariants ``scal = (m, I_u_x, I_u_y, I_00)``, damping and the
        number of flexible coordinates it will own (added next with :meth:`add_flex`);
        returns its row and the DOFs of its frame."""
        ref = self.add_dofs([f"{name}.x", f"{name}.y", f"{name}.theta"], q0, v0)
        f0 = self.tables["flex"].n
        index = self.tables["bodies"].add(name, scal=scal, damp=damping, ref=ref,
                                          flex=(f0, f0 + n_flex))
        return index, ref

    @property
    def bodies_count(self) -> int:
        """Number of (kernel) bodies added so far."""
        return self.tables["bodies"].n

    # ---- points and constraint rows
    def point(self, body: Body, at):
        """``(dofs (6,), u0 (2,), angle0)`` of the material point of ``body`` at the global
        point ``at``: the DOFs ``R_x, R_y, theta, u, v, phi`` (-1 where absent; all -1 for the
        ground), its position in the body frame and the frame's initial angle."""
        if isinstance(body, Ground):
            return -np.ones(6, dtype=np.int64), np.zeros(2, dtype=self.dtype), 0.0
        # a joint's point is looked up for its rows and again for its reaction sign
        key = (body.name, tuple(np.asarray(at).ravel().tolist()))
        hit = self._points.get(key)
        if hit is None:
            hit = self._points[key] = self.locate[body.name](at)
        return hit

    def add_row(self, kind: str, row_kind, joint, label: str, pa, pb, c0,
                profile: Profile | None = None, coef=0.0) -> int:
        """A constraint row ``g(q) - c(t) = 0`` of the table ``kind`` (``"rows"`` with
        ``row_kind`` one of ``kernels.joints.ROW_*``, or ``"slides"``) between the points
        ``pa`` and ``pb`` (:meth:`point`), ``c = c0`` (+ ``profile(t)`` for a driven row);
        ``coef``: ``u0[1, 2]`` (a gear's ratio, a slide's normal angle). Returns the row's
        constraint number."""
        u0 = np.zeros((2, 3), dtype=self.dtype)
        u0[0, :2], u0[1, :2], u0[1, 2] = pa[1], pb[1], coef
        con = len(self.con_names)
        dofs = np.empty((2, 6), dtype=np.int64)
        dofs[0], dofs[1] = pa[0], pb[0]
        values = dict(u0=u0, con=con, dofs=dofs)
        if kind == "rows":
            values["kind"] = row_kind
        item = self.tables[kind].add(f"{joint.name}.{label}", base=c0, profile=profile,
                                     **values)
        self.con_names.append(f"{joint.name}.{label}")
        self.con_joint.append(joint.name)
        sign, side = self._reaction_sign(joint, pa)
        self.con_sign.append(sign)
        self.con_side.append(side)
        self.con_kind.append(POS[kind])
        self.con_item.append(item)
        return con

    def _reaction_sign(self, joint, pa) -> tuple[float, int]:
        """The sign with which a row's multiplier pushes the body the joint holds
        (``morphlab.results.reactions``): ``-1`` if that body is side 0 (``pa``), ``+1`` if side
        1; negated when the held body ``b`` is the ground (the action on ``a`` is measured);
        and the side of the body whose reaction is measured (-1: none)."""
        held, flip = getattr(joint, "b", None), 1.0
        if held is None:
            held = getattr(joint, "body", None)
        if isinstance(held, Ground):
            held, flip = joint.a, -1.0
        at = getattr(joint, "at", None)
        if at is None:
            at = getattr(held, "position", None)
        if held is None or at is None:
            return float("nan"), -1  # a kind of joint without a held body: no reaction
        side = 0 if np.array_equal(pa[0], self.point(held, at)[0]) else 1
        return flip * (-1.0 if side == 0 else 1.0), side

    # ---- the result
    def arrays(self, gravity) -> SystemArrays:
        """The kinds' arrays (pattern fields still -1)."""
        dt = self.dtype
        return SystemArrays(np.asarray(gravity, dtype=dt),
                            *(self.tables[k].arrays(dt) for k in KIND_NAMES))
