"""The compiled arrays of a model, declared once: one :class:`Kind` per kind of item.

Every kind of item a model compiles into (bodies, flexible coordinates, elements, constraint
rows, point loads, torques, line-load entries, spring-dampers, pressure entries) owns a table:
one row per item, each column a :class:`Field` with

* a **role**: ``design`` (floating-point data a design variable can change: invariants,
  element matrices, body-frame points, coefficients), ``topology`` (int64: DOF numbers and
  indices, fixed for a model), ``pattern`` (int64: positions of the item's entries in the CSC
  data of the step matrix, ``-1`` where absent; fixed for a model) or ``time`` (the item's
  time-dependent values at every time of a run: constraint targets, forces, torques);
* a **dtype**: ``"float"`` (the system's: float64, or complex128 for a complex-step design) or
  ``"int"`` (int64);
* the **shape of one row**.

The kernels read a kind's arrays as one named tuple (``kind.arrays``, fields in declaration
order, time fields excluded) and its time values as another (``kind.times``); everything else
in the library (the compile stage's builder and pattern, the perturbed designs of a
sensitivity run, the files of :mod:`morphlab.io`, the tests) is generated from these
declarations or checked against them. Adding a kind of item means declaring its table here
(next to its kernel, which imports it) and registering it in :data:`KINDS`.

A kind is ``optional`` when most models have none: a system without such items holds
``None`` for it, and Numba compiles the kernels of the kind only for the models that have it
(a branch ``if arrays.springs is not None`` of an argument typed ``None`` is dropped).
"""

from __future__ import annotations

import sys
from collections import namedtuple
from typing import NamedTuple

import numpy as np

DESIGN, TOPOLOGY, PATTERN, TIME = "design", "topology", "pattern", "time"
ROLES = (DESIGN, TOPOLOGY, PATTERN, TIME)


class Field(NamedTuple):
    """One column of a kind's table: its name, role, dtype (``"float"`` or ``"int"``), the
    shape of one row and what it holds. ``linear``: the kind's residual is linear in the
    ``linear`` fields together (its other fields held), so the derivative along a change of
    them is the residual evaluated with the change in their place
    (``morphlab.kernels.pseudo``)."""

    name: str
    role: str
    dtype: str
    shape: tuple
    doc: str
    linear: bool = False


