"""The record of the steps a sensitivity method reads back (the factors, matrix blocks and
states of each step: :class:`~morphlab.kernels.adjoint.Keep`), as the time loop fills it.

A primal run passes an empty record (no rows: the compiled loop writes nothing), so that it
and a sensitivity run call the compiled time loop with the same types and share its
compilation.

A record of a whole run is large (the factors of every step: ~300 MB for the 240-element
skin; the direct method's record of a chunk of steps, ~100 MB), and memory obtained afresh is
slow to write the first time: each page is faulted in as it is written, and where NumPy asks
for huge pages the kernel may stop the process to compact memory for them (a direct run of the
240-element skin measured 430 ms with its record reused, up to 930 ms with a fresh one). A
method therefore hands its records back when its run is done (:func:`release`), and its next
record of the same sizes in this process is made of them (:func:`keep_record` with ``pool``).
A record's rows are each written by its run before they are read, so a reused record needs no
clearing. The process keeps the records of each method's last release (at most the adjoint's
``memory`` and one direct record); :func:`clear_pool` frees them.
"""

from __future__ import annotations

import threading
from collections.abc import Iterable

import numpy as np

from ..compile import System
from ..kernels.adjoint import Keep
from ..kernels.newton import Factors
from ..kernels.types import Level

#: Per method ("adjoint", "direct"), the records of its last release, free to be taken.
_POOL: dict[str, list[Keep]] = {}
_LOCK = threading.Lock()


def keep_record(system: System, factor_arrays, K: int, k0: int, blocks: bool, *,
                pool: str | None = None, chunks: bool = False) -> Keep:
    """An empty :class:`~morphlab.kernels.adjoint.Keep` of ``K`` steps from ``k0``, shaped for
    the factors of ``factor_arrays`` (:meth:`~morphlab.solve.linalg.StepFactorization.
    loop_arrays`); with ``blocks`` room for each step's ``Dq, Dv`` (the reuse variant).
    ``pool``: the method's name; the record is made of a released record of that method of the
    same sizes where the pool has one (module docstring; its rows hold another run's values
    until this run writes them); where it has none, the method's released records are freed
    first, so that a process holds one run's released records per method at most besides the
    run in progress. ``chunks``: records of chunks of steps (the direct method's, which reads
    back the steps it writes only): a released record of more steps serves, and a miss keeps
    the released ones (the chunks of one run may differ in their sparse factors' fill; a later
    chunk of the run may take them)."""
    F = factor_arrays
    dt = np.dtype(system.dtype)
    fac = [None if x is None else ((K,) + x.shape, np.dtype(np.int64 if x is F.piv else dt))
           for x in (F.LU, F.piv, F.Lx, F.Ux, F.Ud)]
    states = [(K + 1, system.n_dof)] * 3 + [(K + 1, system.n_con)]
    shapes = fac + [((K, 2, system.nnz if blocks else 0), dt)] + [(s, dt) for s in states]
    if pool is not None and K > 0:
        R = _take(shapes, pool, chunks)
        if R is not None:
            R.k0[0] = k0
            return R
    arrays = [None if s is None else np.zeros(*s) for s in shapes]
    return Keep(*arrays, np.array([k0], dtype=np.int64))


def template(system: System, factorization, blocks: bool) -> tuple[Keep, Factors] | None:
    """A record of no steps and fresh factor arrays of ``factorization``
    (:class:`~morphlab.solve.linalg.StepFactorization`), with the types of the records of its
    compiled steps (``blocks`` as for :func:`keep_record`): the ``like`` of
    :func:`solved_step` before any such record exists. None while the factorization has no
    compiled factors (a sparse one before SuperLU has chosen its row order)."""
    if not factorization.settled:
        return None
    F = factorization.loop_arrays()
    return keep_record(system, F, 0, 0, blocks), F


