"""Model -> System: DOF numbering, invariants, constraint rows and the fixed CSC pattern.

Compiling is done once per model (and once per perturbed model of a finite-difference or
complex-step comparison). The :class:`System` holds flat NumPy arrays only, all of one
floating dtype (float64, or complex128 when a design variable carries a complex-step
perturbation), plus the index tables that map names to DOFs. Nothing here is in an inner loop:
this is model-building code, kept in NumPy.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from typing import NamedTuple

import numpy as np

from ..errors import ModelError
from ..jit.threads import one_blas_thread
from ..kernels.schema import KINDS, PATTERN, TOPOLOGY
from ..kernels.system import KIND_NAMES, TIMED_NAMES
from ..model import Beam, Model
from ..model.items import COLLECTIONS
from ..model.profiles import Profile
from . import bodies, forces, joints, loads  # noqa: F401 - they register the compile functions
from .bodies import section_blocks, section_rows
from .builder import Builder, compile_item
from .checks import check_initial, check_rank
from .design import flatten, views
from .initial import initial_velocities, needs_initial_velocities
from .pattern import newton_pattern
from .record import SECTION, changed_inputs, counts, entry, inputs, replay, same_item, same_value
from .system import System


def _is_complex(value) -> bool:
    """Does ``value`` (a number, an array, or a profile's parameters) hold a complex number?"""
    if isinstance(value, Profile):
        return any(_is_complex(getattr(value, k))
                   for k in getattr(value, "__dataclass_fields__", {}))
    if isinstance(value, (int, float, complex, np.ndarray, np.number)):
        return isinstance(value, complex) or np.iscomplexobj(value)
    return False


def items_of(model: Model) -> list:
    """Every body, joint, load and force element of ``model``, in the order they compile."""
    return [*model.bodies, *model.joints, *model.forces, *model.line_loads, *model.torques,
            *model.springs, *model.pressures]


def _dtype_of(model: Model):
    """complex128 if any number of the model is complex (a complex-step perturbation of a
    design variable), else float64. Every attribute of every item is looked at, so a new kind
    of item needs nothing here."""
    if _is_complex(model.gravity) or any(_is_complex(v) for item in items_of(model)
                                         for v in vars(item).values()):
        return np.dtype(np.complex128)
    return np.dtype(np.float64)


def _length_scale(model: Model) -> float:
    """The model's size: the extent of its bodies and joint points (1 when they share one
    point: a unit-agnostic "no scale")."""
    extent = np.concatenate([np.real(np.asarray(b.nodes)) if isinstance(b, Beam)
                             else np.real(np.asarray(b.position))[None] for b in model.bodies])
    for j in model.joints:
        if getattr(j, "at", None) is not None:
            extent = np.vstack([extent, np.real(np.asarray(j.at))[None]])
    size = float(np.ptp(extent, axis=0).max())
    return size if size > 0 else 1.0


def _same_topology(arrays, n_dof, n_con, like: System) -> bool:
    """Do ``arrays`` have the DOFs, items and topology of ``like``?"""
    if (n_dof, n_con) != (like.n_dof, like.n_con):
        return False
    for name in KIND_NAMES:
        a, b = getattr(arrays, name), like.table(name)
        if (a is None) != (b is None):
            return False
        if a is not None and not all(np.array_equal(getattr(a, f.name), getattr(b, f.name))
                                     for f in KINDS[name].by_role(TOPOLOGY)):
            return False
    return True


class SectionDelta(NamedTuple):
    """A design that differs from a compiled system in the sections of beams alone
    (:func:`section_delta`): its ``model``, ``dtype``, the ``positions`` of the flat design
    data the changed frames' rows hold and their new ``values`` there (positions the new
    section leaves equal included), and the beams' records in the new design."""

    model: Model
    dtype: np.dtype
    positions: np.ndarray
    values: np.ndarray
    record: dict


def section_delta(model: Model, like: System, dt) -> SectionDelta | None:
    """``model`` as a change of ``like`` where it differs from ``like.model`` in the sections
    of beams alone (:data:`~morphlab.compile.record.SECTION`; the thickness variables of a
    sensitivity run): the rows of the frames whose elements' section changed, computed again
    (:func:`~morphlab.compile.bodies.section_blocks`), everything else ``like``'s. None where
    that does not hold (another item or a setting of the model changed, a beam's nodes or
    frames, ``like`` complex and ``dt`` real, or a moving start: initial velocities computed
    from the drives are of least kinetic energy, which the beams' mass enters).

    A section enters the element data only; the DOFs, rows, pattern, time data and checks
    (which read the geometry) are ``like``'s, so :func:`section_system` of the delta equals a
    compile from scratch bit for bit (``tests/test_compile_record.py``)."""
    if not like.record or (like.dtype.kind == "c" and dt.kind != "c") or np.any(like.v0 != 0):
        return None
    # the model's own settings (the gravity; any a later version adds), its lists aside
    mine, theirs = vars(model), vars(like.model)
    if mine.keys() != theirs.keys() or not all(
            same_value(v, theirs[k]) for k, v in mine.items() if k not in COLLECTIONS):
        return None
    new, old = items_of(model), items_of(like.model)
    if len(new) != len(old):
        return None
    changed = []
    for a, b in zip(new, old):
        if isinstance(a, Beam) and type(a) is type(b) and a.name == b.name:
            rec = like.record.get(a.name)
            diff = None if rec is None else changed_inputs(rec.inputs, inputs(a))
            if diff is None or not diff <= SECTION:
                return None
            if diff:
                changed.append((a, rec))
        elif not same_item(a, b):
            return None
    slots = {(s.kind, s.field): s for s in like.slots}
    record = dict(like.record)
    positions, values = [np.zeros(0, np.int64)], [np.zeros(0, dt)]
    for beam, rec in changed:
        starts = dict(zip(KIND_NAMES, rec.before[1]))
        for table, name, row, block in section_blocks(beam, dt, like, starts):
            s = slots[(table, name)]
            positions.append(s.start + row * s.size + np.arange(block.size))
            values.append(block.ravel())
        record[beam.name] = rec._replace(inputs=inputs(beam))
    return SectionDelta(model, dt, np.concatenate(positions),
                        np.concatenate(values).astype(dt, copy=False), record)


def section_system(like: System, delta: SectionDelta) -> System:
    """The system of the design ``delta`` (:func:`section_delta`): a copy of ``like`` with the
    delta's design data, everything else shared."""
    dt = delta.dtype
    design = like.design.astype(dt)
    design[delta.positions] = delta.values
    return dataclasses.replace(
        like, model=delta.model, dtype=dt, q0=like.q0.astype(dt), v0=like.v0.astype(dt),
        arrays=views(like.arrays_as(dt), design), design=design,
        time_base={k: v.astype(dt) for k, v in like.time_base.items()}, record=delta.record)


@one_blas_thread()
def compile_model(model: Model, dtype=None, *, like: System | None = None,
                  on_built: Callable[[System], None] | None = None) -> System:
    """Compile ``model`` into a :class:`System`.

    Parameters
    ----------
    model : Model
    dtype : numpy dtype, optional
        Force float64 or complex128; by default complex128 exactly when the model holds complex
        numbers (a complex-step perturbation).
    like : System, optional
        A system of the same topology (a perturbed design): its step-matrix pattern is reused
        when the DOF, item and topology tables are equal (they are compared, and the pattern is
        built afresh when they are not), and its beams whose inputs are unchanged are copied
        instead of compiled (:mod:`morphlab.compile.record`).
    on_built : callable, optional
        Called with the system as soon as its arrays are built, before the checks below run
        the first kernels.

    Raises
    ------
    ModelError
        Empty model; initial configuration violating the constraints beyond ``1e-9`` of the
        model size, or initial velocities violating them (when the model gives none, they are
        computed from the drives, :mod:`morphlab.compile.initial`); redundant or conflicting
        constraints (rank-deficient constraint Jacobian at the initial configuration, see
        :func:`~morphlab.compile.checks.constraint_rank`).
    """
    if not isinstance(model, Model):
        raise ModelError(f"compile_model expects a Model, got {type(model).__name__}")
    if not model.bodies:
        raise ModelError(f"model {model.name!r} has no bodies")
    dt = np.dtype(dtype) if dtype is not None else _dtype_of(model)
    if like is None:
        return _compile(model, dt, None, on_built)
    out = compile_like(model, like, dt, on_built)
    if isinstance(out, SectionDelta):
        out = section_system(like, out)
        if on_built is not None:
            on_built(out)
    return out


def compile_like(model: Model, like: System, dt,
                 on_built: Callable[[System], None] | None = None) -> SectionDelta | System:
    """``model``, a design of the model ``like`` was compiled from, in ``dt``: its
    :class:`SectionDelta` where it differs in beams' sections alone (no system formed:
    :func:`section_system` forms it), else its system compiled like ``like``
    (:func:`compile_model`'s ``like``)."""
    delta = section_delta(model, like, dt)
    return delta if delta is not None else _compile(model, dt, like, on_built)


def _compile(model: Model, dt, like: System | None, on_built) -> System:
    """``model`` compiled in ``dt`` item by item (:func:`compile_model`), with ``like``'s
    unchanged beams copied and its pattern reused where the topology is equal."""
    b = Builder(model, dt)
    record = {}
    for item in items_of(model):
        if isinstance(item, Beam):  # a beam like's record holds (or its section) is copied
            copied = replay(item, b, like, section_rows) if like is not None else None
            if copied is not None:
                record[item.name] = copied
                continue
            before = counts(b)
            compile_item(item, b)
            record[item.name] = entry(item, b, before)
        else:
            compile_item(item, b)
    arrays = b.arrays(model.gravity)
    n_dof, n_con = len(b.dof_names), len(b.con_names)
    same = like is not None and _same_topology(arrays, n_dof, n_con, like)
    if same:  # the pattern of ``like``: its pattern fields, indices and indptr
        arrays = arrays._replace(**{
            name: getattr(arrays, name)._replace(**{
                f.name: getattr(like.table(name), f.name) for f in KINDS[name].by_role(PATTERN)})
            for name in KIND_NAMES if getattr(arrays, name) is not None})
        indices, indptr = like.indices, like.indptr
    else:
        arrays, indices, indptr = newton_pattern(arrays, n_dof, n_con)
    design, arrays = flatten(arrays, dt)
    system = System(
        model=model, dtype=dt, n_dof=n_dof, n_con=n_con,
        q0=np.array(b.q0, dtype=dt), v0=np.array(b.v0, dtype=dt), arrays=arrays, design=design,
        time_base={k: b.table(k).time_base(dt) for k in TIMED_NAMES},
        time_profiles={k: list(b.table(k).profiles) for k in TIMED_NAMES},
        names={k: list(b.table(k).names) for k in KIND_NAMES}, indices=indices, indptr=indptr,
        bodies=b.bodies, dof_names=b.dof_names, con_names=b.con_names, con_joint=b.con_joint,
        con_kind=np.array(b.con_kind, dtype=np.int64),
        con_item=np.array(b.con_item, dtype=np.int64),
        con_sign=np.array(b.con_sign, dtype=np.float64),
        con_side=np.array(b.con_side, dtype=np.int64), length_scale=_length_scale(model),
        record=record)
    if on_built is not None:
        on_built(system)
    # a complex-step perturbation of ``like``: its real parts are those of ``like`` (to
    # O(h^2) = 1e-60), so the checks of the initial configuration and of the constraint rank,
    # which read real parts only, would repeat those of ``like``
    checked = not (same and dt.kind == "c" and like.dtype.kind == "f")
    if checked:
        check_initial(system, velocities=False)
        check_rank(system)
    if needs_initial_velocities(system):
        system.v0 = initial_velocities(system)
    if checked:
        check_initial(system, positions=False)
    return system
