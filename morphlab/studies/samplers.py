"""Design tables for :func:`~.sweep.sweep`: grids, space-filling samples, random samples.

Every sampler returns a dict of variable name -> ``(n,)`` float array, which ``sweep`` takes
as it is (and ``pandas.DataFrame`` turns into a table). ``bounds`` are ``{name: (low, high)}``.

* :func:`full_factorial`: every combination of given levels (a grid).
* :func:`latin_hypercube`: each variable's range cut into ``n`` equal strata, one sample in
  each, strata paired at random (McKay, Beckman & Conover 1979).
* :func:`sobol`, :func:`halton`: low-discrepancy sequences, scrambled (SciPy's ``qmc``);
  Sobol' points are balanced only in powers of two.
* :func:`monte_carlo`: independent random draws from :func:`normal`, :func:`uniform`, SciPy
  frozen distributions, and :func:`correlated_normal` for variables drawn together.

SciPy's statistics module is imported on first use (it takes a while to load).
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Mapping, Sequence

import numpy as np

from ..errors import StudyError


def _bounds(bounds: Mapping) -> tuple[list[str], np.ndarray, np.ndarray]:
    if not isinstance(bounds, Mapping) or not bounds:
        raise StudyError("bounds must be a non-empty dict of name -> (low, high)")
    names, low, high = [], [], []
    for name, pair in bounds.items():
        try:
            a, b = (float(x) for x in pair)
        except (TypeError, ValueError) as exc:
            raise StudyError(f"bounds of {name!r} must be (low, high), got {pair!r}") from exc
        if not (np.isfinite(a) and np.isfinite(b) and a < b):
            raise StudyError(f"bounds of {name!r} must be finite with low < high, got {pair!r}")
        names.append(str(name))
        low.append(a)
        high.append(b)
    return names, np.array(low), np.array(high)


def _count(n) -> int:
    if isinstance(n, bool) or not isinstance(n, int | np.integer) or n < 1:
        raise StudyError(f"the number of samples must be a positive integer, got {n!r}")
    return int(n)


def _scaled(unit: np.ndarray, names, low, high) -> dict[str, np.ndarray]:
    """Points of the unit cube ``(n, d)`` mapped to the bounds, as columns."""
    x = low + unit * (high - low)
    return {name: x[:, j].copy() for j, name in enumerate(names)}


def full_factorial(axes: Mapping, levels: int | Mapping | None = None) -> dict[str, np.ndarray]:
    """Every combination of the levels of each variable; the first variable varies slowest.

    Parameters
    ----------
    axes : dict
        ``{name: sequence of levels}``, or with ``levels`` ``{name: (low, high)}``.
    levels : int or dict of str -> int, optional
        Equally spaced levels per variable between its bounds (ends included).
    """
    if not isinstance(axes, Mapping) or not axes:
        raise StudyError("axes must be a non-empty dict of name -> levels")
    if levels is not None:
        names, low, high = _bounds(axes)
        counts = levels if isinstance(levels, Mapping) else dict.fromkeys(names, levels)
        if set(counts) != set(names):
            raise StudyError(f"levels given for {sorted(counts)}, variables are {names}")
        axes = {n: np.linspace(a, b, _count(counts[n])) for n, a, b in zip(names, low, high)}
    grids = []
    for name, values in axes.items():
        arr = np.asarray(values, dtype=float).ravel() if isinstance(
            values, Sequence | np.ndarray) else None
        if arr is None or arr.size == 0 or not np.all(np.isfinite(arr)):
            raise StudyError(f"levels of {name!r} must be a non-empty sequence of finite "
                             f"numbers, got {values!r}")
        grids.append(arr)
    points = np.array(list(itertools.product(*grids)), dtype=float)
    return {str(name): points[:, j].copy() for j, name in enumerate(axes)}


def latin_hypercube(bounds: Mapping, n: int, *, seed=None) -> dict[str, np.ndarray]:
    """``n`` samples with exactly one in each of the ``n`` equal strata of every variable."""
    names, low, high = _bounds(bounds)
    n = _count(n)
    rng = np.random.default_rng(seed)
    strata = np.stack([rng.permutation(n) for _ in names], axis=1)
    unit = (strata + rng.random((n, len(names)))) / n
    return _scaled(unit, names, low, high)


def sobol(bounds: Mapping, n: int, *, seed=None, scramble: bool = True
          ) -> dict[str, np.ndarray]:
    """The first ``n`` points of a (scrambled) Sobol' sequence; ``n`` a power of two."""
    names, low, high = _bounds(bounds)
    n = _count(n)
    if n & (n - 1):
        below = 2 ** int(math.log2(n))
        raise StudyError(f"a Sobol' sample is balanced only for a power of two points, got "
                         f"n={n}: use {below} or {2 * below} (or latin_hypercube/halton)")
    from scipy.stats import qmc

    unit = qmc.Sobol(d=len(names), scramble=scramble, seed=seed).random_base2(
        int(math.log2(n)))
    return _scaled(unit, names, low, high)


