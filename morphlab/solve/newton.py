"""Newton–Raphson on the step equations, written once for every analysis.

A :class:`StepProblem` is one set of step equations ``R(z) = R_hist + E(z) = 0`` in the
unknowns ``z = (a, lam/scale)``, with ``q = q_hat + bh2 a`` and ``q' = v_hat + gh a``
(``docs/theory.md`` §5): a time step, the initial accelerations, or a static equilibrium. A
:class:`NewtonSolver` solves such problems for one compiled system: full Newton with the exact
step matrix (quadratic convergence, the factorization the sensitivities reuse) — in one
compiled call once the factorization has settled (:func:`morphlab.kernels.newton.newton_loop`,
the same kernels and arithmetic as the loop from Python, so the same iterates) — or modified
Newton (a factorization kept over iterations and steps). Failures raise the errors of
:mod:`morphlab.errors` naming the time, the step and the dominant equations.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..compile.system import System
from ..errors import ConvergenceError, NonFiniteError, SingularMatrixError
from ..kernels.assemble import Step, apply_correction, matrix, residual
from ..kernels.ffrf import scratch
from ..kernels.newton import (
    CONVERGED,
    NONFINITE_CORRECTION,
    NONFINITE_RESIDUAL,
    NOT_CONVERGED,
    PIVOT_REFUSED,
    SINGULAR,
    Csc,
    Options,
    Work,
)
from ..kernels.system import Parts, Times
from ..kernels.types import Level
from .linalg import Factor, SingularFactor, StepFactorization
from .superlu import PIVOT_THRESHOLD


@dataclass
class StepProblem:
    """The equations of one Newton solve.

    ``system``: whose equations they are (their names in messages); ``M``, ``T``, ``P``: its
    kernel arrays, the time values and the parts evaluated (all); ``s``: the step's
    :class:`~morphlab.kernels.assemble.Step` (predictors, old-level share, coefficients, time
    index); ``linear``: the initial solve (one iteration is exact); ``t``, ``step``: where, for
    messages; ``real``: a complex system's ``(M, T)`` with the real parts of their values
    (:func:`~morphlab.compile.system.real_parts`), for its real step matrix (None: a real
    system).
    """

    system: System
    M: tuple
    T: Times
    P: Parts
    s: Step
    linear: bool
    t: float
    step: int
    real: tuple | None = None

    @property
    def names(self) -> list[str]:
        """The name of each equation / unknown."""
        return self.system.unknown_names

    @property
    def n_dof(self) -> int:
        return self.system.n_dof

    def level(self, z) -> Level:
        """The state at the unknowns ``z``: ``q = q_hat + bh2 a``, ``q' = v_hat + gh a``,
        ``lam = scale z_lam`` (as :func:`morphlab.kernels.assemble.level`)."""
        s, n_dof = self.s, self.n_dof
        a = np.ascontiguousarray(z[:n_dof])
        return Level(s.qh + s.bh2 * a, s.vh + s.gh * a, a,
                     np.ascontiguousarray(z[n_dof:] * s.w.scale))

    def residual(self, z, W, R=None):
        """``(R, |R|)`` at ``z`` (``|R|`` NaN or Inf if an entry is); ``W``: the bodies'
        scratch in ``z``'s dtype."""
        R = np.array(self.s.R_hist, dtype=z.dtype) if R is None else R
        residual(self.M, self.level(z), self.s.w, self.T, self.s.t, self.s.k, self.P,
                 self.n_dof, R, W)
        ssq = float(np.sum(R.real * R.real + R.imag * R.imag))
        return R, float(np.sqrt(ssq))

    def fill(self, z, data, W) -> None:
        """The step matrix at ``z`` into the CSC values ``data`` (m, nnz): row 0 the Newton
        matrix (and ``Dq``, ``Dv`` in rows 1, 2 when the step's coefficients ask); ``W``: the
        bodies' scratch in ``data``'s dtype. A complex system's: the real step matrix
        (:class:`NewtonSolver`), that of the real parts of the data and of ``z``."""
        M, x, T = self.M, self.level(z), self.T
        if self.real is not None:
            M, T = self.real
            x = Level(*(np.ascontiguousarray(a.real) for a in x))
        matrix(M, x, self.s.w, T, self.s.t, self.s.k, self.s.C, data, W)


