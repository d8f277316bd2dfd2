"""Design tables for :func:`~.sweep.sweep`: grids, space-filling samples, random samples.

Every sampler returns a dict of variable name -> ``(n,)`` float array, which ``sweep`` takes
as it is (and ``pandas.DataFrame`` turns into a table). The space-filling samplers take
``{name: (low, high)}`` bounds (uniform variables), or distributions: ``{name: distribution}``
(any SciPy frozen continuous distribution, :class:`normal`, :class:`uniform`, or a
``(low, high)`` pair for a uniform one) or a :class:`~.distributions.JointDistribution` with
correlated variables. Points of the unit cube are mapped by each marginal's inverse CDF.

* :func:`full_factorial`: every combination of given levels (a grid).
* :func:`latin_hypercube`: each variable's range (of probability) cut into ``n`` equal
  strata, one sample in each, strata paired at random (McKay, Beckman & Conover 1979);
  correlated variables are paired by the Iman–Conover method, which keeps every stratum.
* :func:`sobol`, :func:`halton`: low-discrepancy sequences, scrambled (SciPy's ``qmc``);
  Sobol' points are balanced only in powers of two. Correlation through the Gaussian copula.
* :func:`monte_carlo`: independent random draws from :func:`normal`, :func:`uniform`, SciPy
  frozen distributions, and :func:`correlated_normal` for variables drawn together; or from
  a JointDistribution (its Gaussian copula).
* :func:`sample`: one front door to all of them for a set of distributions.

SciPy's statistics module is imported on first use (it takes a while to load).
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Mapping, Sequence

import numpy as np

from ..errors import StudyError
from .distributions import JointDistribution


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


def _is_distribution(value) -> bool:
    return isinstance(value, normal | uniform) or hasattr(value, "ppf")


def _space(bounds):
    """``(names, low, high)`` of plain bounds, or a JointDistribution."""
    if isinstance(bounds, JointDistribution):
        return bounds
    if isinstance(bounds, Mapping) and any(_is_distribution(v) for v in bounds.values()):
        from scipy import stats

        margs = {}
        for name, v in bounds.items():
            if _is_distribution(v):
                margs[name] = v
            else:
                _, a, b = _bounds({name: v})
                margs[name] = stats.uniform(a[0], b[0] - a[0])
        return JointDistribution(margs)
    return _bounds(bounds)


def _mapped(space, unit: np.ndarray) -> dict[str, np.ndarray]:
    """Unit-cube points through the bounds or the distributions (inverse CDFs, copula)."""
    if not isinstance(space, JointDistribution):
        return _scaled(unit, *space)
    x = space.from_unit(unit)
    if not np.all(np.isfinite(x)):
        raise StudyError("a point of the unit cube on its boundary maps to an infinite value "
                         "of an unbounded distribution (an unscrambled sequence starts at 0): "
                         "use scramble=True")
    return space.columns(x)


def _rank_correlation(x: np.ndarray) -> np.ndarray:
    """Spearman's rank correlation matrix of the columns of ``x`` (no ties)."""
    ranks = np.argsort(np.argsort(x, axis=0), axis=0).astype(float)
    return np.corrcoef(ranks, rowvar=False)


def iman_conover(x: np.ndarray, copula_correlation: np.ndarray, rng,
                 corrections: int = 4) -> np.ndarray:
    """The columns of ``x`` (n, d) re-paired so that their ranks follow a Gaussian copula of
    correlation ``copula_correlation``, whose Spearman correlation is ``(6/π) arcsin(R0/2)``.

    Iman & Conover (*A distribution-free approach to inducing rank correlation among input
    variables*, Commun. Statist. B 11(3), 1982): random permutations of the van der Waerden
    scores ``Φ^{-1}(k / (n + 1))`` are decorrelated exactly by their sample Cholesky factor and
    correlated by the target's, and each column of ``x`` takes the ranks of the result. The
    sample's rank correlation then misses the target by about ``0.3 / sqrt(n)``; up to
    ``corrections`` times the scores' target is moved by that miss (same permutations), which
    brings it to about ``1e-4`` at ``n = 1000``. Every column keeps its values (so a Latin
    hypercube keeps its strata).
    """
    from scipy.special import ndtri

    n, d = x.shape
    if n <= d + 1:
        raise StudyError(f"correlated Latin hypercube pairing needs more samples than "
                         f"variables + 1, got n={n} for {d} variables")
    goal = (6.0 / np.pi) * np.arcsin(copula_correlation / 2.0)
    scores = ndtri(np.arange(1, n + 1) / (n + 1.0))
    S = np.stack([rng.permutation(scores) for _ in range(d)], axis=1)
    W = np.linalg.solve(np.linalg.cholesky(np.corrcoef(S, rowvar=False)), S.T).T
    target, best, best_miss = np.array(copula_correlation, dtype=float), None, np.inf
    for _ in range(corrections + 1):
        try:
            P = np.linalg.cholesky(target)
        except np.linalg.LinAlgError:
            break  # a correction left the positive definite matrices: keep the best so far
        T = W @ P.T
        order = np.argsort(T, axis=0)
        miss = goal - _rank_correlation(T)
        if np.max(np.abs(miss)) < best_miss:
            best, best_miss = order, np.max(np.abs(miss))
        target = target + miss
    out = np.empty_like(x)
    for j in range(d):
        out[best[:, j], j] = np.sort(x[:, j])
    return out


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


