"""Random design variables: marginal distributions joined by a Gaussian copula.

A :class:`JointDistribution` holds one marginal per variable (any SciPy frozen continuous
distribution, or :class:`~.samplers.normal` / :class:`~.samplers.uniform`) and their
dependence as a *Gaussian copula* (the Nataf model): with ``u`` independent standard normal
and ``L`` the Cholesky factor of the copula's correlation ``R0``,

    z = L u,    x_i = F_i^{-1}(Φ(z_i))                                           (1)

so each ``x_i`` has its marginal ``F_i`` and the ranks of ``x`` are those of a correlated
normal vector (Liu & Der Kiureghian, *Multivariate distribution models with prescribed
marginals and covariances*, Prob. Eng. Mech. 1(2), 1986). Equation (1) is the
isoprobabilistic transform of the reliability methods (:mod:`.reliability`) and, applied to
uniform points through ``u = Φ^{-1}(unit)``, the inverse-CDF mapping of every sampler.

The dependence may be given three ways (at most one):

* ``copula_correlation``: ``R0`` itself (OpenTURNS' ``NormalCopula``);
* ``rank_correlation``: Spearman's ρ_S, exactly ``R0 = 2 sin(π ρ_S / 6)`` for a Gaussian
  copula (Kruskal 1958), whatever the marginals;
* ``correlation``: Pearson's ρ of the variables themselves; each pair's ``R0`` solves Nataf's
  integral equation ``ρ = E[(x_i - μ_i)(x_j - μ_j)] / (σ_i σ_j)`` (a 2-D Gauss–Hermite
  quadrature of 48² points and Brent's method), refused when no ``R0`` in (-1, 1) reaches ρ.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from ..errors import StudyError

_GH_POINTS = 48  # Gauss-Hermite points per axis of the Nataf quadrature


def marginal(dist, name: str = "x"):
    """``dist`` as a SciPy frozen distribution: :class:`~.samplers.normal` and
    :class:`~.samplers.uniform` are converted, SciPy frozen distributions pass as they are."""
    from scipy import stats

    kind = type(dist).__name__
    if kind == "normal" and hasattr(dist, "std"):
        return stats.norm(dist.mean, dist.std)
    if kind == "uniform" and hasattr(dist, "high"):
        return stats.uniform(dist.low, dist.high - dist.low)
    if not all(hasattr(dist, m) for m in ("ppf", "isf", "cdf", "sf", "pdf")):
        raise StudyError(f"the distribution of {name!r} must be a SciPy frozen continuous "
                         f"distribution (e.g. scipy.stats.norm(10, 0.1)), normal(...) or "
                         f"uniform(...), got {dist!r}")
    return dist


def _family(dist) -> str:
    return getattr(getattr(dist, "dist", None), "name", "")


def _loc_scale(dist) -> tuple[float, float, list]:
    """``(loc, scale, shape parameters)`` of a SciPy frozen distribution, from the arguments
    it was frozen with (positional in the order shapes, loc, scale, or by keyword)."""
    shapes = [s.strip() for s in (dist.dist.shapes or "").split(",") if s.strip()]
    bound = dict(zip(shapes + ["loc", "scale"], dist.args))
    bound.update(dist.kwds)
    return (float(bound.get("loc", 0.0)), float(bound.get("scale", 1.0)),
            [float(bound[k]) for k in shapes])


def normal_to_marginal(dist, z: np.ndarray) -> np.ndarray:
    """``F^{-1}(Φ(z))`` for standard normal values ``z``: exact ``loc + scale z`` for a
    normal and ``loc + scale exp(s z)`` for a lognormal; otherwise the lower tail through
    ``ppf`` and the upper through ``isf``, so that neither loses the tail to round-off."""
    from scipy.special import ndtr

    z = np.asarray(z, dtype=float)
    family = _family(dist)
    if family in ("norm", "lognorm"):
        loc, scale, shapes = _loc_scale(dist)
        return loc + scale * (z if family == "norm" else np.exp(shapes[0] * z))
    return np.where(z <= 0.0, dist.ppf(ndtr(np.minimum(z, 0.0))),
                    dist.isf(ndtr(-np.maximum(z, 0.0))))


def marginal_to_normal(dist, x: np.ndarray) -> np.ndarray:
    """``Φ^{-1}(F(x))``, the inverse of :func:`normal_to_marginal`."""
    from scipy.special import ndtri

    x = np.asarray(x, dtype=float)
    family = _family(dist)
    if family in ("norm", "lognorm"):
        loc, scale, shapes = _loc_scale(dist)
        y = (x - loc) / scale
        return y if family == "norm" else np.log(y) / shapes[0]
    low = dist.cdf(x)
    return np.where(low <= 0.5, ndtri(low), -ndtri(dist.sf(x)))


def dx_dz(dist, z: np.ndarray, x: np.ndarray) -> np.ndarray:
    """Derivative of :func:`normal_to_marginal`: ``φ(z) / f(x)``."""
    family = _family(dist)
    if family in ("norm", "lognorm"):
        loc, scale, shapes = _loc_scale(dist)
        return np.full_like(z, scale) if family == "norm" else shapes[0] * (x - loc)
    phi = np.exp(-0.5 * z * z) / np.sqrt(2.0 * np.pi)
    return phi / dist.pdf(x)


def _nataf_rho(d1, d2, r0: float, nodes, weights) -> float:
    """Pearson correlation of two marginals joined by a Gaussian copula of correlation r0."""
    t1, t2 = np.meshgrid(nodes, nodes, indexing="ij")
    w = np.outer(weights, weights)
    z2 = r0 * t1 + np.sqrt(max(0.0, 1.0 - r0 * r0)) * t2
    x1, x2 = normal_to_marginal(d1, t1), normal_to_marginal(d2, z2)
    m1, m2 = float(d1.mean()), float(d2.mean())
    return float(np.sum(w * (x1 - m1) * (x2 - m2)) / (d1.std() * d2.std()))


def _nataf(marginals, names, rho: np.ndarray) -> np.ndarray:
    from numpy.polynomial.hermite_e import hermegauss
    from scipy.optimize import brentq

    nodes, weights = hermegauss(_GH_POINTS)
    weights = weights / np.sqrt(2.0 * np.pi)
    for d, name in zip(marginals, names):
        if not (np.isfinite(d.mean()) and np.isfinite(d.std()) and d.std() > 0):
            raise StudyError(f"a Pearson correlation of {name!r} needs a finite mean and std "
                             f"of its marginal; give rank_correlation instead")
    d = len(names)
    out = np.eye(d)
    edge = 1.0 - 1e-12
    for i in range(d):
        for j in range(i + 1, d):
            target = rho[i, j]
            if target == 0.0:
                continue

            def gap(r, i=i, j=j, target=target):
                return _nataf_rho(marginals[i], marginals[j], r, nodes, weights) - target

            low, high = gap(-edge), gap(edge)
            if not low <= 0.0 <= high:
                raise StudyError(
                    f"correlation {target} between {names[i]!r} and {names[j]!r} cannot be "
                    f"reached with their marginals (a Gaussian copula gives "
                    f"{low + target:.4f} to {high + target:.4f})")
            out[i, j] = out[j, i] = brentq(gap, -edge, edge, xtol=1e-14, rtol=1e-14)
    return out


def _correlation_matrix(value, d: int, what: str, names) -> np.ndarray:
    if isinstance(value, Mapping):  # {(a, b): rho}
        R = np.eye(d)
        for key, r in value.items():
            if not (isinstance(key, tuple) and len(key) == 2 and all(k in names for k in key)
                    and key[0] != key[1]):
                raise StudyError(f"{what}: keys must be pairs of two variables of {names}, got "
                                 f"{key!r}")
            i, j = names.index(key[0]), names.index(key[1])
            R[i, j] = R[j, i] = float(r)
    else:
        R = np.array(value, dtype=float)
    if R.shape != (d, d) or not np.all(np.isfinite(R)):
        raise StudyError(f"{what} must be a finite ({d}, {d}) matrix for the variables {names} "
                         f"or a dict {{(a, b): value}}, got shape {R.shape}")
    if not np.array_equal(R, R.T) or not np.all(np.diag(R) == 1.0):
        raise StudyError(f"{what} must be symmetric with ones on its diagonal")
    if np.any(np.abs(R) > 1.0):
        raise StudyError(f"{what}: entries must lie in [-1, 1]")
    return R


class JointDistribution:
    """Marginal distributions joined by a Gaussian copula (module docstring).

    Parameters
    ----------
    marginals : dict of str -> distribution
        One marginal per variable: a SciPy frozen continuous distribution (``scipy.stats.norm(
        mu, sigma)``, ``lognorm``, ``uniform``, ``truncnorm``, ...), :class:`~.samplers.normal`
        or :class:`~.samplers.uniform`. Variable units.
    copula_correlation, rank_correlation, correlation : (d, d) array or dict, optional
        The dependence, at most one (module docstring): a symmetric matrix in the order of
        ``marginals``, or ``{(a, b): value}`` for the correlated pairs (the rest 0).

    Attributes
    ----------
    names : list[str]
    marginals : list of SciPy frozen distributions
    copula_correlation : ndarray, shape (d, d)
        ``R0`` of the Gaussian copula (the identity for independent variables).
    factor : ndarray, shape (d, d)
        Its lower Cholesky factor ``L``.
    independent : bool
    """

    def __init__(self, marginals: Mapping, *, copula_correlation=None, rank_correlation=None,
                 correlation=None):
        if not isinstance(marginals, Mapping) or not marginals:
            raise StudyError("marginals must be a non-empty dict of variable -> distribution")
        self.names = [str(k) for k in marginals]
        self.marginals = [marginal(d, str(k)) for k, d in marginals.items()]
        d = len(self.names)
        given = [(k, v) for k, v in (("copula_correlation", copula_correlation),
                                     ("rank_correlation", rank_correlation),
                                     ("correlation", correlation)) if v is not None]
        if len(given) > 1:
            raise StudyError(f"give at most one of copula_correlation, rank_correlation and "
                             f"correlation, got {[k for k, _ in given]}")
        R0 = np.eye(d)
        if given:
            what, value = given[0]
            R = _correlation_matrix(value, d, what, self.names)
            if what == "copula_correlation":
                R0 = R
            elif what == "rank_correlation":
                R0 = 2.0 * np.sin(np.pi * R / 6.0)
            else:
                R0 = _nataf(self.marginals, self.names, R)
        try:
            self.factor = np.linalg.cholesky(R0)
        except np.linalg.LinAlgError as exc:
            raise StudyError(f"the copula correlation is not positive definite:\n{R0}") from exc
        self.copula_correlation = R0
        self.independent = bool(np.array_equal(R0, np.eye(d)))

    def __len__(self) -> int:
        return len(self.names)

    def __repr__(self) -> str:
        margs = ", ".join(f"{n}: {_describe(m)}" for n, m in zip(self.names, self.marginals))
        dep = "independent" if self.independent else "Gaussian copula"
        return f"JointDistribution({margs}; {dep})"

    # ------------------------------------------------------------------ transforms
    def from_standard(self, u: np.ndarray) -> np.ndarray:
        """Variables ``x`` (n, d) of independent standard normal points ``u`` (n, d): eq. (1)."""
        u = np.atleast_2d(np.asarray(u, dtype=float))
        z = u @ self.factor.T
        return np.stack([normal_to_marginal(m, z[:, i]) for i, m in enumerate(self.marginals)],
                        axis=1)

    def to_standard(self, x: np.ndarray) -> np.ndarray:
        """Independent standard normal points ``u`` (n, d) of variables ``x`` (n, d)."""
        from scipy.linalg import solve_triangular

        x = np.atleast_2d(np.asarray(x, dtype=float))
        z = np.stack([marginal_to_normal(m, x[:, i]) for i, m in enumerate(self.marginals)],
                     axis=1)
        return solve_triangular(self.factor, z.T, lower=True).T

    def jacobian(self, u: np.ndarray) -> np.ndarray:
        """``dx/du`` (d, d) at one standard point ``u`` (d,): ``diag(φ(z_i) / f_i(x_i)) L``."""
        u = np.asarray(u, dtype=float).ravel()
        z = self.factor @ u
        x = self.from_standard(u[None, :])[0]
        diag = np.array([float(dx_dz(m, z[i:i + 1], x[i:i + 1])[0])
                         for i, m in enumerate(self.marginals)])
        return diag[:, None] * self.factor

    def from_unit(self, unit: np.ndarray) -> np.ndarray:
        """Variables (n, d) of points of the unit cube (n, d) (uniform, independent): the
        copula's inverse-CDF mapping of a sampler."""
        from scipy.special import ndtri

        return self.from_standard(ndtri(np.asarray(unit, dtype=float)))

    # ------------------------------------------------------------------ moments
    def mean(self) -> np.ndarray:
        """Means of the marginals (d,)."""
        return np.array([float(m.mean()) for m in self.marginals])

    def std(self) -> np.ndarray:
        """Standard deviations of the marginals (d,)."""
        return np.array([float(m.std()) for m in self.marginals])

    def median(self) -> np.ndarray:
        """The variables at ``u = 0`` (d,): the medians of the marginals."""
        return self.from_standard(np.zeros((1, len(self))))[0]

    def covariance(self) -> np.ndarray:
        """Covariance (d, d) of the variables: the Pearson correlation that the copula gives
        (quadrature of the module docstring; exact for normal marginals) scaled by the
        standard deviations."""
        from numpy.polynomial.hermite_e import hermegauss

        s = self.std()
        if not np.all(np.isfinite(s)):
            raise StudyError("a covariance needs marginals with a finite std")
        C = np.diag(s * s)
        if self.independent:
            return C
        nodes, weights = hermegauss(_GH_POINTS)
        weights = weights / np.sqrt(2.0 * np.pi)
        normal = all(_family(m) == "norm" for m in self.marginals)
        for i in range(len(self)):
            for j in range(i + 1, len(self)):
                r0 = self.copula_correlation[i, j]
                if r0 == 0.0:
                    continue
                rho = r0 if normal else _nataf_rho(self.marginals[i], self.marginals[j], r0,
                                                   nodes, weights)
                C[i, j] = C[j, i] = rho * s[i] * s[j]
        return C

    def columns(self, x: np.ndarray) -> dict[str, np.ndarray]:
        """A design table ``{name: (n,) array}`` of variables ``x`` (n, d)."""
        x = np.atleast_2d(x)
        return {name: x[:, j].copy() for j, name in enumerate(self.names)}


def _describe(dist) -> str:
    family = _family(dist) or type(dist).__name__
    try:
        return f"{family}(mean {float(dist.mean()):.4g}, std {float(dist.std()):.4g})"
    except Exception:
        return family


def joint(distributions) -> JointDistribution:
    """``distributions`` as a :class:`JointDistribution`: as it is, or from a dict of
    independent marginals."""
    if isinstance(distributions, JointDistribution):
        return distributions
    if isinstance(distributions, Mapping):
        return JointDistribution(distributions)
    raise StudyError(f"distributions must be a JointDistribution or a dict of variable -> "
                     f"distribution, got {type(distributions).__name__}")