def halton(bounds: Mapping, n: int, *, seed=None, scramble: bool = True
           ) -> dict[str, np.ndarray]:
    """The first ``n`` points of a (scrambled) Halton sequence."""
    names, low, high = _bounds(bounds)
    n = _count(n)
    from scipy.stats import qmc

    unit = qmc.Halton(d=len(names), scramble=scramble, seed=seed).random(n)
    return _scaled(unit, names, low, high)


class normal:
    """Normal distribution with mean ``mean`` and standard deviation ``std`` (> 0)."""

    def __init__(self, mean: float, std: float):
        self.mean, self.std = float(mean), float(std)
        if not (np.isfinite(self.mean) and np.isfinite(self.std) and self.std > 0):
            raise StudyError(f"normal needs a finite mean and std > 0, got {mean!r}, {std!r}")

    def draw(self, rng, n: int) -> np.ndarray:
        return rng.normal(self.mean, self.std, n)

    def __repr__(self) -> str:
        return f"normal({self.mean!r}, {self.std!r})"


class uniform:
    """Uniform distribution on ``[low, high)``."""

    def __init__(self, low: float, high: float):
        self.low, self.high = float(low), float(high)
        if not (np.isfinite(self.low) and np.isfinite(self.high) and self.low < self.high):
            raise StudyError(f"uniform needs finite low < high, got {low!r}, {high!r}")

    def draw(self, rng, n: int) -> np.ndarray:
        return rng.uniform(self.low, self.high, n)

    def __repr__(self) -> str:
        return f"uniform({self.low!r}, {self.high!r})"


class correlated_normal:
    """Jointly normal variables: mean ``(d,)``, covariance ``(d, d)`` (symmetric, positive
    definite). In :func:`monte_carlo` it sits under a tuple of ``d`` names."""

    def __init__(self, mean, cov):
        self.mean = np.asarray(mean, dtype=float).ravel()
        self.cov = np.asarray(cov, dtype=float)
        d = self.mean.size
        if self.cov.shape != (d, d) or not np.array_equal(self.cov, self.cov.T):
            raise StudyError(f"correlated_normal needs a symmetric ({d}, {d}) covariance for "
                             f"{d} means, got shape {self.cov.shape}")
        try:
            self.factor = np.linalg.cholesky(self.cov)
        except np.linalg.LinAlgError as exc:
            raise StudyError("correlated_normal: the covariance is not positive "
                             "definite") from exc

    def draw(self, rng, n: int) -> np.ndarray:
        return self.mean + rng.standard_normal((n, self.mean.size)) @ self.factor.T


def _draw(dist, rng, n: int, key) -> np.ndarray:
    if hasattr(dist, "draw"):
        return dist.draw(rng, n)
    if hasattr(dist, "rvs") and hasattr(dist, "ppf"):  # a SciPy frozen distribution
        return np.asarray(dist.rvs(size=n, random_state=rng), dtype=float)
    raise StudyError(f"distribution of {key!r} must be normal(...), uniform(...), "
                     f"correlated_normal(...) or a SciPy frozen distribution, got {dist!r}")


def monte_carlo(distributions: Mapping, n: int, *, seed=None) -> dict[str, np.ndarray]:
    """``n`` random designs: ``{name: distribution}`` drawn independently, and
    ``{(name, ...): correlated_normal(mean, cov)}`` for variables drawn together."""
    if not isinstance(distributions, Mapping) or not distributions:
        raise StudyError("distributions must be a non-empty dict of name -> distribution")
    n = _count(n)
    rng = np.random.default_rng(seed)
    out = {}
    for key, dist in distributions.items():
        names = list(key) if isinstance(key, tuple) else [key]
        joint = isinstance(dist, correlated_normal)
        if joint != isinstance(key, tuple) or (joint and len(names) != dist.mean.size):
            raise StudyError(f"a correlated_normal of d variables goes under a tuple of d "
                             f"names, other distributions under one name; got {key!r}: {dist!r}")
        x = _draw(dist, rng, n, key).reshape(n, len(names))
        out.update({str(name): x[:, j].copy() for j, name in enumerate(names)})
    return out
