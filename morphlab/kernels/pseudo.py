"""The explicit part of a sensitivity pseudo-load: ``dR/dp_i`` of a step at its converged
state, for every design variable ``i`` (``docs/theory.md`` §6).

The residual depends on a design variable only through the system's design data (a flat
vector whose entries the kinds' tables view, :mod:`morphlab.kernels.system`) and its time
values. Variable ``i`` changes the entries ``PP[PO[i]:PO[i + 1]]`` of the design data, with
the derivatives ``PV`` there, and the time values of table ``tl[i]`` / ``tn[i]``. Each kind of
item it changes is evaluated over the items it changes (:class:`~morphlab.kernels.system.
Parts`) along one of two paths:

* **linear**: where the kind's residual is linear in the changed data (the invariants and
  element matrices of the bodies, with their damping and the gravity held; the magnitudes of
  point forces and torques), the derivative is the residual with the derivatives in place of
  the data: real arithmetic, the same kernels as the primal's, on ``ML`` (the system's arrays
  with the linear design fields as views of the zero vector ``ZL``) and the derivative time
  tables ``TL``;
* **perturbed**: otherwise, the residual of the perturbed design: complex step (``MN`` complex,
  ``pert = i h``: ``Im R / h``, exact) or, for the paper's semi-analytical method, a forward
  difference (``MN`` real: ``(R(p + h) - R(p)) / h``), on ``MN`` (the system's arrays as
  views of ``DN``, into which the perturbed design's values ``VN`` are written and the
  nominal's restored) and the perturbed time tables ``TN``.

The parts each variable changes are evaluated alone: a thickness variable of a few elements
costs a few elements, not a whole residual. Parts of the bodies' kinds alone (a section, a
material: the common case on the linear path) go to their kernel directly, not through the
dispatch over every kind, to which the whole system's tables would be passed once per
variable, level and step (about 1 µs a call, as much as a thickness variable's own terms).
"""

from typing import NamedTuple

import numpy as np

from . import ffrf
from ._jit import inner, kernel
from .assemble import BODIES, ELEMENTS, residual
from .system import Parts, set_positions
from .types import Level


class Pseudo(NamedTuple):
    """What the explicit parts of the pseudo-loads read (module docstring).

    ``OFF``, ``OFFN`` (n_x, n_kinds + 1): offsets into ``IDX`` of the items each variable's
    linear and perturbed paths evaluate; ``FOFF`` (n_x + 1,), ``FIDX``: its flexible
    coordinates; ``PO`` (n_x + 1,), ``PP``: its positions in the flat design data, ``PV`` (real)
    the derivatives there and ``VN`` (``DN``'s dtype) the perturbed design's values, ``D0``
    the nominal's (``DN``'s dtype); ``ML``, ``ZL``, ``TL``, ``tl``: the linear path;
    ``MN``, ``DN``, ``TN``, ``tn``, ``pert``: the perturbed path (all None when no variable
    takes it, and ``VN``, ``D0`` and ``WN`` too: then the kernels compile none of its code and
    unbox none of its arrays); ``forward``: the perturbed path is a forward difference (else a
    complex step); ``WL``, ``WN``: the bodies' scratch of each path.
    """

    OFF: np.ndarray
    OFFN: np.ndarray
    IDX: np.ndarray
    FOFF: np.ndarray
    FIDX: np.ndarray
    PO: np.ndarray
    PP: np.ndarray
    PV: np.ndarray
    VN: np.ndarray
    D0: np.ndarray
    ML: tuple
    ZL: np.ndarray
    TL: tuple
    tl: np.ndarray
    MN: tuple
    DN: np.ndarray
    TN: tuple
    tn: np.ndarray
    pert: np.ndarray
    forward: bool
    WL: tuple
    WN: tuple