def latin_hypercube(bounds, n: int, *, seed=None, pairing: str = "iman-conover"
                    ) -> dict[str, np.ndarray]:
    """``n`` samples with exactly one in each of the ``n`` equal strata of probability of
    every variable.

    Parameters
    ----------
    bounds : dict or JointDistribution
        ``{name: (low, high)}``, ``{name: distribution}`` or a JointDistribution (module
        docstring).
    n : int
    seed : int or numpy Generator, optional
    pairing : {"iman-conover", "copula"}
        For correlated variables: re-pair the strata to the copula's ranks (Iman–Conover:
        every variable keeps one sample per stratum), or map the hypercube through the
        Gaussian copula (exact copula, strata of the correlated variables lost).
    """
    space = _space(bounds)
    n = _count(n)
    if pairing not in ("iman-conover", "copula"):
        raise StudyError(f"pairing must be 'iman-conover' or 'copula', got {pairing!r}")
    d = len(space) if isinstance(space, JointDistribution) else len(space[0])
    rng = np.random.default_rng(seed)
    strata = np.stack([rng.permutation(n) for _ in range(d)], axis=1)
    unit = (strata + rng.random((n, d))) / n
    if isinstance(space, JointDistribution) and not space.independent \
            and pairing == "iman-conover":
        margins = JointDistribution(dict(zip(space.names, space.marginals)))
        x = iman_conover(margins.from_unit(unit), space.copula_correlation, rng)
        return space.columns(x)
    return _mapped(space, unit)


def sobol(bounds, n: int, *, seed=None, scramble: bool = True) -> dict[str, np.ndarray]:
    """The first ``n`` points of a (scrambled) Sobol' sequence; ``n`` a power of two.
    ``bounds``: as for :func:`latin_hypercube` (correlation through the Gaussian copula)."""
    space = _space(bounds)
    n = _count(n)
    if n & (n - 1):
        below = 2 ** int(math.log2(n))
        raise StudyError(f"a Sobol' sample is balanced only for a power of two points, got "
                         f"n={n}: use {below} or {2 * below} (or latin_hypercube/halton)")
    from scipy.stats import qmc

    d = len(space) if isinstance(space, JointDistribution) else len(space[0])
    unit = qmc.Sobol(d=d, scramble=scramble, seed=seed).random_base2(int(math.log2(n)))
    return _mapped(space, unit)


def halton(bounds, n: int, *, seed=None, scramble: bool = True) -> dict[str, np.ndarray]:
    """The first ``n`` points of a (scrambled) Halton sequence. ``bounds``: as for
    :func:`latin_hypercube` (correlation through the Gaussian copula)."""
    space = _space(bounds)
    n = _count(n)
    from scipy.stats import qmc

    d = len(space) if isinstance(space, JointDistribution) else len(space[0])
    unit = qmc.Halton(d=d, scramble=scramble, seed=seed).random(n)
    return _mapped(space, unit)


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


def monte_carlo(distributions, n: int, *, seed=None) -> dict[str, np.ndarray]:
    """``n`` random designs: ``{name: distribution}`` drawn independently, and
    ``{(name, ...): correlated_normal(mean, cov)}`` for variables drawn together; or a
    :class:`~.distributions.JointDistribution` (independent standard normal draws through
    its Gaussian copula)."""
    if isinstance(distributions, JointDistribution):
        rng = np.random.default_rng(seed)
        u = rng.standard_normal((_count(n), len(distributions)))
        return distributions.columns(distributions.from_standard(u))
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


SAMPLERS = {"lhs": latin_hypercube, "sobol": sobol, "halton": halton, "mc": monte_carlo}


def sample(distributions, n: int, method: str = "lhs", *, seed=None) -> dict[str, np.ndarray]:
    """``n`` designs of ``distributions`` (a JointDistribution or ``{name: distribution}``)
    by ``method``: ``"lhs"`` (:func:`latin_hypercube`, Iman–Conover pairing), ``"sobol"``,
    ``"halton"`` or ``"mc"`` (:func:`monte_carlo`)."""
    if method not in SAMPLERS:
        raise StudyError(f"method must be one of {sorted(SAMPLERS)}, got {method!r}")
    from .distributions import joint

    return SAMPLERS[method](joint(distributions), n, seed=seed)
