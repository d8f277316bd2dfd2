"""The fixed sparsity pattern of the Newton matrix and the scatter map of every contribution.

Every contribution to the saddle-point matrix (body border rows/columns, element blocks,
constraint rows and columns, the Hessian terms of joints and point loads) gets its (row,
column) pairs once per model; ``np.unique`` turns them into a CSC pattern and, for each
contribution, the position of its value in ``data``. A Newton iteration then only refills
``data`` (kernels.assemble). A new kind of contribution adds its coordinates with
:meth:`Pattern.add` and reads its positions back from :meth:`Pattern.finish`.
"""

from __future__ import annotations

import numpy as np

from ..kernels.forces import SPRING_ANGLE
from ..kernels.joints import ROW_ANGLE, ROW_SLIDE

# entries of a side's 6 x 6 Hessian that can be nonzero (theta-theta, theta-w, w-theta)
_HESS_ENTRIES = ((2, 2), (2, 3), (3, 2), (2, 4), (4, 2))


class Pattern:
    """Coordinates of named contributions (``-1``: absent), then the CSC pattern and the
    position in ``data`` of every entry of each contribution, in the contribution's shape."""

    def __init__(self, n: int):
        self.n = n
        self.parts: list[tuple[str, np.ndarray, np.ndarray, tuple]] = []

    def add(self, name: str, rows, cols) -> None:
        """Contribution ``name``: (row, column) of each of its entries, arrays of one shape."""
        rows, cols = np.broadcast_arrays(np.asarray(rows, np.int64), np.asarray(cols, np.int64))
        self.parts.append((name, rows.ravel(), cols.ravel(), rows.shape))

    def finish(self) -> dict:
        """``indptr``, ``indices`` and the map of every contribution (its shape, -1 where an
        entry is absent)."""
        R = np.concatenate([p[1] for p in self.parts])
        C = np.concatenate([p[2] for p in self.parts])
        valid = (R >= 0) & (C >= 0)
        ukey, inv = np.unique(C[valid] * self.n + R[valid], return_inverse=True)
        full_map = -np.ones(R.size, dtype=np.int64)
        full_map[valid] = inv
        indptr = np.zeros(self.n + 1, dtype=np.int64)
        np.add.at(indptr, ukey // self.n + 1, 1)
        out = {"indptr": np.cumsum(indptr), "indices": (ukey % self.n).astype(np.int64)}
        start = 0
        for name, rows, _, shape in self.parts:
            seg = full_map[start:start + rows.size].reshape(shape)
            out[name] = np.ascontiguousarray(seg if name not in out else
                                             np.concatenate([out[name], seg]))
            start += rows.size
        return out


def _borders(s, pat: Pattern) -> np.ndarray:
    """Each body's 3 x 3 reference block, reference-row/flex-column and flex-row/reference-
    column entries (row-major in each part); returns the offsets of each body's entries."""
    body_ref, flex_off, flex_dof = s["body_ref"], s["flex_off"], s["flex_dof"]
    offsets = [0]
    for b in range(body_ref.shape[0]):
        ref = body_ref[b]
        fd = flex_dof[flex_off[b]:flex_off[b + 1]]
        rows = np.concatenate([np.repeat(ref, 3), np.repeat(ref, fd.size), np.repeat(fd, 3)])
        cols = np.concatenate([np.tile(ref, 3), np.tile(fd, 3), np.tile(ref, fd.size)])
        pat.add("border_map", rows, cols)
        offsets.append(offsets[-1] + rows.size)
    if body_ref.shape[0] == 0:
        pat.add("border_map", np.zeros(0), np.zeros(0))
    return np.array(offsets, dtype=np.int64)


def _hessian(dofs, which) -> tuple[np.ndarray, np.ndarray]:
    """Row and column DOFs of the Hessian entries :data:`_HESS_ENTRIES` of points whose six
    DOFs are ``dofs[..., 6]``, where ``which`` (broadcastable to ``dofs[..., 0]``) is True."""
    shape = dofs.shape[:-1] + (6, 6)
    Hr, Hc = -np.ones(shape, dtype=np.int64), -np.ones(shape, dtype=np.int64)
    for (j, k) in _HESS_ENTRIES:
        Hr[..., j, k] = np.where(which, dofs[..., j], -1)
        Hc[..., j, k] = np.where(which, dofs[..., k], -1)
    return Hr, Hc


def _con_hessian(cd, kind) -> tuple[np.ndarray, np.ndarray]:
    """Rows and columns of the constraint Hessians, (n_con, 2, 2, 6, 6) indexed by the side of
    the row and of the column DOF: the one-side entries :data:`_HESS_ENTRIES` of point rows
    (none for angle rows), every pair of the two sides' DOFs for a slide row (its Hessian
    couples the guide's rotation with both points)."""
    n_con = cd.shape[0]
    Hr = -np.ones((n_con, 2, 2, 6, 6), dtype=np.int64)
    Hc = -np.ones_like(Hr)
    point = (kind != ROW_ANGLE) & (kind != ROW_SLIDE)
    for side in range(2):
        Hr[:, side, side], Hc[:, side, side] = _hessian(cd[:, side], point)
    slide = kind == ROW_SLIDE
    for r in range(2):
        for c in range(2):
            rows = np.broadcast_to(cd[:, r, :, None], (n_con, 6, 6))
            cols = np.broadcast_to(cd[:, c, None, :], (n_con, 6, 6))
            ok = slide[:, None, None] & (rows >= 0) & (cols >= 0)
            Hr[:, r, c] = np.where(ok, rows, Hr[:, r, c])
            Hc[:, r, c] = np.where(ok, cols, Hc[:, r, c])
    return Hr, Hc


def _spring_entries(dofs, kind) -> tuple[np.ndarray, np.ndarray]:
    """Rows and columns of the spring-damper entries, (n_spring, 2, 2, 6, 6) indexed by the
    side of the row and of the column DOF: every pair of the DOFs its measure depends on
    (``R, theta, u, v`` of both points for a length, ``theta, phi`` for an angle)."""
    n = dofs.shape[0]
    used = np.where((kind == SPRING_ANGLE)[:, None], np.array([0, 0, 1, 0, 0, 1], bool),
                    np.array([1, 1, 1, 1, 1, 0], bool))
    d = np.where(used[:, None, :], dofs, -1)  # (n, 2, 6)
    rows = np.broadcast_to(d[:, :, None, :, None], (n, 2, 2, 6, 6))
    cols = np.broadcast_to(d[:, None, :, None, :], (n, 2, 2, 6, 6))
    ok = (rows >= 0) & (cols >= 0)
    return np.where(ok, rows, -1), np.where(ok, cols, -1)


def _line_entries(s, gd) -> tuple[np.ndarray, np.ndarray]:
    """Rows and columns of the line-load entries, (n_line, 7, 7) over (theta, d_0..d_5) of
    each loaded element: theta with itself and with every element coordinate, both ways."""
    el = s["line_elem"]
    local = np.concatenate([s["body_ref"][s["elem_body"][el], 2][:, None], gd[el]], axis=1)
    rows = np.broadcast_to(local[:, :, None], (el.size, 7, 7)).copy()
    cols = np.broadcast_to(local[:, None, :], (el.size, 7, 7)).copy()
    border = np.zeros((7, 7), dtype=bool)
    border[0, :] = border[:, 0] = True
    ok = border[None] & (rows >= 0) & (cols >= 0)
    return np.where(ok, rows, -1), np.where(ok, cols, -1)


def newton_pattern(s) -> dict:
    """Fixed CSC pattern of the Newton matrix and the scatter map of every contribution."""
    n_dof, n_con = s["n_dof"], s["n_con"]
    pat = Pattern(n_dof + n_con)
    border_off = _borders(s, pat)
    efd, flex_dof = s["elem_fdof"], s["flex_dof"]
    gd = np.where(efd >= 0, flex_dof[np.maximum(efd, 0)] if flex_dof.size else -1, -1)
    pat.add("elem_map", gd[:, :, None], gd[:, None, :])
    cd = s["con_dofs"]
    crow = (n_dof + np.arange(n_con))[:, None, None]
    pat.add("con_map_row", crow, cd)
    pat.add("con_map_col", cd, crow)
    pat.add("con_map_H", *_con_hessian(cd, s["con_kind"]))
    pat.add("load_map", *_hessian(s["load_dofs"], True))
    pat.add("spring_map", *_spring_entries(s["spring_dofs"], s["spring_kind"]))
    pat.add("line_map", *_line_entries(s, gd.reshape(-1, 6)))
    return dict(pat.finish(), border_off=border_off)
