"""Where a run keeps its histories: the arrays of a Result, filled step by step.

Only the histories asked for are kept (``store``; a long run of a large model often needs only
the coordinates), in memory or in memory-mapped ``.npy`` files (``memmap``); a run whose
histories do not fit the memory available is refused before it starts, with the size it needs.
The Newton history is kept compactly: one row ``(|R|, correction)`` per iteration.
"""

from __future__ import annotations

import os
import pathlib

import numpy as np

from ..compile import System
from ..compile.system import extra_items
from ..errors import ModelError, ResourceError
from ..kernels.joints import constraint_violation_history
from .settings import State

#: The histories a run can keep, in the order of a state.
HISTORIES = ("q", "v", "a", "lam")
#: A run that does not keep both ``q`` and ``v`` in full buffers this many steps of them and
#: evaluates their constraint violations in one compiled call: per step from Python, the
#: evaluation and its two maxima cost about a tenth of a Newton step of a small model.
VIOLATION_CHUNK = 64


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
    per_time += 3 * system.n_con + 2 * system.load_dofs.shape[0] + system.torque_dofs.shape[0]
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
    """

    def __init__(self, system: System, t: np.ndarray, store=HISTORIES, memmap=None):
        store = tuple(store)
        if not store or not set(store) <= set(HISTORIES):
            raise ModelError(f"store must be a non-empty tuple of {HISTORIES}, got {store!r}")
        self.system, self.t, self.store = system, t, store
        n_t = t.size
        widths = {"q": system.n_dof, "v": system.n_dof, "a": system.n_dof,
                  "lam": system.n_con}
        self.arrays = {k: self._array(k, (n_t, widths[k]), memmap) for k in store}
        self.iterations = np.zeros(n_t, dtype=np.int64)
        self.viol = np.zeros(n_t)
        self.vviol = np.zeros(n_t)
        self.log = np.zeros((max(4 * n_t, 16), 2))  # Newton rows, grown by doubling
        self.log_offsets = np.zeros(n_t + 1, dtype=np.int64)
        self._rows = 0  # Newton rows so far
        self._u0 = np.ascontiguousarray(system.con_u0)
        self._extra = extra_items(system)
        self._batch = "q" in store and "v" in store  # violations from the kept histories
        if system.n_con and not self._batch:  # else from a buffer of the last steps
            m, dt = min(VIOLATION_CHUNK, n_t), system.dtype
            self._buf = (np.zeros((m, system.n_dof), dt), np.zeros((m, system.n_dof), dt),
                         np.zeros((m, system.n_con), dt), np.zeros((m, system.n_con), dt))
        self._buffered = 0  # steps in the buffer, the last ones recorded
        self.n_done = -1

    def _array(self, name, shape, memmap):
        dt = self.system.dtype
        if memmap is None:
            return np.zeros(shape, dtype=dt)  # calloc: pages are touched when written
        folder = pathlib.Path(memmap)
        folder.mkdir(parents=True, exist_ok=True)
        return np.lib.format.open_memmap(folder / f"{name}.npy", mode="w+", dtype=dt,
                                         shape=shape)

    def record(self, n: int, st: State, iterations: int, history, ta) -> None:
        """Keep step ``n``: its state, Newton iterations and history rows, and the constraint
        violation at position and velocity level (``ta``: the time data at ``st.t``)."""
        for name, arr in self.arrays.items():
            arr[n] = getattr(st, name)
        self.iterations[n] = iterations
        k, rows = self._rows, len(history)
        if k + rows > self.log.shape[0]:
            self.log = np.concatenate([self.log, np.zeros_like(self.log)])
        if rows:
            self.log[k:k + rows] = history
        self._rows = k + rows
        self.log_offsets[n + 1] = self._rows
        self.n_done = n
        if self.system.n_con and not self._batch:  # else at the end, from the histories
            k = self._buffered
            for buf, x in zip(self._buf, (st.q, st.v, ta.c, ta.cd)):
                buf[k] = x
            self._buffered = k + 1
            if self._buffered == self._buf[0].shape[0]:
                self._violations()

    def _violations(self) -> None:
        """The constraint violations of the buffered steps, the last ones recorded."""
        k, s = self._buffered, self.system
        if k == 0:
            return
        n0 = self.n_done + 1 - k
        Q, V, C, CD = (b[:k] for b in self._buf)
        constraint_violation_history(self._extra, Q, V, C, CD, s.con_kind, s.con_dofs,
                                     self._u0, self.viol[n0:n0 + k], self.vviol[n0:n0 + k])
        self._buffered = 0

    def result_fields(self, table) -> dict:
        """The Result's history fields up to the last recorded step (copies of in-memory
        arrays, views of memory maps); ``table``: the run's time table."""
        sl = slice(0, self.n_done + 1)
        if self._buffered:
            self._violations()
        if self._batch and self.system.n_con and self.n_done >= 0 and table is not None:
            s = self.system
            constraint_violation_history(self._extra, self.arrays["q"][sl],
                                         self.arrays["v"][sl],
                                         np.ascontiguousarray(table.C[sl]),
                                         np.ascontiguousarray(table.CD[sl]), s.con_kind,
                                         s.con_dofs, self._u0, self.viol[sl], self.vviol[sl])
        out = {k: (self.arrays[k][sl] if isinstance(self.arrays[k], np.memmap)
                   else self.arrays[k][sl].copy()) if k in self.arrays else None
               for k in HISTORIES}
        end = self.log_offsets[self.n_done + 1] if self.n_done >= 0 else 0
        return dict(t=self.t[sl].copy(), newton_iterations=self.iterations[sl].copy(),
                    constraint_violation=self.viol[sl].copy(),
                    velocity_violation=self.vviol[sl].copy(), newton_log=self.log[:end].copy(),
                    newton_log_offsets=self.log_offsets[:self.n_done + 2].copy(), **out)
