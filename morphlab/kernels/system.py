"""The containers every whole-system kernel reads, generated from the kinds of items.

A compiled model reaches the kernels as one :data:`SystemArrays`: the gravitational
acceleration ``gravity`` (2,) and one table per kind of item (:mod:`morphlab.kernels.schema`),
in the order of :data:`KIND_NAMES`, each the kind's named tuple of arrays, or ``None`` for an
optional kind the model does not have (its kernels are then not compiled). A run's time values
travel as :data:`Times` (one named tuple per kind with time fields, each array with two
leading axes: the table, then the time index; ``None`` for an absent kind), and what a
residual evaluation covers as :class:`Parts` (item indices per kind in one packed array, and
for the flexible coordinates a bool mask).

The design data of a system are views into one flat array (``morphlab.compile`` lays them
out): a design variable's change is a set of positions in it, written and restored by
:func:`set_positions` whatever the kinds.
"""

from collections import namedtuple
from typing import NamedTuple

import numpy as np

from ._jit import inner
from .assemble import POS  # noqa: F401 - importing assemble registers every kind first
from .schema import KINDS, TIME

#: The kinds, in the order of :data:`SystemArrays` (after ``gravity``).
KIND_NAMES = tuple(KINDS)
#: The kinds with time values, in the order of :data:`Times`.
TIMED_NAMES = tuple(k for k, kind in KINDS.items() if kind.times is not None)

SystemArrays = namedtuple("SystemArrays", ("gravity",) + KIND_NAMES)
Times = namedtuple("Times", TIMED_NAMES)


class Parts(NamedTuple):
    """What a residual evaluation covers: the items of kind ``j`` (position in
    :data:`KIND_NAMES`) are ``idx[off[j]:off[j + 1]]`` (int64), and the flexible coordinates
    those with ``flex`` set. One packed layout whatever the kinds, so the parts of many design
    variables are rows of one offset table over one index array."""

    off: np.ndarray
    idx: np.ndarray
    flex: np.ndarray


def _count(arrays, name: str) -> int:
    table = getattr(arrays, name)
    return 0 if table is None else table[0].shape[0]


def all_parts(arrays) -> Parts:
    """:class:`Parts` covering every item of ``arrays`` (a :data:`SystemArrays`)."""
    counts = [_count(arrays, k) for k in KIND_NAMES]
    off = np.zeros(len(counts) + 1, dtype=np.int64)
    off[1:] = np.cumsum(counts)
    idx = np.concatenate([np.arange(n, dtype=np.int64) for n in counts])
    return Parts(off, idx, np.ones(_count(arrays, "flex"), dtype=np.bool_))


def parts_of_kinds(arrays, names) -> Parts:
    """:class:`Parts` covering every item of the kinds ``names`` and nothing else (the
    flexible coordinates all, with the bodies)."""
    counts = [_count(arrays, k) if k in names else 0 for k in KIND_NAMES]
    off = np.zeros(len(counts) + 1, dtype=np.int64)
    off[1:] = np.cumsum(counts)
    idx = np.concatenate([np.arange(n, dtype=np.int64) for n in counts])
    flex = np.full(_count(arrays, "flex"), "bodies" in names, dtype=np.bool_)
    return Parts(off, idx, flex)


def pack_parts(arrays, per_variable: list) -> tuple:
    """The parts of several design variables as one table: ``per_variable[i]`` maps kind names
    to item indices (the flexible coordinates included, as indices). Returns ``(OFF (n_x,
    n_kinds + 1), IDX, FOFF (n_x + 1,), FIDX)``: variable ``i``'s parts are
    ``Parts(OFF[i], IDX, mask)`` with ``mask`` set at ``FIDX[FOFF[i]:FOFF[i + 1]]``."""
    n_k = len(KIND_NAMES)
    OFF = np.zeros((len(per_variable), n_k + 1), dtype=np.int64)
    chunks, fchunks = [], []
    start = 0
    for i, parts in enumerate(per_variable):
        OFF[i, 0] = start
        for j, name in enumerate(KIND_NAMES):
            sel = np.zeros(0, np.int64) if name == "flex" else np.asarray(
                parts.get(name, ()), dtype=np.int64)
            chunks.append(sel)
            start += sel.size
            OFF[i, j + 1] = start
        fchunks.append(np.asarray(parts.get("flex", ()), dtype=np.int64))
    IDX = np.concatenate(chunks) if chunks else np.zeros(0, np.int64)
    FOFF = np.zeros(len(per_variable) + 1, dtype=np.int64)
    FOFF[1:] = np.cumsum([c.size for c in fchunks])
    FIDX = np.concatenate(fchunks) if fchunks else np.zeros(0, np.int64)
    return OFF, IDX, FOFF, FIDX


def time_fields(name: str) -> tuple:
    """The time fields of kind ``name``."""
    return KINDS[name].by_role(TIME)


@inner
def set_positions(D, pos, val):
    """``D[pos[j]] = val[j]`` for every ``j`` (a design's entries into the flat design data;
    the nominal's back, with the nominal's values)."""
    for j in range(pos.shape[0]):
        D[pos[j]] = val[j]
