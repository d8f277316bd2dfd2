"""Variance-based sensitivity: first- and total-order Sobol' indices through :func:`sweep`.

For independent inputs ``X_i`` and a response ``Y = f(X)`` of variance ``V``, the first-order
index ``S_i = V(E[Y | X_i]) / V`` is the share of the variance that ``X_i`` explains alone,
the total index ``S_Ti = E(V[Y | X_~i]) / V`` its share with all its interactions.

Design (Saltelli et al., *Variance based sensitivity analysis of model output. Design and
estimator for the total sensitivity index*, Comput. Phys. Commun. 181, 2010): two matrices
``A`` and ``B`` of ``n`` points each, the two halves of one scrambled Sobol' sequence in
``2d`` dimensions mapped by the inverse CDFs, and ``d`` matrices ``AB_i`` (``A`` with column
``i`` from ``B``): ``n (d + 2)`` runs, all in one sweep. Estimators (the response centred by
the mean of ``f(A)`` and ``f(B)``, ``V`` their pooled variance):

    S_i  = mean(f(B) (f(AB_i) - f(A))) / V                      (Saltelli 2010, table 2 b)
    S_Ti = mean((f(A) - f(AB_i))²) / (2 V)                       (Jansen 1999, table 2 f)

the estimators of :func:`scipy.stats.sobol_indices`. Intervals: BCa bootstrap over the ``n``
rows (a row is ``A_j``, ``B_j`` and every ``AB_ij``), seeded. A row with a failed run is left
out whole.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from ..errors import StudyError
from .distributions import joint
from .function_task import values_only
from .reliability import _check_fixed, _designs
from .statistics import _check_confidence, _rng_keyword
from .sweep import sweep


@dataclass
class SobolIndices:
    """First- and total-order Sobol' indices of responses, with intervals.

    Attributes
    ----------
    variables, responses : list[str]
    first, total : dict[str, dict[str, float]]
        ``first[response][variable]``: ``S_i``; ``total[response][variable]``: ``S_Ti``.
    first_ci, total_ci : dict[str, dict[str, (float, float)]]
        BCa bootstrap intervals at ``confidence``.
    first_se, total_se : dict[str, dict[str, float]]
        Bootstrap standard errors.
    variance, mean : dict[str, float]
        The response's variance and mean from ``A`` and ``B``.
    n : int
        Rows used (of ``n`` asked); ``runs`` the model runs, ``n (d + 2)``.
    confidence : float
    table : SweepResult
        Every run: ``A``, then ``B``, then ``AB_1 ... AB_d`` (``n`` rows each).
    """

    variables: list
    responses: list
    first: dict
    total: dict
    first_ci: dict
    total_ci: dict
    first_se: dict
    total_se: dict
    variance: dict
    mean: dict
    n: int
    runs: int
    confidence: float
    table: object = None

    def table_text(self, digits: int = 3) -> str:
        pct = f"{100 * self.confidence:.0f} %"
        lines = [f"Sobol' indices from {self.n} rows ({self.runs} runs); {pct} intervals"]
        for r in self.responses:
            lines.append(f"{r}:  " + "variable".ljust(12) + "first [interval]".rjust(26)
                         + "total [interval]".rjust(26))
            for v in self.variables:
                f, t = self.first[r][v], self.total[r][v]
                fc, tc = self.first_ci[r][v], self.total_ci[r][v]
                lines.append("    " + v.ljust(12 + len(r))
                             + f"{f:.{digits}f} [{fc[0]:.{digits}f}, {fc[1]:.{digits}f}]".rjust(26)
                             + f"{t:.{digits}f} [{tc[0]:.{digits}f}, {tc[1]:.{digits}f}]".rjust(26))
        return "\n".join(lines)

    def __repr__(self) -> str:
        return "SobolIndices\n" + self.table_text()


def saltelli_matrices(dist, n: int, seed) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``A``, ``B`` (n, d) and ``AB`` (d, n, d) in the variables (module docstring)."""
    from scipy.stats import qmc

    d = len(dist)
    unit = qmc.Sobol(d=2 * d, scramble=True, seed=seed).random_base2(int(np.log2(n)))
    A, B = dist.from_unit(unit[:, :d]), dist.from_unit(unit[:, d:])
    AB = np.repeat(A[None], d, axis=0)
    for i in range(d):
        AB[i, :, i] = B[:, i]
    return A, B, AB