def solved_step(like: tuple[Keep, Factors] | None, new: Level, old: Level, Dq, Dv,
                k: int, factor: Factors | None = None) -> tuple[Keep, Factors]:
    """A record of the one step ``k`` solved from Python, for the kernels that read the steps
    from a record, and the factor arrays to pass with it: the step's states ``old``, ``new``
    (rows 0 and 1) and the ``Dq``, ``Dv`` (nnz,) of its fill (None: the exact variant, no
    blocks). With ``factor``, the arrays of the step's compiled factor (of the kind of
    ``like``'s), the record holds them and the kernels solve with it as with a recorded
    step's; without, the caller solves in their place (``sweep`` with ``solved``, ``chunk``
    with ``rhs_only``) and the record's factor fields are views of the first row of those of
    ``like``, a record and its factor arrays that the kernels take already (or
    :func:`template`), so that they take this one with the types they were compiled for (the
    fields are not read); with ``like`` None (a run without compiled factors), a dense factor
    of one entry."""
    dt = np.asarray(new.q).dtype if like is None else like[0].Q.dtype
    if factor is not None:
        F = factor
        fac = [None if x is None else x[None] for x in (F.LU, F.piv, F.Lx, F.Ux, F.Ud)]
    elif like is None:
        F = Factors(np.zeros((1, 1), dt), np.zeros(1, np.int64), None, None, None, None, None)
        fac = [np.zeros((1, 1, 1), dt), np.zeros((1, 1), np.int64), None, None, None]
    else:
        R, F = like
        fac = [None if x is None else x[:1] for x in (R.LU, R.piv, R.Lx, R.Ux, R.Ud)]
    D = np.zeros((1, 2, 0 if Dq is None else Dq.size), dt)
    if Dq is not None:
        D[0, 0], D[0, 1] = Dq, Dv
    states = [np.stack([np.asarray(a, dtype=dt), np.asarray(b, dtype=dt)])
              for a, b in zip(old, new)]
    return Keep(*fac, D, *states, np.array([k], dtype=np.int64)), F


def _shapes(R: Keep) -> list:
    return [None if x is None else (x.shape, x.dtype) for x in R[:-1]]


def _fit(have: list, want: list, longer: bool) -> bool:
    """Do a record's array shapes and dtypes ``have`` serve ``want``? (``longer``: with as
    many steps or more.)"""
    if not longer:
        return have == want
    return len(have) == len(want) and all(
        h == w if h is None or w is None else
        (h[1] == w[1] and h[0][1:] == w[0][1:] and h[0][0] >= w[0][0])
        for h, w in zip(have, want))


def _take(shapes: list, pool: str, chunks: bool = False) -> Keep | None:
    """A released record of method ``pool`` that serves these array shapes and dtypes
    (:func:`_fit`), taken from the pool, or None (and, unless ``chunks``, that method's
    released records freed)."""
    with _LOCK:
        held = _POOL.setdefault(pool, [])
        for i, R in enumerate(held):
            if _fit(_shapes(R), shapes, chunks):
                return held.pop(i)
        if not chunks:
            held.clear()
    return None


def release(records: Iterable[Keep], pool: str) -> None:
    """Hand ``records`` (no longer read by their run) to method ``pool``'s part of the pool,
    in place of the records it holds: the method's next :func:`keep_record` of the same sizes
    in this process takes them."""
    kept = [R for R in records if R is not None and R.Q.shape[0] > 1]
    with _LOCK:
        _POOL[pool] = kept


def clear_pool() -> None:
    """Free the released records the process keeps (module docstring)."""
    with _LOCK:
        _POOL.clear()


def pooled_bytes() -> int:
    """Bytes of the released records the process keeps."""
    with _LOCK:
        return sum(x.nbytes for held in _POOL.values() for R in held for x in R
                   if x is not None)


def fits(K: Keep, F) -> bool:
    """Does the record hold factors of ``F``'s kind and sizes?"""
    if F.order is None:
        return K.LU is not None and K.LU.shape[1:] == F.LU.shape
    return K.Lx is not None and K.Lx.shape[1] == F.Lx.size and K.Ux.shape[1] == F.Ux.size