class Kind:
    """The table of one kind of item: its fields and the named tuples the kernels read.

    Attributes
    ----------
    name : str
        The kind's name, also its field in :data:`Arrays` (``"bodies"``, ``"rows"``, ...).
    fields : tuple of Field
    arrays : type
        Named tuple of the kind's design, topology and pattern arrays (declaration order).
    times : type or None
        Named tuple of its time fields (each with a leading time axis in a run's table).
    optional : bool
        ``None`` in a system whose model has no such item (module docstring).
    timing : {"drive", "scale"} or None
        How the time values follow from an item's constant and its time profile ``f``:
        ``"drive"``, a constraint target and its rates ``(c0 + f, f', f'')`` (the first three
        time fields); ``"scale"``, ``base f(t)`` (the one time field).
    work : bool
        The kind is an external load: the power of its residual share is the work the
        loads do (the energy balance); default False.
    reactions : callable or None
        A constraint kind's reaction directions (:meth:`reactions_of`).
    coordinates : callable or None
        ``coordinates(arrays, n_dof) -> {pattern field: (rows, cols)}``: the step-matrix
        entries of the kind's pattern fields (:meth:`pattern_of`), where ``arrays`` is the
        system's :data:`~morphlab.kernels.system.SystemArrays` (topology filled).
    """

    def __init__(self, name: str, fields, doc: str, optional: bool = False,
                 timing: str | None = None, work: bool = False, module: str | None = None):
        self.name = name
        self.work = work
        self.fields = tuple(fields)
        self.doc = doc
        self.optional = optional
        self.timing = timing
        self.module = module
        self.coordinates = None
        self.reactions = None
        names = [f.name for f in self.fields]
        if len(set(names)) != len(names):
            raise ValueError(f"kind {name!r} declares a field twice: {names}")
        for f in self.fields:
            if f.role not in ROLES or f.dtype not in ("float", "int"):
                raise ValueError(f"kind {name!r}, field {f.name!r}: role {f.role!r} or dtype "
                                 f"{f.dtype!r} unknown")
        if any(f.linear and f.role == DESIGN for f in self.fields) and any(
                f.linear and f.role == TIME for f in self.fields):
            # the linear path of the pseudo-loads holds the linear design fields at zero
            # while it evaluates a change of the time values: a residual linear in each
            # group but not in both together (bilinear) must declare one group only
            raise ValueError(f"kind {name!r}: linear design and linear time fields; the "
                             "residual must be linear in all its linear fields together")
        self.fields_by_name = {f.name: f for f in self.fields}
        title = "".join(p.capitalize() for p in name.split("_"))
        # the named tuples live in the kind's kernel module (``module``; :func:`register`
        # binds them there): Numba's disk cache finds a type again by its module and name
        self.arrays = namedtuple(title, [f.name for f in self.fields if f.role != TIME],
                                 module=module)
        timed = [f.name for f in self.fields if f.role == TIME]
        self.times = namedtuple(title + "Times", timed, module=module) if timed else None

    def reactions_of(self, fn):
        """Register ``fn(A, items, sides, q) -> (n_t, n, 3)`` as the kind's
        :attr:`reactions`: the force (x, y) and moment a unit multiplier of each row ``items``
        applies to its side ``sides`` (0 or 1) at the states ``q`` (n_t, n_dof), with the
        sign of side 1 (a decorator; constraint kinds only)."""
        self.reactions = fn
        return fn

    def pattern_of(self, fn):
        """Register ``fn`` as the kind's :attr:`coordinates` (a decorator)."""
        self.coordinates = fn
        return fn

    def __repr__(self) -> str:
        return f"<Kind {self.name}: {', '.join(f.name for f in self.fields)}>"

    def by_role(self, role: str) -> tuple:
        """The fields of ``role``."""
        return tuple(f for f in self.fields if f.role == role)

    def dtype_of(self, field: Field, float_dtype) -> np.dtype:
        """The numpy dtype of ``field`` in a system of floating dtype ``float_dtype``."""
        return np.dtype(float_dtype) if field.dtype == "float" else np.dtype(np.int64)

    def empty(self, float_dtype, n: int = 0):
        """The kind's arrays (:attr:`arrays`) for ``n`` items, zero-filled (pattern -1)."""
        out = []
        for f in self.fields:
            if f.role == TIME:
                continue
            dt = self.dtype_of(f, float_dtype)
            a = np.zeros((n,) + f.shape, dtype=dt)
            if f.role == PATTERN:
                a -= 1
            out.append(a)
        return self.arrays(*out)


def design(name, shape, doc, linear=False) -> Field:
    return Field(name, DESIGN, "float", tuple(shape), doc, linear)


def topology(name, shape, doc) -> Field:
    return Field(name, TOPOLOGY, "int", tuple(shape), doc)


def pattern(name, shape, doc) -> Field:
    return Field(name, PATTERN, "int", tuple(shape), doc)


def timed(name, shape, doc, linear=False) -> Field:
    return Field(name, TIME, "float", tuple(shape), doc, linear)


#: The kinds, registered by the kernel modules that own them (see their ``KIND``), in the
#: order of :data:`Arrays` (:func:`register`).
KINDS: dict = {}


def register(kind: Kind) -> Kind:
    """Add ``kind`` to :data:`KINDS` (at import of its kernel module, ``kind.module``) and bind
    its named tuples in that module under their names (``Loads``, ``LoadsTimes``, ...), where
    Numba's disk cache and pickle look a type up."""
    if kind.name in KINDS and KINDS[kind.name] is not kind:
        raise ValueError(f"two kinds named {kind.name!r}")
    KINDS[kind.name] = kind
    if kind.module is not None:
        module = sys.modules[kind.module]
        for tuple_type in (kind.arrays, kind.times):
            if tuple_type is not None:
                setattr(module, tuple_type.__name__, tuple_type)
    return kind