def estimates(fA: np.ndarray, fB: np.ndarray, fAB: np.ndarray) -> np.ndarray:
    """``(S_1..S_d, S_T1..S_Td)`` (2d,) of one response from ``f(A)``, ``f(B)`` (n,) and
    ``f(AB)`` (d, n) (module docstring)."""
    mean = 0.5 * (np.mean(fA) + np.mean(fB))
    a, b, ab = fA - mean, fB - mean, fAB - mean
    var = np.var(np.concatenate([a, b]))
    first = np.mean(b * (ab - a), axis=-1) / var
    total = 0.5 * np.mean((a - ab) ** 2, axis=-1) / var
    return np.concatenate([first, total])


def sobol_indices(task, distributions, n: int, *, fixed=None, executor=None, seed=0,
                  confidence: float = 0.95, n_resamples: int = 999,
                  progress: bool | Callable[[int, int], object] = False) -> SobolIndices:
    """First- and total-order Sobol' indices of every response of ``task``.

    Parameters
    ----------
    task : SimulationTask, FunctionTask or callable
        The responses (values only are used; a SimulationTask runs without gradients).
    distributions : JointDistribution or dict of str -> distribution
        Independent random variables.
    n : int
        Rows, a power of two; ``n (d + 2)`` runs. The estimators' errors fall as
        ``1/sqrt(n)``; the intervals tell when ``n`` suffices.
    fixed : dict[str, float], optional
        The task's other design variables.
    executor : None, "serial" or concurrent.futures.Executor
        As for :func:`~.sweep.sweep`.
    seed : int
        Scrambling of the Sobol' sequence and the bootstrap.
    confidence : float
        Of the intervals.
    n_resamples : int
        Bootstrap resamples.
    progress : bool or callable
        Of the sweep of the ``n (d + 2)`` runs (:func:`~.sweep.sweep`): a progress bar, or
        ``progress(n_done, n_total)``.

    Returns
    -------
    SobolIndices
    """
    from scipy import stats

    dist = joint(distributions)
    if not dist.independent:
        raise StudyError("Sobol' indices by this design need independent variables; the "
                         "distributions are correlated")
    if isinstance(n, bool) or not isinstance(n, int | np.integer) or n < 4 or n & (n - 1):
        raise StudyError(f"n must be a power of two >= 4 (the Sobol' sequence is balanced "
                         f"only there), got {n!r}")
    confidence = _check_confidence(confidence)
    fixed = _check_fixed(fixed, dist.names)
    d = len(dist)
    A, B, AB = saltelli_matrices(dist, n, seed)
    X = np.concatenate([A, B, AB.reshape(d * n, d)])
    table = sweep(values_only(task), _designs(dist, fixed, X), executor=executor,
                  progress=progress)
    ok = np.asarray(table.ok).reshape(d + 2, n).all(axis=0)
    if ok.sum() < 4:
        raise StudyError(f"only {int(ok.sum())} of {n} rows ran without failure: "
                         f"{next((e for e in table.errors if e), '')}")
    responses = list(table.values)
    out = SobolIndices(list(dist.names), responses, {}, {}, {}, {}, {}, {}, {}, {},
                       int(ok.sum()), len(X), confidence, table)
    for r in responses:
        f = table.values[r].reshape(d + 2, n)[:, ok]
        fA, fB, fAB = f[0], f[1], f[2:]
        est = estimates(fA, fB, fAB)
        boot = stats.bootstrap(
            (np.arange(fA.size),),
            lambda idx, fA=fA, fB=fB, fAB=fAB: estimates(fA[idx], fB[idx], fAB[:, idx]),
            confidence_level=confidence, method="BCa", n_resamples=n_resamples,
            vectorized=False, **{_rng_keyword(): np.random.default_rng(seed)})
        lo, hi = boot.confidence_interval
        for name, sl in (("first", slice(0, d)), ("total", slice(d, 2 * d))):
            getattr(out, name)[r] = dict(zip(dist.names, est[sl].tolist()))
            getattr(out, f"{name}_ci")[r] = {v: (float(a), float(b)) for v, a, b in
                                             zip(dist.names, lo[sl], hi[sl])}
            getattr(out, f"{name}_se")[r] = dict(zip(dist.names,
                                                     boot.standard_error[sl].tolist()))
        out.variance[r] = float(np.var(np.concatenate([fA, fB])))
        out.mean[r] = float(0.5 * (np.mean(fA) + np.mean(fB)))
    return out
