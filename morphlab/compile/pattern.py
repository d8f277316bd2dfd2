"""The fixed sparsity pattern of the Newton matrix and the scatter map of every contribution.

Every contribution to the saddle-point matrix (body border rows/columns, element blocks,
constraint rows and columns, the Hessian terms of joints and point loads) gets its (row,
column) pairs once per model; ``np.unique`` turns them into a CSC pattern and, for each
contribution, the position of its value in ``data``. A Newton iteration then only refills
``data`` (kernels.assemble.fill_matrix).
"""

from __future__ import annotations

import numpy as np

from ..kernels.joints import ROW_ANGLE

# entries of a side's 6 x 6 Hessian that can be nonzero (theta-theta, theta-w, w-theta)
_HESS_ENTRIES = ((2, 2), (2, 3), (3, 2), (2, 4), (4, 2))


def newton_pattern(s) -> dict:
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
        point_rows = (s["con_kind"] != ROW_ANGLE)[:, None]
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