class NewtonSolver:
    """Solves :class:`StepProblem` s of one compiled system.

    Parameters
    ----------
    system : System
    dtype : numpy dtype
        Of the unknowns and the step matrices.
    tol, max_iter :
        Converged when the position correction ``bh2 |da|_max`` is at most ``tol`` times the
        model size; at most ``max_iter`` iterations.
    dense_max : int
        See :class:`morphlab.solve.linalg.StepFactorization`.
    compiled : bool
        Let the run solve its steps in compiled chunks once the factorization has settled
        (:mod:`morphlab.solve.timeloop`).
    polish : int
        Extra iterations after convergence. A complex run takes at least one: its imaginary
        part converges one iteration behind its real part.
    rows : int
        Rows of the fill (1: the Newton matrix; 3: with ``Dq`` and ``Dv``, a sensitivity run).

    A complex run (a complex step through the run or the statics) factors the real step
    matrix: the matrix of the real parts of the data and the iterate, which is the primal's
    matrix at that iterate. The real part then follows Newton's method exactly, and each
    iteration solves the imaginary part's linear equation (the derivative's) with the exact
    matrix at the previous iterate, so the polish iteration leaves it as accurate as the real
    part (``docs/theory.md`` §6.7). A complex run compiles no complex matrix kernels and
    factors in real arithmetic.

    Attributes
    ----------
    n_factorizations : int
        Factorizations so far.
    data : (rows, nnz) float
        The last fill.
    W, W_fill :
        The bodies' scratch of the residual (in ``dtype``) and of the fill (real; the same
        object in a real run).
    """

    def __init__(self, system: System, dtype, *, tol: float, max_iter: int, dense_max: int,
                 compiled: bool = True, polish: int = 0, rows: int = 1):
        self.system = system
        self.dtype = np.dtype(dtype)
        self.tol = tol
        self.max_iter = max_iter
        self.compiled = compiled
        complex_run = self.dtype.kind == "c"
        self.polish = max(polish, 1) if complex_run else polish
        self.n_dof = system.n_dof
        # the step matrix is real in every run (a complex run's: of the real parts)
        self.factorization = StepFactorization(system.indices, system.indptr, system.n,
                                               np.dtype(float), dense_max)
        self.data = np.zeros((rows, system.nnz))
        self.W = scratch(system.count("flex"), np.zeros(1, dtype=self.dtype))
        self.W_fill = scratch(system.count("flex"), np.zeros(1)) if complex_run else self.W
        self.csc = Csc(system.indices, system.indptr)
        self.n_factorizations = 0
        self.kept: Factor | None = None  # the factorization modified Newton keeps
        self._work = None  # buffers of the compiled loop, allocated on first use

    def options(self, linear: bool = False) -> Options:
        """The compiled loop's :class:`~morphlab.kernels.newton.Options`."""
        return Options(float(self.tol), int(self.max_iter), float(self.system.length_scale),
                       int(self.polish), bool(linear), PIVOT_THRESHOLD)

    def work(self) -> Work:
        """The compiled loop's buffers (:class:`~morphlab.kernels.newton.Work`)."""
        if self._work is None:
            self._work = Work(np.empty(self.system.n, dtype=self.dtype), self.data, self.W,
                              np.zeros((self.max_iter, 2)))
        return self._work

    def factor(self, p: StepProblem, z) -> Factor:
        """Fill and factor the exact step matrix at ``z``."""
        p.fill(z, self.data, self.W_fill)
        try:
            lu = self.factorization(self.data[0])
        except SingularFactor as exc:
            raise singular(p, "no nonzero pivot left for the column of "
                           f"{self.system.unknown_names[exc.column]}") from None
        except RuntimeError as exc:
            raise singular(p, str(exc)) from None
        self.n_factorizations += 1
        return lu

    def solve(self, p: StepProblem, z) -> tuple:
        """Full Newton from ``z``: ``(z, factor, iterations, history)``, the factor taken at the
        iterate before the final correction (``data``: that fill), ``history`` (iterations,
        2) the ``(|R|, correction)`` of each iteration."""
        L = self.system.length_scale
        err = np.inf
        rows = []
        for it in range(1, self.max_iter + 1):
            z, lu, r_norm, dz_max = self._iteration(p, z, it)
            # linear in z for the initial accelerations: one solve is exact
            err = 0.0 if p.linear else p.s.bh2 * dz_max / L
            rows.append((r_norm, err))
            if err <= self.tol:
                for _ in range(self.polish):
                    R, _ = p.residual(z, self.W)
                    lu = self.factor(p, z)
                    z = z + lu.solve(-R)
                return z, lu, it, np.array(rows)
        raise not_converged(p, z, self, err)

    def _iteration(self, p: StepProblem, z, it: int):
        """One iteration from ``z``: ``(z + dz, factor at z, |R(z)|, |dz_a|_max)``."""
        R, r_norm = p.residual(z, self.W)
        if not np.isfinite(r_norm):
            raise non_finite_residual(p, R, it)
        try:
            lu = self.factor(p, z)
        except SingularMatrixError as err:
            err.step, err.residual, err.dominant = p.step, r_norm, dominant(p, R)
            raise
        z1, dz_max, finite = apply_correction(z, lu.solve(-R), self.n_dof)
        if not finite:
            raise non_finite_correction(p, z1, r_norm)
        return z1, lu, r_norm, dz_max

    def outcome(self, p: StepProblem, z, it, status, bad, F):
        """What a compiled Newton solve of step ``p`` returned (a run's compiled chunk
        stopping at this step, :mod:`morphlab.kernels.steps`): :meth:`solve`'s tuple, or the
        error it raises; ``(z, None, it, history)`` when a sparse pivot failed the threshold at
        iteration ``it``."""
        ws = self.work()
        hist = ws.hist
        if status == CONVERGED:
            self.n_factorizations += it + self.polish
            return z, self.factorization.factor_of(F), it, hist[:it].copy()
        # no complete factorization at `it` unless the failure came after it
        self.n_factorizations += it if status in (NONFINITE_CORRECTION, NOT_CONVERGED) else it - 1
        if status == PIVOT_REFUSED:
            return z, None, it, hist[:it - 1].copy()
        r_norm = float(hist[it - 1, 0])
        if status == NONFINITE_RESIDUAL:
            raise non_finite_residual(p, ws.R, it)
        if status == SINGULAR:
            raise singular(p, "no nonzero pivot left for the column of "
                           f"{self.system.unknown_names[bad]}", r_norm, ws.R)
        if status == NONFINITE_CORRECTION:
            raise non_finite_correction(p, z, r_norm)
        raise not_converged(p, z, self, float(hist[it - 1, 1]))

    def solve_modified(self, p: StepProblem, z) -> tuple:
        """Newton with the factorization kept over iterations and steps (primal runs only):
        refactor when the contraction rate of the corrections exceeds 0.3 or they grow.
        Converged when the estimated remaining error ``err theta/(1 - theta)`` is below
        ``tol`` (first iteration with a kept matrix: ``err <= tol/100``), the usual test of
        simplified Newton methods (Hairer & Wanner, Solving ODEs II, §IV.8). Returns
        :meth:`solve`'s tuple."""
        L = self.system.length_scale
        hist = []
        err_prev = None
        for it in range(1, self.max_iter + 1):
            R, r_norm = p.residual(z, self.W)
            if not np.isfinite(r_norm):
                raise non_finite_residual(p, R, it)
            fresh = self.kept is None
            if fresh:
                try:
                    self.kept = self.factor(p, z)
                except SingularMatrixError as err:
                    err.step, err.residual, err.dominant = p.step, r_norm, dominant(p, R)
                    raise
            dz = self.kept.solve(-R)
            err = p.s.bh2 * float(np.max(np.abs(dz[: self.n_dof]))) / L
            hist.append((r_norm, err))
            if not np.isfinite(err):
                self.kept = None
                continue
            theta = err / err_prev if err_prev else None
            if theta is not None and theta >= 1.0 and not fresh:
                self.kept = None  # diverging with an old matrix: refactor and retry
                err_prev = None
                continue
            z = z + dz
            if theta is None:
                done = err <= (self.tol if fresh else 1e-2 * self.tol)
            else:
                done = err * theta / max(1.0 - theta, 1e-12) <= self.tol
            if done:
                return z, self.kept, it, np.array(hist).reshape(-1, 2)
            if theta is not None and theta > 0.3:
                self.kept = None
            err_prev = err
        R, _ = p.residual(z, self.W)
        raise ConvergenceError(
            f"modified Newton did not converge at t={p.t:.6g} (step {p.step}) in "
            f"{self.max_iter} iterations (residual norm {np.linalg.norm(R):.3g}); dominant "
            f"equations: {', '.join(dominant(p, R))}", time=p.t, step=p.step,
            residual=float(np.linalg.norm(R)), dominant=dominant(p, R))


