"""The fixed sparsity pattern of the step matrix and the scatter map of every contribution.

Every kind of item declares where its entries of the saddle-point matrix go
(:attr:`~morphlab.kernels.schema.Kind.coordinates`: the (row, column) pairs of each of its
pattern fields); ``np.unique`` turns them into a CSC pattern and, for each pattern field, the
position of every entry in ``data`` (``-1``: absent). A Newton iteration then only refills
``data`` (:mod:`morphlab.kernels.assemble`). Nothing here knows a kind of item.
"""

from __future__ import annotations

import numpy as np

from ..kernels.schema import KINDS, PATTERN
from ..kernels.system import KIND_NAMES, SystemArrays


def newton_pattern(arrays: SystemArrays, n_dof: int, n_con: int) -> tuple:
    """``(arrays with their pattern fields filled, indices, indptr)``."""
    n = n_dof + n_con
    parts = []  # (kind, field, rows, cols, shape)
    for name in KIND_NAMES:
        kind, table = KINDS[name], getattr(arrays, name)
        if table is None or not kind.by_role(PATTERN):
            continue
        coords = kind.coordinates(arrays, n_dof)
        for f in kind.by_role(PATTERN):
            rows, cols = np.broadcast_arrays(*(np.asarray(x, np.int64) for x in coords[f.name]))
            parts.append((name, f.name, rows.ravel(), cols.ravel(), rows.shape))
    R = np.concatenate([p[2] for p in parts]) if parts else np.zeros(0, np.int64)
    C = np.concatenate([p[3] for p in parts]) if parts else np.zeros(0, np.int64)
    valid = (R >= 0) & (C >= 0)
    ukey, inv = np.unique(C[valid] * n + R[valid], return_inverse=True)
    full_map = -np.ones(R.size, dtype=np.int64)
    full_map[valid] = inv
    indptr = np.zeros(n + 1, dtype=np.int64)
    np.add.at(indptr, ukey // n + 1, 1)
    maps: dict = {}
    start = 0
    for name, fname, rows, _, shape in parts:
        maps.setdefault(name, {})[fname] = np.ascontiguousarray(
            full_map[start:start + rows.size].reshape(shape))
        start += rows.size
    filled = arrays._replace(**{name: getattr(arrays, name)._replace(**fields)
                                for name, fields in maps.items()})
    return filled, (ukey % n).astype(np.int64), np.cumsum(indptr)
