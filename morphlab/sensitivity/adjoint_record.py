"""The forward half of the discrete adjoint (:mod:`morphlab.sensitivity.adjoint`): what the
primal run records for the backward sweep, and the recomputation of a segment of steps from a
checkpoint.

The compiled steps go into a :class:`~morphlab.kernels.adjoint.Keep` (their factors, the
``Dq``, ``Dv`` of their last Newton fill and their states), the steps solved from Python (the
initial solve, the steps SuperLU chooses a row order on) one by one
(:class:`_PythonStep`). When the record of the whole run would not fit the memory budget, the
hook keeps checkpoints instead (the state at the start of every segment of steps), and
:class:`_Replay` recomputes a segment into a record when the sweep reaches it.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..compile import System
from ..kernels.histories import Histories
from ..kernels.newton import CONVERGED, PIVOT_REFUSED
from ..kernels.steps import run_steps
from ..kernels.types import Level
from ..solve.record import fits as _fits
from ..solve.record import keep_record
from ..solve.scheme import kernel_scheme
from ..solve.settings import Settings
from ..solve.timeloop import StepHook
from .beside import Beside
from .direct import converged_blocks


@dataclass
class _PythonStep:
    """A step solved from Python, as the sweep reads it: its factor (a ``Factor``), the
    ``Dq``, ``Dv`` of its last fill and its state (and the state before it)."""

    factor: object
    Dq: np.ndarray
    Dv: np.ndarray
    new: Level
    old: Level


def _level(st) -> Level:
    return Level(np.array(st.q), np.array(st.v), np.array(st.a), np.array(st.lam))


class AdjointHook(StepHook):
    """Records the steps of the primal run for the sweep (module docstring), and starts the
    work ``beside`` the run after its first compiled chunk (:mod:`.beside`), raising its
    error at a chunk boundary."""

    def __init__(self, system: System, n_steps: int, memory: int, reuse: bool,
                 beside: Beside | None = None):
        self.system, self.n_steps, self.memory = system, n_steps, memory
        self.beside = beside  # work started after the first compiled chunk (module beside)
        self.rows = 3 if reuse else 1
        self.python: dict[int, _PythonStep] = {}
        # the Keeps of the compiled steps, each from its first step to the end of the run; a
        # later one (a new row order of the sparse factors, whose values the earlier one's
        # patterns do not read) takes over from its first step
        self.records: list = []
        self.patterns: list = []  # the factor arrays of each record's row order
        self.segment = None  # steps per segment in checkpoint mode
        self.checkpoints: dict = {}  # step -> State at its start (checkpoint mode)

    def start(self, stepper, hist) -> None:
        self.stepper, self.hist = stepper, hist

    def python_step(self, k: int, out) -> None:
        if k > 0:
            self._beside()
        data = self.stepper.newton.data
        old = _level(out.state) if k == 0 else _level(self.hist.state(k - 1))
        Dq = Dv = None
        if self.rows == 3 and k == 0:
            stp = self.stepper
            sc0 = kernel_scheme(stp.init_coef, stp.scale, stp.b0, stp.b1, split=True)
            Dq, Dv = converged_blocks(stp, sc0, _level(out.state))
        elif self.rows == 3:
            Dq, Dv = data[1].copy(), data[2].copy()
        self.python[k] = _PythonStep(out.factor, Dq, Dv, _level(out.state), old)

    def after_chunk(self, k0: int, k: int) -> None:
        self._beside()

    def _beside(self) -> None:
        """Start the work beside the run (once), raise its error if it has failed."""
        if self.beside is not None:
            self.beside.start()
            self.beside.check()

    def _per_step(self, F) -> int:
        s = self.system
        itemsize = np.dtype(s.dtype).itemsize
        values = sum(x.nbytes for x in (F.LU, F.piv, F.Lx, F.Ux, F.Ud) if x is not None)
        return values + 2 * s.nnz * itemsize + (3 * s.n_dof + s.n_con) * itemsize

    def chunk(self, k0: int, k1: int) -> int:
        if self.segment is None:
            return k1
        nxt = (k0 // self.segment + 1) * self.segment  # segments start at multiples
        if k0 % self.segment == 0:
            self.checkpoints[k0] = self.hist.state(k0 - 1)
        return min(k1, max(nxt, k0 + 1))

    def kernels(self, k0: int, k1: int):
        F = self.stepper.newton.factorization.loop_arrays()
        if self.segment is not None:  # checkpoint mode: the sweep recomputes the steps
            return None
        if (not self.records or not _fits(self.records[-1], F)
                or F.order is not self.patterns[-1].order):  # new sizes or a new row order
            per = self._per_step(F)
            used = sum(self._per_step_of(R) * (R.Q.shape[0] - 1) for R in self.records)
            if used + per * (self.n_steps - k0 + 1) > self.memory:
                self.segment = max(1, int(self.memory // (2 * per)))
                self.checkpoints[k0] = self.hist.state(k0 - 1)
                return None
            self.records.append(keep_record(self.system, F, self.n_steps - k0 + 1, k0,
                                            self.rows == 3, pool="adjoint"))
            self.patterns.append(F)
        R = self.records[-1]
        st = self.hist.state(k0 - 1)
        j = k0 - R.k0[0]
        R.Q[j], R.V[j], R.A[j], R.L[j] = st.q, st.v, st.a, st.lam
        return R

    def _per_step_of(self, R) -> int:
        """Bytes per step of the record ``R``."""
        return sum(x[0].nbytes for x in (R.LU, R.piv, R.Lx, R.Ux, R.Ud, R.D, R.Q, R.V, R.A,
                                         R.L) if x is not None)

    def record_of(self, k: int) -> tuple:
        """The record that holds step ``k`` (the latest one starting at or before it) and the
        factor arrays of its row order, or ``(None, None)``."""
        for R, F in zip(reversed(self.records), reversed(self.patterns)):
            if R.k0[0] <= k:
                return R, F
        return None, None


class _Replay:
    """Recomputes a segment of steps from a checkpoint with a record (checkpoint mode)."""

    def __init__(self, hook: AdjointHook, settings: Settings):
        self.hook = hook
        stp = hook.stepper
        self.stp, self.nw = stp, stp.newton
        s = hook.system
        self.H = Histories(*(np.zeros((2, w), dtype=s.dtype) for w in
                             (s.n_dof, s.n_dof, s.n_dof, s.n_dof, s.n_con)),
                           np.zeros(settings.n_steps + 1, dtype=np.int64),
                           np.zeros((settings.n_steps + 1, settings.max_iter, 2)),
                           np.zeros((settings.n_steps + 1, 2)), False)

    def segment(self, c: int, k1: int) -> list:
        """The records of the compiled steps ``c .. k1 - 1`` recomputed from the checkpoint at
        ``c``: a list of ``(K, F)`` in time order, a new one where a refused pivot gives the
        factorization a new row order (``F``: the factor arrays of the record's row order)."""
        st = self.hook.checkpoints[c]
        H, stp, nw = self.H, self.stp, self.nw
        j = (c - 1) % 2
        H.Q[j], H.V[j], H.A[j], H.L[j], H.G[j] = st.q, st.v, st.a, st.lam, st.g
        pieces = []
        k = c
        while k < k1:
            F = nw.factorization.loop_arrays()
            K = keep_record(self.hook.system, F, k1 - k, k, self.hook.rows == 3,
                            pool="adjoint")
            j = (k - 1) % 2
            K.Q[0], K.V[0], K.A[0], K.L[0] = H.Q[j], H.V[j], H.A[j], H.L[j]
            k_next, status, bad, it, z = run_steps(stp.M, stp.T, stp.P, stp.scheme_of(),
                                                   nw.csc, F, nw.options(), nw.work(), H, k,
                                                   k1, K)
            if k_next > k:
                pieces.append((K, F))
            if status == PIVOT_REFUSED:  # a new row order for this matrix, then on
                nw.factorization._new_row_order(nw.work().data[0])
            elif status != CONVERGED:  # pragma: no cover - the primal converged here
                raise RuntimeError(f"a recomputed step failed (status {status} at {k_next})")
            k = k_next
        return pieces
