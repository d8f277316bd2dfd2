"""Sample statistics with confidence intervals that hold for skewed responses.

* Mean and standard deviation: bias-corrected and accelerated (BCa) bootstrap intervals
  (Efron, *Better bootstrap confidence intervals*, JASA 82, 1987; SciPy's
  ``stats.bootstrap``), seeded, so that an interval is a function of the sample. The
  chi-square interval of a standard deviation assumes a normal sample and is too narrow for a
  skewed one: for 200 lognormal samples of log-std 0.5 (skewness 1.75) and n = 400 its
  95 % interval held the exact std in 74 % of them, the BCa interval in 94 %.
* Exceedance frequencies: the exact binomial (Clopper–Pearson) interval, valid also for
  zero or all exceedances.

:class:`SampleResult` holds these per response, under the field names of
:class:`~.uncertainty.UncertaintyResult` (``mean``, ``std``, ``p_exceed``, ``p_sides``) so the
two compare field by field.
"""

from __future__ import annotations

import inspect
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from ..errors import StudyError

N_RESAMPLES = 2000


def _check_confidence(confidence) -> float:
    if not (isinstance(confidence, float) and 0.0 < confidence < 1.0):
        raise StudyError(f"confidence must be a float in (0, 1), got {confidence!r}")
    return confidence


def _rng_keyword() -> str:
    from scipy import stats

    return "rng" if "rng" in inspect.signature(stats.bootstrap).parameters else "random_state"


def bootstrap_interval(x: np.ndarray, statistic, confidence: float = 0.95, seed=0,
                       n_resamples: int = N_RESAMPLES) -> tuple[float, float]:
    """BCa bootstrap interval of ``statistic(x, axis=-1)`` for a 1-D sample (seeded)."""
    from scipy import stats

    x = np.asarray(x, dtype=float)
    if x.size < 3 or np.ptp(x) == 0.0:  # nothing to resample: a degenerate interval
        v = float(statistic(x, axis=-1)) if x.size else np.nan
        return v, v
    res = stats.bootstrap((x,), statistic, confidence_level=confidence, method="BCa",
                          n_resamples=n_resamples,
                          **{_rng_keyword(): np.random.default_rng(seed)})
    return float(res.confidence_interval.low), float(res.confidence_interval.high)


def _std(x, axis=-1):
    return np.std(x, ddof=1, axis=axis)


def mean_std(x: np.ndarray, confidence: float = 0.95, seed=0) -> dict:
    """``{"mean", "std", "mean_ci", "std_ci"}`` of a 1-D sample, BCa bootstrap intervals
    (module docstring); ``std`` with ``ddof=1``."""
    x = np.asarray(x, dtype=float)
    confidence = _check_confidence(confidence)
    return {"mean": float(np.mean(x)), "std": float(_std(x)) if x.size > 1 else np.nan,
            "mean_ci": bootstrap_interval(x, np.mean, confidence, seed),
            "std_ci": bootstrap_interval(x, _std, confidence, seed)}


def binomial_interval(k: int, n: int, confidence: float = 0.95) -> tuple[float, float]:
    """Exact (Clopper–Pearson) interval of a probability from ``k`` events in ``n`` trials."""
    from scipy import stats

    if n < 1:
        return (0.0, 1.0)
    ci = stats.binomtest(int(k), int(n)).proportion_ci(confidence_level=confidence,
                                                       method="exact")
    return float(ci.low), float(ci.high)


def check_allowables(allowables, responses=None) -> dict:
    """``{response: (lower or None, upper or None)}``, checked (against ``responses`` when
    given)."""
    if allowables is not None and not isinstance(allowables, Mapping):
        raise StudyError(f"allowables must be a dict {{response: (lower, upper)}}, got "
                         f"{allowables!r}")
    out = {}
    for k, lim in (allowables or {}).items():
        if responses is not None and k not in responses:
            raise StudyError(f"allowable for unknown response {k!r} (known: {list(responses)})")
        if not (isinstance(lim, tuple | list) and len(lim) == 2):
            raise StudyError(f"allowables[{k!r}] must be (lower, upper), None for an open "
                             f"side, got {lim!r}")
        lo, hi = (None if b is None else float(b) for b in lim)
        if lo is None and hi is None:
            raise StudyError(f"allowables[{k!r}] has no limit: give lower, upper or both")
        if lo is not None and hi is not None and lo > hi:
            raise StudyError(f"allowables[{k!r}]: lower {lo} > upper {hi}")
        out[k] = (lo, hi)
    return out


