"""Importance sampling around FORM's design points.

For a limit state with design points ``u_1 .. u_K`` (K = 1, or 2 with a second mode), ``n``
draws are split equally among the normal densities ``N(u_k, I)``; the sampling density is
their mixture ``h(u) = (1/K) Σ_k φ(u - u_k)``, and

    P_f = E_h[1[g(u) <= 0] φ(u) / h(u)],     φ(u) / h(u) = 1 / ((1/K) Σ_k exp(u·u_k - |u_k|²/2))

estimated by the mean of the ``n`` terms: unbiased whatever the design points (they only
decide the variance), with the standard error of a stratified sample,
``SE² = Σ_k (1/K)² s_k² / n_k`` (``s_k²`` the sample variance of the terms drawn from
component k), and the coefficient of variation ``SE / P_f`` (e.g. Melchers & Beck,
*Structural Reliability Analysis and Prediction*, 3rd ed., Wiley 2018, §3.5; Au & Beck,
*A new adaptive importance sampling scheme*, Struct. Safety 21, 1999, for the mixture).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from scipy.special import ndtri

from ..errors import StudyError
from .distributions import joint
from .function_task import values_only
from .reliability import ReliabilityResult, _check_fixed, _designs
from .statistics import _check_confidence
from .sweep import sweep


def _weights(U: np.ndarray, centres: list[np.ndarray]) -> np.ndarray:
    """``φ(u) / h(u)`` of the mixture (module docstring), (n,)."""
    terms = np.stack([np.exp(U @ c - 0.5 * c @ c) for c in centres])
    return 1.0 / np.mean(terms, axis=0)


def importance_sampling(task, distributions, result: ReliabilityResult, n: int, *,
                        fixed=None, seed=0, executor=None, confidence: float = 0.95,
                        progress: bool | Callable[[int, int], object] = False
                        ) -> ReliabilityResult:
    """Importance sampling around the design points of a FORM result (module docstring).

    Parameters
    ----------
    task : SimulationTask, FunctionTask or callable
        The model of the FORM result (run here for values only).
    distributions : JointDistribution or dict
        The random variables of the FORM result.
    result : ReliabilityResult
        From :func:`~.reliability.form`; its limit states are filled in place.
    n : int
        Draws per limit state (split equally among its modes); all limit states in one sweep.
    fixed : dict[str, float], optional
        The task's other design variables, as for FORM.
    seed : int
    executor : None, "serial" or concurrent.futures.Executor
        As for :func:`~.sweep.sweep`.
    confidence : float
        Of the intervals ``p_is ± z SE`` (normal approximation).
    progress : bool or callable
        Of the draws' sweep (:func:`~.sweep.sweep`): a progress bar, or ``progress(n_done,
        n_total)``.

    Returns
    -------
    ReliabilityResult
        ``result``, with ``p_is``, ``is_std_error``, ``is_cov``, ``is_ci``, ``is_n``,
        ``is_failures`` and ``is_failed_runs`` of each limit state and
        ``method="importance-sampling"``.
    """
    dist = joint(distributions)
    fixed = _check_fixed(fixed, dist.names)
    confidence = _check_confidence(confidence)
    if isinstance(n, bool) or not isinstance(n, int | np.integer) or n < 4:
        raise StudyError(f"n must be an integer >= 4 (draws per limit state), got {n!r}")
    if not isinstance(result, ReliabilityResult) or list(result.variables) != list(dist.names):
        raise StudyError(f"result must be the ReliabilityResult of FORM over the variables "
                         f"{dist.names}")
    keys = [k for k, ls in result.limit_states.items() if ls.modes]
    if not keys:
        raise StudyError("no limit state of the FORM result has a design point")
    rng = np.random.default_rng(seed)
    blocks = []  # (key, component index of every draw, draws)
    for key in keys:
        centres = [m["u"] for m in result.limit_states[key].modes]
        comp = np.arange(n) * len(centres) // n  # equal shares, in order
        blocks.append((key, comp, np.stack(centres)[comp]
                       + rng.standard_normal((n, len(dist)))))
    U = np.concatenate([b[2] for b in blocks])
    table = sweep(values_only(task), _designs(dist, fixed, dist.from_standard(U)),
                  executor=executor, progress=progress)
    z = float(ndtri(0.5 + confidence / 2.0))
    for j, (key, comp, u) in enumerate(blocks):
        ls = result.limit_states[key]
        rows = slice(j * n, (j + 1) * n)
        ok = np.asarray(table.ok[rows])
        r = table.values[ls.response][rows]
        fail = ok & ((r > ls.limit) if ls.side == "upper" else (r < ls.limit))
        terms = np.where(fail, _weights(u, [m["u"] for m in ls.modes]), 0.0)[ok]
        comp = comp[ok]
        K = len(ls.modes)
        p = float(np.mean(terms)) if terms.size else np.nan
        var = sum(np.var(terms[comp == k], ddof=1) / max(np.sum(comp == k), 1)
                  for k in range(K) if np.sum(comp == k) > 1) / K**2
        se = float(np.sqrt(var))
        ls.p_is, ls.is_std_error = p, se
        ls.is_cov = se / p if p > 0 else np.inf
        ls.is_ci = (max(0.0, p - z * se), p + z * se)
        ls.is_n, ls.is_failures, ls.is_failed_runs = int(ok.sum()), int(fail.sum()), \
            int((~ok).sum())
    result.runs += len(U)
    result.method = "importance-sampling"
    result._collect()
    return result
