"""The compile record: what each beam of a compiled model contributed, so that another design of
the same model (a sensitivity run's perturbed designs, a finite-difference step) copies the
beams whose inputs did not change instead of compiling them again.

A beam is most of a model's compile time (its frames, elements and frame joints), and most
design variables leave it alone (a joint point, a torque, a rigid body). The record lives on
the :class:`~morphlab.compile.system.System` (``system.record``), so it is explicit and shared
by nothing else: compiling from two threads is safe. A beam is copied only when every input it
was compiled from is equal (the same numbers, a complex part included) and the builder stands
where it stood when the beam was compiled (the same DOFs, rows and constraint rows before it);
the copy is then the compile's own output, bit for bit (``tests/test_compile_record.py``).

A beam whose inputs differ only in its section (:data:`SECTION`: a thickness, a modulus, a
density) keeps its layout: its rows are copied with its element data computed again from the
new section (``section``, :func:`morphlab.compile.bodies.section_rows`), which costs the
elements' arithmetic and none of the frames' bookkeeping. A thickness variable of a
many-frame skin, compiled once per variable by a sensitivity run, is that case; when no other
item changed, the whole system is such a copy (:func:`same_item` compares the other items;
``morphlab.compile.compile``).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import NamedTuple

import numpy as np

from ..kernels.schema import DESIGN, KINDS, TIME, TOPOLOGY
from ..model import Item

#: Attributes of a beam that are not inputs of its compile.
_NOT_INPUTS = {"_model", "name"}
#: Attributes of a beam that change its element data only (not its DOFs, rows or frames).
SECTION = frozenset({"E", "rho", "thickness", "width", "area", "second_moment", "fibre"})


class Entry(NamedTuple):
    """What one beam contributed: its ``inputs`` (attribute values), the builder's counts
    ``before`` and ``after`` it (:func:`counts`), its body information, the function that
    finds its material points and the initial velocities of its DOFs as the model gives them
    (``v0``: before the compile computes them from the drives, which it does again for the
    other design); ``units``: the element units of its elements (geometry only,
:class:`~morphlab.compile.beam.Units`), from which a section copy forms the new section's
element data (:func:`morphlab.compile.bodies.section_rows`)."""

    inputs: dict
    before: tuple
    after: tuple
    info: object
    locate: Callable
    v0: list
    units: object


def counts(b) -> tuple:
    """Where the builder ``b`` stands: DOFs, rows of each table, constraint rows."""
    return (len(b.dof_names), tuple(t.n for t in b.tables.values()), len(b.con_names))


def inputs(beam) -> dict:
    """The values a beam is compiled from (its attributes but its name and model)."""
    return {k: v for k, v in vars(beam).items() if k not in _NOT_INPUTS}


def equal(a, b) -> bool:
    """Are two input values equal: numbers of one type, or numeric arrays of one shape (a
    complex part included)?"""
    if isinstance(a, np.ndarray) or isinstance(b, np.ndarray):
        a, b = np.asarray(a), np.asarray(b)
        return a.shape == b.shape and a.dtype.kind in "biufc" and b.dtype.kind in "biufc" \
            and bool(np.array_equal(a, b))
    try:
        return bool(a == b) and type(a) is type(b)
    except (TypeError, ValueError):
        return False


def same_value(a, b) -> bool:
    """:func:`equal`, with the items a value refers to (a joint's bodies) compared by kind and
    name: they are compared as items themselves."""
    if isinstance(a, Item) or isinstance(b, Item):
        return type(a) is type(b) and a.name == b.name
    if isinstance(a, (list, tuple)) and isinstance(b, (list, tuple)):
        return type(a) is type(b) and len(a) == len(b) and all(map(same_value, a, b))
    return equal(a, b)


def same_item(a, b) -> bool:
    """Are two items (of two designs of a model) of one kind and name and equal in every
    input?"""
    if type(a) is not type(b) or a.name != b.name:
        return False
    x, y = inputs(a), inputs(b)
    return x.keys() == y.keys() and all(same_value(x[k], y[k]) for k in x)


def changed_inputs(a: dict, b: dict) -> set | None:
    """The names of the inputs that differ between two beams (None: not the same attributes)."""
    if a.keys() != b.keys():
        return None
    return {k for k in a if not equal(a[k], b[k])}


def entry(beam, b, before: tuple) -> Entry:
    """The record of ``beam``, just compiled into ``b`` from the counts ``before``."""
    return Entry(inputs(beam), before, counts(b), b.bodies[beam.name], b.locate[beam.name],
                 b.v0[before[0]:], b.units.get(beam.name))


def replay(beam, b, like, section: Callable | None = None) -> Entry | None:
    """Copy ``beam``'s contribution from the compiled system ``like`` into the builder ``b``
    when its record there applies (module docstring); returns the beam's record in the new
    system, or None where nothing was copied. ``section(beam, dtype, like, starts)``: the
    rows of a beam whose section alone changed, ``{table: {field: values}}`` (``starts``: the
    beam's first row in each table); without it such a beam is compiled again."""
    rec = like.record.get(beam.name)
    if rec is None or counts(b) != rec.before or (
            np.dtype(like.dtype).kind == "c" and np.dtype(b.dtype).kind != "c"):
        return None  # (a complex system's rows would lose their imaginary parts in a real one)
    now = inputs(beam)
    diff = changed_inputs(rec.inputs, now)
    if diff is None or (diff and (section is None or not diff <= SECTION)):
        return None
    starts = dict(zip(b.tables, rec.before[1]))
    patch = section(beam, b.dtype, like, starts) if diff else {}
    d0, d1 = rec.before[0], rec.after[0]
    b.dof_names += like.dof_names[d0:d1]
    b.q0 += list(like.q0[d0:d1])
    b.v0 += rec.v0
    for (name, table), n0, n1 in zip(b.tables.items(), rec.before[1], rec.after[1]):
        if n1 == n0:
            continue
        arrays = like.table(name)
        kind = KINDS[name]
        values = {f.name: getattr(arrays, f.name)[n0:n1] for f in kind.fields
                  if f.role in (DESIGN, TOPOLOGY)}
        values.update(patch.get(name, {}))
        base = like.time_base[name][n0:n1] if any(f.role == TIME for f in kind.fields) else None
        first = table.add(like.names[name][n0:n1], base=base, count=n1 - n0, **values)
        for i, prof in like.time_profiles.get(name, ()):
            if n0 <= i < n1:
                table.profiles.append((first + i - n0, prof))
    c0, c1 = rec.before[2], rec.after[2]
    b.con_names += like.con_names[c0:c1]
    b.con_joint += like.con_joint[c0:c1]
    b.con_sign += list(like.con_sign[c0:c1])
    b.con_side += list(like.con_side[c0:c1])
    b.con_kind += list(like.con_kind[c0:c1])
    b.con_item += list(like.con_item[c0:c1])
    b.bodies[beam.name] = rec.info
    b.locate[beam.name] = rec.locate
    return rec._replace(inputs=now) if diff else rec