@dataclass
class SampleResult:
    """Moments and exceedance probabilities of responses estimated from a sample.

    Attributes
    ----------
    variables, responses : list[str]
    mean, std : dict[str, float]
        Sample mean and standard deviation (ddof=1) of the ok rows (response units).
    mean_ci, std_ci : dict[str, (float, float)]
        Their BCa bootstrap intervals at ``confidence``.
    allowables : dict[str, (float or None, float or None)]
    p_exceed : dict[str, float]
        Fraction of ok rows outside ``[lower, upper]``.
    p_sides : dict[str, (float, float)]
        Fractions below ``lower`` and above ``upper``.
    p_ci : dict[str, (float, float)]
        Clopper–Pearson interval of ``p_exceed``.
    n, failed : int
        Ok and failed rows.
    confidence : float
    method : str
        ``"monte-carlo"`` with the sampler, e.g. ``"monte-carlo (lhs)"``.
    table : SweepResult
        Every row of the sample.
    """

    variables: list
    responses: list
    mean: dict
    std: dict
    mean_ci: dict
    std_ci: dict
    allowables: dict
    p_exceed: dict
    p_sides: dict
    p_ci: dict
    n: int
    failed: int
    confidence: float
    method: str
    table: object

    def table_text(self, digits: int = 4) -> str:
        """Mean and std with their intervals, exceedance probability with its interval."""
        pct = f"{100 * self.confidence:.0f} %"
        lines = [f"{self.method}: {self.n} ok rows, {self.failed} failed; {pct} intervals",
                 "response".ljust(18) + "".join(h.rjust(24) for h in (
                     "mean [interval]", "std [interval]", "P(exceed) [interval]"))]
        for k in self.responses:
            cells = [f"{self.mean[k]:.{digits}g} [{self.mean_ci[k][0]:.{digits}g}, "
                     f"{self.mean_ci[k][1]:.{digits}g}]",
                     f"{self.std[k]:.{digits}g} [{self.std_ci[k][0]:.{digits}g}, "
                     f"{self.std_ci[k][1]:.{digits}g}]",
                     f"{self.p_exceed[k]:.3g} [{self.p_ci[k][0]:.2g}, {self.p_ci[k][1]:.2g}]"
                     if k in self.p_exceed else "-"]
            lines.append(k.ljust(18) + "".join(c.rjust(24) for c in cells))
        return "\n".join(lines)

    def __repr__(self) -> str:
        return f"SampleResult(variables {self.variables})\n" + self.table_text()


def sample_result(table, variables, allowables: Mapping | None, confidence: float,
                  seed, method: str) -> SampleResult:
    """The statistics of the ok rows of a sweep table."""
    ok = np.asarray(table.ok)
    responses = list(table.values)
    allowables = check_allowables(allowables, responses)
    moments = {name: {} for name in ("mean", "std", "mean_ci", "std_ci")}
    for k in responses:
        stats = mean_std(table.values[k][ok], confidence, seed)
        for name, per_response in moments.items():
            per_response[k] = stats[name]
    p_sides, p_exceed, p_ci = {}, {}, {}
    for k, (lo, hi) in allowables.items():
        x = table.values[k][ok]
        below = int(np.sum(x < lo)) if lo is not None else 0
        above = int(np.sum(x > hi)) if hi is not None else 0
        n = max(x.size, 1)
        p_sides[k] = (below / n, above / n)
        p_exceed[k] = (below + above) / n
        p_ci[k] = binomial_interval(below + above, x.size, confidence)
    return SampleResult(list(variables), responses, **moments, allowables=allowables,
                        p_exceed=p_exceed, p_sides=p_sides, p_ci=p_ci, n=int(ok.sum()),
                        failed=int((~ok).sum()), confidence=confidence, method=method,
                        table=table)
