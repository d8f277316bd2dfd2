"""Which of a run's design variables the adjoint's sweep evaluates how (``docs/theory.md``
§7.4, §7.5): those that change the bodies' linear data alone take the data gradient of the
bodies' kinds (:func:`bodies_linear`); of the others, those on the linear path alone with
disjoint items and rows are evaluated together (:func:`share_units`). Both read the
pseudo-load data (:class:`~morphlab.kernels.pseudo.Pseudo`) that
:func:`morphlab.sensitivity.designs.pseudo_data` forms.
"""

from __future__ import annotations

import numpy as np

from ..kernels.pseudo import Pseudo
from ..kernels.system import KIND_NAMES

#: The column of the parts' offsets after the bodies' kinds (the first three kinds).
_BODY_KINDS_END = KIND_NAMES.index("elements") + 1
#: The bodies' kinds: what their data gradient and stiffness share read of a system.
BODY_KINDS = KIND_NAMES[:_BODY_KINDS_END]
assert BODY_KINDS == ("bodies", "flex", "elements")


def linear_only(ps: Pseudo, n_x: int) -> np.ndarray:
    """Which of the ``n_x`` variables take the linear path alone (parts there, none on the
    perturbed path, no change of time values): (n_x,) bool."""
    o, on = ps.OFF[:n_x], ps.OFFN[:n_x]
    return (on[:, -1] == on[:, 0]) & (ps.tl[:n_x] == 0) & (o[:, -1] > o[:, 0])


def bodies_linear(ps: Pseudo, n_x: int) -> np.ndarray:
    """Which of the ``n_x`` variables change the linear design data of the bodies' kinds
    alone (:func:`linear_only`, parts of those kinds only): (n_x,) bool. The adjoint takes
    their design shares from the data gradient of those kinds
    (``morphlab.kernels.ffrf_adjoint``)."""
    return linear_only(ps, n_x) & (ps.OFF[:n_x, _BODY_KINDS_END] == ps.OFF[:n_x, -1])


def share_units(ps: Pseudo, RO: np.ndarray, RI: np.ndarray, skip=None) -> tuple:
    """Group the variables whose explicit parts can be evaluated together:
    ``(ps', UO, UI, UV)``, unit ``u`` evaluating variable ``UV[u]`` of ``ps'`` for its
    members ``UI[UO[u]:UO[u + 1]]``; the variables set in ``skip`` ((n_x,) bool) are in no
    unit (the caller forms their shares otherwise).

    The explicit part is linear in the design data on the linear path, so the variables that
    take that path alone (no perturbed path, no change of time values) and whose items,
    flexible coordinates and residual rows (``RO``, ``RI``: :func:`~morphlab.sensitivity.
    adjoint._touched`) are pairwise disjoint have the sum of their explicit parts, row by row
    each its own, from one evaluation with the union of their changes: a group of them is one
    more variable of ``ps'`` (appended after the ``n_x`` of ``ps``). The thickness variables of
    a many-frame skin, one frame each, would become one or two evaluations a step instead of
    one each (the adjoint passes them as ``skip``: the data gradient takes them); variables
    that share a frame stay units of their own."""
    n_x = RO.size - 1
    n_k = ps.OFF.shape[1] - 1
    groups: list = []  # [members, rows (set), items (set), flex (set)]
    single = []
    alone = linear_only(ps, n_x)
    for i in range(n_x):
        if skip is not None and skip[i]:
            continue
        if not alone[i]:
            single.append(i)
            continue
        rows = set(RI[RO[i]:RO[i + 1]].tolist())
        items = {(k, int(j)) for k in range(n_k) for j in ps.IDX[ps.OFF[i, k]:ps.OFF[i, k + 1]]}
        flex = set(ps.FIDX[ps.FOFF[i]:ps.FOFF[i + 1]].tolist())
        for g in groups:
            if not (rows & g[1] or items & g[2] or flex & g[3]):
                g[0].append(i)
                g[1] |= rows
                g[2] |= items
                g[3] |= flex
                break
        else:
            groups.append([[i], rows, items, flex])
    single += [g[0][0] for g in groups if len(g[0]) == 1]
    groups = [g[0] for g in groups if len(g[0]) > 1]
    units = [(i, [i]) for i in sorted(single)] + [(n_x + j, m) for j, m in enumerate(groups)]
    UO = np.zeros(len(units) + 1, dtype=np.int64)
    UO[1:] = np.cumsum([len(m) for _, m in units])
    UI = np.array([i for _, m in units for i in m], dtype=np.int64)
    UV = np.array([v for v, _ in units], dtype=np.int64)
    if not groups:
        return ps, UO, UI, UV
    # the groups as variables: their parts, coordinates and positions the members' together
    off, idx, fidx, pos = [], [], [], []
    start = ps.IDX.size
    for members in groups:
        row = [start]
        for k in range(n_k):
            sel = np.concatenate([ps.IDX[ps.OFF[i, k]:ps.OFF[i, k + 1]] for i in members])
            idx.append(np.sort(sel))
            start += sel.size
            row.append(start)
        off.append(row)
        fidx.append(np.sort(np.concatenate([ps.FIDX[ps.FOFF[i]:ps.FOFF[i + 1]]
                                            for i in members])))
        pos.append(np.concatenate([np.arange(ps.PO[i], ps.PO[i + 1]) for i in members]))
    order = np.concatenate([np.arange(ps.PO[-1])] + pos)
    n_g = len(groups)
    FOFF = np.concatenate([ps.FOFF, ps.FOFF[-1] + np.cumsum([f.size for f in fidx])])
    PO = np.concatenate([ps.PO, ps.PO[-1] + np.cumsum([p.size for p in pos])])
    empty = np.full((n_g, n_k + 1), ps.OFFN[-1, -1], dtype=np.int64)
    return ps._replace(
        OFF=np.concatenate([ps.OFF, np.array(off, dtype=np.int64)]),
        OFFN=np.concatenate([ps.OFFN, empty]), IDX=np.concatenate([ps.IDX] + idx),
        FOFF=FOFF, FIDX=np.concatenate([ps.FIDX] + fidx), PO=PO, PP=ps.PP[order],
        PV=ps.PV[order], tl=np.concatenate([ps.tl, np.zeros(n_g, np.int64)]),
        **({} if ps.MN is None else  # the perturbed path's data, where it has the path
           {"VN": ps.VN[order], "D0": ps.D0[order],
            "tn": np.concatenate([ps.tn, np.zeros(n_g, np.int64)]),
            "pert": np.concatenate([ps.pert, np.zeros(n_g, ps.pert.dtype)])})), UO, UI, UV
