"""The design data of a system as one flat vector, and the views of it the kernels read.

Every design field of every kind (:mod:`morphlab.kernels.schema`), and the gravity, is laid out
in one flat array: :func:`flatten` gives the vector and the system's arrays as views into it.
The same :func:`layout` maps a position of the vector back to its kind, field and item, so the
change of a design variable is a set of positions whatever the kinds it touches
(``morphlab.sensitivity.designs``), and :func:`views` gives the arrays over another vector of
the same layout (a working copy a sensitivity run writes designs into).
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from ..kernels.schema import DESIGN, KINDS
from ..kernels.system import KIND_NAMES, SystemArrays


class Slot(NamedTuple):
    """Where one design field lies in the flat vector: ``kind`` (None for the gravity),
    ``field``, first position ``start``, number of items ``n`` and numbers per item
    ``size``."""

    kind: str | None
    field: str
    start: int
    n: int
    size: int


def layout(arrays: SystemArrays) -> list[Slot]:
    """The slots of the design fields of ``arrays`` (absent kinds have none)."""
    out = [Slot(None, "gravity", 0, 1, 2)]
    pos = 2
    for name in KIND_NAMES:
        table = getattr(arrays, name)
        if table is None:
            continue
        for f in KINDS[name].by_role(DESIGN):
            a = getattr(table, f.name)
            size = math.prod(f.shape)
            out.append(Slot(name, f.name, pos, a.shape[0], size))
            pos += a.shape[0] * size
    return out


def flatten(arrays: SystemArrays, dtype) -> tuple[np.ndarray, SystemArrays]:
    """``(D, arrays)``: the design data in one vector of ``dtype`` and ``arrays`` with its
    design fields replaced by views of it."""
    slots = layout(arrays)
    size = slots[-1].start + slots[-1].n * slots[-1].size
    D = np.zeros(size, dtype=dtype)
    D[0:2] = arrays.gravity
    for s in slots[1:]:
        D[s.start:s.start + s.n * s.size] = getattr(getattr(arrays, s.kind), s.field).ravel()
    return D, views(arrays, D)


def views(arrays: SystemArrays, D: np.ndarray, fields=None) -> SystemArrays:
    """``arrays`` with its design fields (those of ``fields``, ``{(kind, field)}``, if given;
    the gravity is ``(None, "gravity")``) as views of ``D``, a vector of their layout."""
    slots = layout(arrays)
    chosen = {(s.kind, s.field) for s in slots} if fields is None else set(fields)
    gravity = D[0:2] if (None, "gravity") in chosen else arrays.gravity
    tables = {}
    for s in slots[1:]:
        if (s.kind, s.field) not in chosen:
            continue
        shape = (s.n,) + KINDS[s.kind].fields_by_name[s.field].shape
        tables.setdefault(s.kind, {})[s.field] = D[s.start:s.start + s.n * s.size].reshape(
            shape)
    out = arrays._replace(gravity=gravity)
    return out._replace(**{k: getattr(out, k)._replace(**v) for k, v in tables.items()})


def owners(arrays: SystemArrays, positions: np.ndarray, slots=None) -> list[tuple]:
    """``(kind, field, items)`` of the slots that hold ``positions`` of the flat vector:
    one entry per slot touched, ``items`` the distinct items (int64, sorted) of it
    (``slots``: :func:`layout` of ``arrays``, if at hand)."""
    slots = layout(arrays) if slots is None else slots
    starts = np.array([s.start for s in slots])
    pos = np.asarray(positions, dtype=np.int64)
    which = np.searchsorted(starts, pos, side="right") - 1
    out = []
    for j in np.unique(which):
        s = slots[int(j)]
        items = np.unique((pos[which == j] - s.start) // s.size)
        out.append((s.kind, s.field, items))
    return out
