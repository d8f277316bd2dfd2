"""The record of the steps a sensitivity method reads back (the factors, matrix blocks and
states of each step: :class:`~morphlab.kernels.adjoint.Keep`), as the time loop fills it.

A primal run passes an empty record (no rows: the compiled loop writes nothing), so that it
and a sensitivity run call the compiled time loop with the same types and share its
compilation.
"""

from __future__ import annotations

import numpy as np

from ..compile import System
from ..kernels.adjoint import Keep


def keep_record(system: System, factor_arrays, K: int, k0: int, blocks: bool) -> Keep:
    """An empty :class:`~morphlab.kernels.adjoint.Keep` of ``K`` steps from ``k0``, shaped for
    the factors of ``factor_arrays`` (:meth:`~morphlab.solve.linalg.StepFactorization.
    loop_arrays`); with ``blocks`` room for each step's ``Dq, Dv`` (the reuse variant)."""
    F = factor_arrays
    dt = system.dtype

    def rows(x, dtype=dt):  # the factor's own fields; None for the other kind's
        return None if x is None else np.zeros((K,) + x.shape, dtype)

    return Keep(rows(F.LU), rows(F.piv, np.int64), rows(F.Lx), rows(F.Ux), rows(F.Ud),
                np.zeros((K, 2, system.nnz if blocks else 0), dt),
                np.zeros((K + 1, system.n_dof), dt),
                np.zeros((K + 1, system.n_dof), dt), np.zeros((K + 1, system.n_dof), dt),
                np.zeros((K + 1, system.n_con), dt), np.array([k0], dtype=np.int64))


def fits(K: Keep, F) -> bool:
    """Does the record hold factors of ``F``'s kind and sizes?"""
    if F.order is None:
        return K.LU is not None and K.LU.shape[1:] == F.LU.shape
    return K.Lx is not None and K.Lx.shape[1] == F.Lx.size and K.Ux.shape[1] == F.Ux.size