class Column(NamedTuple):
    """One variable's explicit part and its scratch: ``R`` (n,) float64, the column
    :func:`explicit` adds to; ``RN``, ``R0`` (n,): scratch residuals of the perturbed path
    (``DN``'s dtype, float64); ``mask`` (n_flex,) bool, all False between calls; ``XN``,
    ``XO``: the new and the old level's state in ``DN``'s dtype
    (:class:`~morphlab.kernels.types.Level`), which the perturbed path evaluates, loaded once
    a step by :func:`load` for all variables. ``RN``, ``R0``, ``XN``, ``XO`` are None for
    data without the perturbed path."""

    R: np.ndarray
    RN: np.ndarray
    R0: np.ndarray
    mask: np.ndarray
    XN: tuple
    XO: tuple

    @classmethod
    def zeros(cls, n_dof: int, n_con: int, n_flex: int, ps: "Pseudo") -> "Column":
        """A zero column for ``n_dof + n_con`` residual rows, ``n_flex`` flexible
        coordinates and the pseudo-load data ``ps`` (the perturbed path's buffers in its
        dtype, none without the path)."""
        n = n_dof + n_con
        mask = np.zeros(n_flex, dtype=np.bool_)
        if ps.MN is None:
            return cls(np.zeros(n), None, None, mask, None, None)
        dtype = ps.DN.dtype

        def level():
            return Level(*(np.zeros(n_dof, dtype=dtype) for _ in range(3)),
                         np.zeros(n_con, dtype=dtype))

        return cls(np.zeros(n), np.zeros(n, dtype=dtype), np.zeros(n), mask, level(), level())


@inner
def _any(off):
    return off[off.shape[0] - 1] > off[0]


@inner
def load(xn, x):
    """The state ``x`` into the level ``xn`` (of the perturbed path's dtype; None: no
    perturbed path, nothing to load)."""
    if xn is None:
        return
    for j in range(x.q.shape[0]):
        xn.q[j] = x.q[j]
        xn.v[j] = x.v[j]
        xn.a[j] = x.a[j]
    for j in range(x.lam.shape[0]):
        xn.lam[j] = x.lam[j]


@inner
def explicit(ps, MN, M, T, i, x, xn, w, k, c):
    """Add ``dR/dp_i`` of one level's residual share (state ``x``, the same in the perturbed
    path's dtype ``xn`` (:func:`load`), weights ``w``, time index ``k``) to the column
    ``c.R`` (:class:`Column`). ``M``, ``T``: the nominal system and time values (the forward
    difference subtracts their residual). ``MN``: ``ps.MN``, passed on its own: None when no
    variable takes the perturbed path, and then Numba compiles none of that path's code (it
    prunes a branch on an argument that is None, not on a field of one)."""
    n_dof = x.q.shape[0]
    R, RN, R0, mask = c.R, c.RN, c.R0, c.mask
    a, b = ps.PO[i], ps.PO[i + 1]
    pos = ps.PP[a:b]
    for j in range(ps.FOFF[i], ps.FOFF[i + 1]):
        mask[ps.FIDX[j]] = True
    o = ps.OFF[i]
    if _any(o):
        set_positions(ps.ZL, pos, ps.PV[a:b])
        if o[ELEMENTS + 1] == o[o.shape[0] - 1]:  # the bodies' kinds alone (module docstring)
            ML, idx = ps.ML, ps.IDX
            ffrf.residual(ML.bodies, ML.flex, ML.elements, ML.gravity, x, w,
                          idx[o[BODIES]:o[BODIES + 1]], idx[o[ELEMENTS]:o[ELEMENTS + 1]], mask,
                          R, ps.WL)
        else:
            residual(ps.ML, x, w, ps.TL, ps.tl[i], k, Parts(o, ps.IDX, mask), n_dof, R, ps.WL)
        for j in range(a, b):
            ps.ZL[ps.PP[j]] = 0.0
    if MN is not None and _any(ps.OFFN[i]):
        P = Parts(ps.OFFN[i], ps.IDX, mask)
        for j in range(RN.shape[0]):
            RN[j] = 0.0
        set_positions(ps.DN, pos, ps.VN[a:b])
        residual(MN, xn, w, ps.TN, ps.tn[i], k, P, n_dof, RN, ps.WN)
        set_positions(ps.DN, pos, ps.D0[a:b])
        if ps.forward:
            for j in range(R0.shape[0]):
                R0[j] = 0.0
            residual(M, x, w, T, np.int64(0), k, P, n_dof, R0, ps.WL)
            h = ps.pert[i].real
            for j in range(R.shape[0]):
                R[j] += (RN[j].real - R0[j]) / h
        else:
            h = ps.pert[i].imag
            for j in range(R.shape[0]):
                R[j] += RN[j].imag / h
    for j in range(ps.FOFF[i], ps.FOFF[i + 1]):
        mask[ps.FIDX[j]] = False


@kernel
def explicit_column(ps, M, T, i, x, w, k, c):
    """:func:`explicit` called from Python: one variable's column at a given state, for tests
    and inspection (the adjoint finds the rows a variable touches in its sweep's kernel,
    ``morphlab.sensitivity.adjoint._touched``, and compiles no call of this one)."""
    load(c.XN, x)
    explicit(ps, ps.MN, M, T, i, x, c.XN, w, k, c)
