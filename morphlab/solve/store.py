"""Where a run keeps its histories: the arrays of a Result, filled step by step.

Only the histories asked for are kept in full (``store``; a long run of a large model often
needs only the coordinates), in memory or in memory-mapped ``.npy`` files (``memmap``); the
others hold the two levels the stepping reads. A run whose histories do not fit the memory
available is refused before it starts, with the size it needs. The same arrays are written by
the steps solved from Python and by the compiled chunks of steps
(:class:`~morphlab.kernels.histories.Histories`).
"""

from __future__ import annotations

import os
import pathlib

import numpy as np

from ..compile import System
from ..errors import ModelError, ResourceError
from ..kernels.histories import Histories
from .settings import State

#: The histories a run can keep, in the order of a state.
HISTORIES = ("q", "v", "a", "lam")


def available_memory() -> int | None:
    """Bytes of physical memory available now (None where the system does not say)."""
    try:
        return os.sysconf("SC_AVPHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")
    except (ValueError, OSError, AttributeError):  # pragma: no cover - not Linux
        return None


def check_memory(system: System, n_t: int, store=HISTORIES, memmap=None) -> None:
    """Refuse a run whose histories (``store``, in memory unless ``memmap``) and time tables
    need more than 80 % of the memory available now, before anything is allocated."""
    widths = {"q": system.n_dof, "v": system.n_dof, "a": system.n_dof, "lam": system.n_con}
    per_time = 0 if memmap is not None else sum(widths[k] for k in store if k in widths)
    per_time += 3 * system.n_con + 2 * system.count("loads") + system.count("torques")
    need = n_t * (per_time * np.dtype(system.dtype).itemsize + 8 * 5)  # + t, statistics
    avail = available_memory()
    if avail is not None and need > 0.8 * avail:
        raise ResourceError(
            f"a run of {n_t} times keeping {tuple(store)} of {system.n_dof} coordinates needs "
            f"{need / 2**20:.0f} MiB, more than the {avail / 2**20:.0f} MiB of memory "
            "available: keep fewer histories (simulate(..., store=('q',))), run fewer steps, "
            "or keep them on disk (simulate(..., memmap='a folder'))")


class HistoryStore:
    """The histories of one run of ``n_t`` times (see the module docstring).

    Parameters
    ----------
    system : System
    t : (n_t,)
        The times of the run.
    store : tuple of {"q", "v", "a", "lam"}
        Histories kept; the others are ``None`` in the Result.
    memmap : path, optional
        A folder for the kept histories as memory-mapped ``.npy`` files (``q.npy``, ...).
    max_iter : int
        Newton's iteration limit (the rows of the Newton log per step).
    """

    def __init__(self, system: System, t: np.ndarray, store=HISTORIES, memmap=None,
                 max_iter: int = 12):
        store = tuple(store)
        if not store or not set(store) <= set(HISTORIES):
            raise ModelError(f"store must be a non-empty tuple of {HISTORIES}, got {store!r}")
        self.system, self.t, self.store = system, t, store
        n_t = t.size
        widths = {"q": system.n_dof, "v": system.n_dof, "a": system.n_dof,
                  "lam": system.n_con}
        levels = {k: n_t if k in store else min(2, n_t) for k in HISTORIES}
        arr = {k: self._array(k, (levels[k], widths[k]), memmap if k in store else None)
               for k in HISTORIES}
        self.H = Histories(arr["q"], arr["v"], arr["a"],
                           np.zeros((min(2, n_t), system.n_dof), dtype=system.dtype),
                           arr["lam"], np.zeros(n_t, dtype=np.int64),
                           np.zeros((n_t, max_iter, 2)), np.zeros((n_t, 2)), system.n_con > 0)
        self.n_done = -1

    def _array(self, name, shape, memmap):
        dt = self.system.dtype
        if memmap is None:
            return np.zeros(shape, dtype=dt)  # calloc: pages are touched when written
        folder = pathlib.Path(memmap)
        folder.mkdir(parents=True, exist_ok=True)
        return np.lib.format.open_memmap(folder / f"{name}.npy", mode="w+", dtype=dt,
                                         shape=shape)

    def state(self, n: int) -> State:
        """The state at time index ``n`` (which the histories must still hold)."""
        H = self.H
        return State(float(self.t[n]), H.Q[n % H.Q.shape[0]].copy(),
                     H.V[n % H.V.shape[0]].copy(), H.A[n % H.A.shape[0]].copy(),
                     H.L[n % H.L.shape[0]].copy(), H.G[n % H.G.shape[0]].copy())

    def record(self, n: int, st: State, iterations: int, history) -> None:
        """Keep step ``n`` solved from Python: its state, Newton iterations and history rows,
        and its constraint violation."""
        H = self.H
        for arr, x in ((H.Q, st.q), (H.V, st.v), (H.A, st.a), (H.L, st.lam), (H.G, st.g)):
            arr[n % arr.shape[0]] = x
        H.iters[n] = iterations
        rows = min(len(history), H.newton.shape[1])
        if rows:
            H.newton[n, :rows] = np.asarray(history)[:rows]
        self.n_done = n
        if H.track:
            phi, phid = self.system.constraint_violation(st.q, st.v, float(self.t[n]))
            H.viol[n] = np.max(np.abs(phi.real)), np.max(np.abs(phid.real))

    def result_fields(self) -> dict:
        """The Result's history fields up to the last recorded step (copies of in-memory
        arrays, views of memory maps)."""
        H, n = self.H, self.n_done + 1
        sl = slice(0, n)
        named = {"q": H.Q, "v": H.V, "a": H.A, "lam": H.L}
        out = {k: (named[k][sl] if isinstance(named[k], np.memmap) else named[k][sl].copy())
               if k in self.store else None for k in HISTORIES}
        iters = H.iters[sl].copy()
        offsets = np.zeros(n + 1, dtype=np.int64)
        offsets[1:] = np.cumsum(np.minimum(iters, H.newton.shape[1]))
        log = (np.concatenate([H.newton[k, :min(int(iters[k]), H.newton.shape[1])]
                               for k in range(n)]) if n else np.zeros((0, 2)))
        return dict(t=self.t[sl].copy(), newton_iterations=iters,
                    constraint_violation=H.viol[sl, 0].copy(),
                    velocity_violation=H.viol[sl, 1].copy(), newton_log=log,
                    newton_log_offsets=offsets, **out)
