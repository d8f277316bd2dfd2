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

from ..compile.system import System, SystemArrays, TimeArrays
from ..errors import ConvergenceError, NonFiniteError, SingularMatrixError
from ..kernels.assemble import apply_correction, step_matrix, step_residual
from ..kernels.newton import (
    CONVERGED,
    NONFINITE_CORRECTION,
    NONFINITE_RESIDUAL,
    NOT_CONVERGED,
    PIVOT_REFUSED,
    SINGULAR,
    newton_loop,
)
from .linalg import Factor, StepFactorization
from .scheme import StepCoefficients
from .superlu import PIVOT_THRESHOLD


@dataclass
class StepProblem:
    """The equations of one Newton solve.

    ``system``: whose equations they are (their names in messages); ``S``: its kernel arrays;
    ``qh, vh`` (n_dof,): the predictors; ``coef``: the step coefficients (``coef.h == 0``: the
    linear initial solve); ``R_hist`` (n,): the constant old-level share of the residual;
    ``ta``: the time data at the new level; ``scale``: of the constraint rows and multipliers;
    ``b0, b1``: the stabilization; ``t``, ``step``: where, for messages.
    """

    system: System
    S: SystemArrays
    qh: np.ndarray
    vh: np.ndarray
    coef: StepCoefficients
    R_hist: np.ndarray
    ta: TimeArrays
    scale: float
    b0: float
    b1: float
    t: float
    step: int

    @property
    def names(self) -> list[str]:
        """The name of each equation / unknown."""
        return self.system.unknown_names

    def residual(self, z, n_dof: int, R=None):
        """``(R, |R|)`` at ``z`` (``|R|`` NaN or Inf if an entry is)."""
        if R is None:
            dt = np.result_type(z.dtype, self.qh.dtype, self.R_hist.dtype)
            R = np.empty(z.shape[0], dtype=dt)
        ssq = step_residual(*self.residual_args(z, n_dof, R))
        return R, float(np.sqrt(ssq))

    def residual_args(self, z, n_dof: int, R) -> tuple:
        """The arguments of :func:`~morphlab.kernels.assemble.step_residual` at ``z`` into
        ``R`` (also what ``morphlab.solve.precompile`` compiles it for)."""
        dt = R.dtype
        # astype(copy=False): no copies in the Newton loop when the dtypes already agree
        return (self.S, z.astype(dt, copy=False), self.qh.astype(dt, copy=False),
                self.vh.astype(dt, copy=False), self.coef.bh2, self.coef.gh, self.scale,
                self.coef.arrays.w_new, self.b0, self.b1, *self.ta, n_dof,
                self.R_hist.astype(dt, copy=False), R)

    def fill(self, z, data) -> None:
        """The exact step matrix at ``z`` into the CSC values ``data``."""
        step_matrix(self.S, z, self.qh, self.vh, self.coef.bh2, self.coef.gh, self.scale,
                    self.coef.arrays.w_new, self.b0, self.b1, self.ta.F, data)


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
        Use the compiled loop once the factorization has settled.
    polish : int
        Extra iterations after convergence (complex-step reference runs: the imaginary part
        converges one iteration behind the real part).

    Attributes
    ----------
    n_factorizations : int
        Factorizations so far.
    """

    def __init__(self, system: System, dtype, *, tol: float, max_iter: int, dense_max: int,
                 compiled: bool = True, polish: int = 0):
        self.system = system
        self.dtype = np.dtype(dtype)
        self.tol = tol
        self.max_iter = max_iter
        self.compiled = compiled
        self.polish = polish
        self.n_dof = system.n_dof
        self.factorization = StepFactorization(system.indices, system.indptr, system.n,
                                               self.dtype, dense_max)
        self.data = np.zeros(system.nnz, dtype=self.dtype)  # CSC values of the step matrix
        self.n_factorizations = 0
        self.kept: Factor | None = None  # the factorization modified Newton keeps
        self._scratch = None  # buffers of the compiled loop, allocated on first use

    def factor(self, p: StepProblem, z) -> Factor:
        """Fill and factor the exact step matrix at ``z``."""
        p.fill(z, self.data)
        try:
            lu = self.factorization(self.data)
        except RuntimeError as exc:
            raise singular(p, str(exc)) from None
        self.n_factorizations += 1
        return lu

    def solve(self, p: StepProblem, z) -> tuple:
        """Full Newton from ``z``: ``(z, factor, iterations, history)``, the factor taken at the
        iterate before the final correction, ``history`` (iterations, 2) the ``(|R|,
        correction)`` of each iteration."""
        first, hist = 1, np.zeros((0, 2))
        fac = self.factorization
        if (self.compiled and fac.settled and (fac.dense or self.polish == 0)
                and z.dtype == p.qh.dtype == p.vh.dtype == p.R_hist.dtype == self.dtype):
            z, lu, it, hist = self._compiled(p, z)
            if lu is not None:
                return z, lu, it, hist
            first = it  # a sparse pivot failed at iteration ``it``: redo it from here
        L = self.system.length_scale
        err = np.inf
        rows = list(map(tuple, hist))
        for it in range(first, self.max_iter + 1):
            z, lu, r_norm, dz_max = self._iteration(p, z, it)
            # linear in z for the initial accelerations (h = 0): one solve is exact
            err = 0.0 if p.coef.h == 0.0 else p.coef.bh2 * dz_max / L
            rows.append((r_norm, err))
            if err <= self.tol:
                for _ in range(self.polish):
                    R, _ = p.residual(z, self.n_dof)
                    lu = self.factor(p, z)
                    z = z + lu.solve(-R)
                return z, lu, it, np.array(rows)
        raise not_converged(p, z, self, err)

    def _iteration(self, p: StepProblem, z, it: int):
        """One iteration from ``z``: ``(z + dz, factor at z, |R(z)|, |dz_a|_max)``."""
        R, r_norm = p.residual(z, self.n_dof)
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

    def _compiled(self, p: StepProblem, z):
        """:meth:`solve` in one compiled call. Returns its tuple, or ``(z, None, it, history)``
        when a sparse pivot failed the threshold at iteration ``it`` (``z`` the iterate whose
        matrix it was, ``history`` the iterations before)."""
        system, fac = self.system, self.factorization
        if self._scratch is None:  # residual (read on failure), (|R|, err) rows
            self._scratch = (np.empty(system.n, dtype=self.dtype), np.zeros((self.max_iter, 2)))
        R, hist = self._scratch
        arrays = fac.loop_arrays()  # fresh factors every step: the sensitivities keep them
        z, it, status, bad = newton_loop(*self.loop_args(p, z, R, arrays, hist))
        if status == CONVERGED:
            self.n_factorizations += it + self.polish
            return z, fac.factor_of(arrays), it, hist[:it].copy()
        # no complete factorization at `it` unless the failure came after it
        self.n_factorizations += it if status in (NONFINITE_CORRECTION, NOT_CONVERGED) else it - 1
        if status == PIVOT_REFUSED:
            return z, None, it, hist[:it - 1].copy()
        r_norm = float(hist[it - 1, 0])
        if status == NONFINITE_RESIDUAL:
            raise non_finite_residual(p, R, it)
        if status == SINGULAR:
            raise singular(p, "no nonzero pivot left for the column of "
                           f"{system.unknown_names[bad]}", r_norm, R)
        if status == NONFINITE_CORRECTION:
            raise non_finite_correction(p, z, r_norm)
        raise not_converged(p, z, self, float(hist[it - 1, 1]))

    def loop_args(self, p: StepProblem, z, R, arrays: tuple, hist) -> tuple:
        """The arguments of :func:`~morphlab.kernels.newton.newton_loop` for ``p`` from ``z``:
        residual ``R`` (n,), factor ``arrays`` (``StepFactorization.loop_arrays``), history
        ``hist`` (max_iter, 2) (also what ``morphlab.solve.precompile`` compiles it for)."""
        system = self.system
        return (p.S, z, p.qh, p.vh, p.coef.bh2, p.coef.gh, p.scale, p.coef.arrays.w_new, p.b0,
                p.b1, *p.ta, self.n_dof, p.R_hist, system.indices, system.indptr,
                p.coef.h == 0.0, system.length_scale, self.tol, self.max_iter, self.polish, R,
                self.data, *arrays, PIVOT_THRESHOLD, hist)

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
            R, r_norm = p.residual(z, self.n_dof)
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
            err = p.coef.bh2 * float(np.max(np.abs(dz[: self.n_dof]))) / L
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
        R, _ = p.residual(z, self.n_dof)
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
    R, _ = p.residual(z, solver.n_dof)
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