# ---------------------------------------------------------------------------------- errors
def dominant(p: StepProblem, R, k: int = 3) -> list[str]:
    """Names of the ``k`` equations with the largest residual entries."""
    names = p.names
    idx = np.argsort(-np.abs(R))[:k]
    return [f"{names[i]} ({abs(R[i]):.3g})" for i in idx]


def non_finite(p: StepProblem, x, k: int = 8) -> list[str]:
    """Names of the first ``k`` equations/unknowns with a NaN or Inf entry."""
    names = p.names
    return [names[i] for i in np.flatnonzero(~np.isfinite(x))[:k]]


def not_converged(p: StepProblem, z, solver: NewtonSolver, err) -> ConvergenceError:
    R, _ = p.residual(z, solver.W)
    r = float(np.linalg.norm(R))
    return ConvergenceError(
        f"Newton did not converge at t={p.t:.6g} (step {p.step}) in {solver.max_iter} "
        f"iterations: position correction {err:.3g} of the model size (tol "
        f"{solver.tol:.1g}), residual norm {r:.3g}; dominant equations: "
        f"{', '.join(dominant(p, R))}", time=p.t, step=p.step, residual=r,
        dominant=dominant(p, R))


def non_finite_correction(p: StepProblem, z1, r_norm) -> NonFiniteError:
    bad = non_finite(p, z1)
    return NonFiniteError(
        f"non-finite Newton correction at t={p.t:.6g} (step {p.step}) in {', '.join(bad)}",
        time=p.t, step=p.step, residual=r_norm, dominant=bad)


def non_finite_residual(p: StepProblem, R, it: int) -> NonFiniteError:
    bad = non_finite(p, R)
    return NonFiniteError(
        f"non-finite residual at t={p.t:.6g} (step {p.step}, iteration {it}) in "
        f"{', '.join(bad)}", time=p.t, step=p.step, residual=float("nan"), dominant=bad)


def singular(p: StepProblem, detail: str, r_norm=None, R=None) -> SingularMatrixError:
    err = SingularMatrixError(
        f"singular saddle-point matrix at t={p.t:.6g}: {detail}. Look for redundant joints, "
        "a body without mass in its free directions, or a mechanism locked in a singular "
        "position", time=p.t)
    if R is not None:
        err.step, err.residual, err.dominant = p.step, r_norm, dominant(p, R)
    return err
