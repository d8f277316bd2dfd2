"""The record of the steps a sensitivity method reads back (the factors, matrix blocks and
states of each step: :class:`~morphlab.kernels.adjoint.Keep`), as the time loop fills it.

A primal run passes an empty record (no rows: the compiled loop writes nothing), so that it
and a sensitivity run call the compiled time loop with the same types and share its
compilation.

A record of a whole run is large (the factors of every step: ~300 MB for the 240-element
skin), and memory obtained afresh is slow to write the first time (each page is faulted in
as it is written). The adjoint therefore hands its records back when its sweep is done
(:func:`release`), and its next record of the same sizes in this process is made of them
(:func:`keep_record` with ``pooled``). A record's rows are each written by its run before
they are read, so a reused record needs no clearing. The process keeps the records of the
last release (at most the adjoint's ``memory``); :func:`clear_pool` frees them.
"""

from __future__ import annotations

import threading
from collections.abc import Iterable

import numpy as np

from ..compile import System
from ..kernels.adjoint import Keep

_POOL: list[Keep] = []  # the records of the last release, free to be taken
_LOCK = threading.Lock()


def keep_record(system: System, factor_arrays, K: int, k0: int, blocks: bool, *,
                pooled: bool = False) -> Keep:
    """An empty :class:`~morphlab.kernels.adjoint.Keep` of ``K`` steps from ``k0``, shaped for
    the factors of ``factor_arrays`` (:meth:`~morphlab.solve.linalg.StepFactorization.
    loop_arrays`); with ``blocks`` room for each step's ``Dq, Dv`` (the reuse variant).
    ``pooled``: made of a released record of the same sizes where the pool has one (module
    docstring; its rows hold another run's values until this run writes them); where it has
    none, the pool is freed first, so that a process holds one run's released records at most
    besides the run in progress."""
    F = factor_arrays
    dt = np.dtype(system.dtype)
    fac = [None if x is None else ((K,) + x.shape, np.dtype(np.int64 if x is F.piv else dt))
           for x in (F.LU, F.piv, F.Lx, F.Ux, F.Ud)]
    states = [(K + 1, system.n_dof)] * 3 + [(K + 1, system.n_con)]
    shapes = fac + [((K, 2, system.nnz if blocks else 0), dt)] + [(s, dt) for s in states]
    if pooled and K > 0:
        R = _take(shapes)
        if R is not None:
            R.k0[0] = k0
            return R
    arrays = [None if s is None else np.zeros(*s) for s in shapes]
    return Keep(*arrays, np.array([k0], dtype=np.int64))


def _shapes(R: Keep) -> list:
    return [None if x is None else (x.shape, x.dtype) for x in R[:-1]]


def _take(shapes: list) -> Keep | None:
    """A released record of these array shapes and dtypes, taken from the pool, or None (and
    the pool freed)."""
    with _LOCK:
        for i, R in enumerate(_POOL):
            if _shapes(R) == shapes:
                return _POOL.pop(i)
        _POOL.clear()
    return None


def release(records: Iterable[Keep]) -> None:
    """Hand ``records`` (no longer read by their run) to the pool, in place of the records it
    holds: the next :func:`keep_record` of the same sizes in this process takes them."""
    kept = [R for R in records if R.Q.shape[0] > 1]
    with _LOCK:
        _POOL[:] = kept


def clear_pool() -> None:
    """Free the released records the process keeps (module docstring)."""
    with _LOCK:
        _POOL.clear()


def pooled_bytes() -> int:
    """Bytes of the released records the process keeps."""
    with _LOCK:
        return sum(x.nbytes for R in _POOL for x in R if x is not None)


def fits(K: Keep, F) -> bool:
    """Does the record hold factors of ``F``'s kind and sizes?"""
    if F.order is None:
        return K.LU is not None and K.LU.shape[1:] == F.LU.shape
    return K.Lx is not None and K.Lx.shape[1] == F.Lx.size and K.Ux.shape[1] == F.Ux.size
