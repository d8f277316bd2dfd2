"""First-order second-moment (FOSM) propagation of design scatter through exact gradients.

For responses ``r(p)`` with gradients ``G = dr/dp`` (n_r, n_v) at the nominal design and an
input covariance ``C`` (n_v, n_v), the first-order Taylor expansion gives

    E[r] ≈ r(p0),    Cov[r] ≈ G C Gᵀ,    σ_k = sqrt((G C Gᵀ)_kk)

exact for responses linear in ``p``, whatever the input distribution. With normally
distributed inputs the linearised responses are normal, so the probability of leaving an
allowable interval ``[lower, upper]`` is

    P(r > upper) = Φ((μ - upper) / σ),    P(r < lower) = Φ((lower - μ) / σ)

with Φ the standard normal CDF (the FOSM method of e.g. Haldar & Mahadevan, *Probability,
Reliability and Statistical Methods in Engineering Design*, Wiley 2000, ch. 7). The
approximation holds while the second-order terms are small against the first over the input
scatter; :func:`linearization_check` measures that from runs at ``p0 ± d``.

:class:`UncertaintyResult` holds ``mean``, ``std`` and ``p_exceed`` under the names a sampling
estimate of the same quantities uses, so the two can be compared field by field.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np
from scipy.special import ndtr

from ..errors import SensitivityError
from ..sensitivity.api import SensitivityResult


@dataclass
class UncertaintyResult:
    """Moments of responses under scattered design variables, and exceedance probabilities.

    Attributes
    ----------
    variables, responses : list[str]
        Scattered variables and responses (the order of ``cov``).
    mean, std : dict[str, float]
        Mean and standard deviation of each response (response units).
    cov : ndarray, shape (n_r, n_r)
        Response covariance.
    allowables : dict[str, (float or None, float or None)]
        ``(lower, upper)`` limits given, None for an open side.
    p_exceed : dict[str, float]
        Probability of leaving ``[lower, upper]``: ``p_below + p_above``.
    p_sides : dict[str, (float, float)]
        ``(P(r < lower), P(r > upper))``.
    method : str
        How the numbers were found (``"fosm"``).
    """

    variables: list
    responses: list
    mean: dict
    std: dict
    cov: np.ndarray
    allowables: dict = field(default_factory=dict)
    p_exceed: dict = field(default_factory=dict)
    p_sides: dict = field(default_factory=dict)
    method: str = "fosm"

    def correlation(self) -> np.ndarray:
        """Response correlation matrix (n_r, n_r); NaN rows for responses with zero std."""
        s = np.sqrt(np.diag(self.cov))
        with np.errstate(invalid="ignore", divide="ignore"):
            return self.cov / np.outer(s, s)

    def table(self, digits: int = 4) -> str:
        """Mean, std, coefficient of variation and exceedance probabilities as text."""
        lines = ["response".ljust(18) + "".join(h.rjust(13) for h in (
            "mean", "std", "cov [%]", "lower", "upper", "P(exceed)"))]
        for k in self.responses:
            mu, s = self.mean[k], self.std[k]
            cv = 100.0 * s / abs(mu) if mu != 0 else np.nan
            lo, hi = self.allowables.get(k, (None, None))
            cells = [f"{mu:.{digits}g}", f"{s:.{digits}g}", f"{cv:.3g}",
                     "-" if lo is None else f"{lo:.{digits}g}",
                     "-" if hi is None else f"{hi:.{digits}g}",
                     f"{self.p_exceed[k]:.3e}" if k in self.p_exceed else "-"]
            lines.append(k.ljust(18) + "".join(c.rjust(13) for c in cells))
        return "\n".join(lines)

    def __repr__(self) -> str:
        return (f"UncertaintyResult({self.method}, variables {self.variables})\n"
                + self.table())


def _nominal(sens) -> tuple[dict, dict, list]:
    """``(values, gradients, variable order)`` of a SensitivityResult or a pair."""
    if isinstance(sens, SensitivityResult):
        return dict(sens.values), sens.gradients, list(sens.variables)
    if not (isinstance(sens, (tuple, list)) and len(sens) == 2
            and isinstance(sens[0], Mapping) and isinstance(sens[1], Mapping) and sens[0]):
        raise SensitivityError("expected a SensitivityResult or a pair (values dict, "
                               "gradients dict[response][variable])")
    values, grads = sens
    missing = [k for k in values if k not in grads or not isinstance(grads[k], Mapping)]
    if missing:
        raise SensitivityError(f"no gradients[response][variable] for responses {missing}")
    return dict(values), grads, list(grads[next(iter(values))])


def _input_covariance(std, cov, variables, known) -> tuple[list, np.ndarray]:
    if (std is None) == (cov is None):
        raise SensitivityError("give exactly one of std (dict of independent standard "
                               "deviations) and cov (covariance matrix)")
    if std is not None:
        if not isinstance(std, Mapping) or not std:
            raise SensitivityError("std must be a non-empty dict variable -> standard deviation")
        names = list(std) if variables is None else list(variables)
        if set(names) != set(std):
            raise SensitivityError(f"variables {names} and the keys of std {list(std)} differ")
        s = np.array([float(std[v]) for v in names])
        if not np.all(np.isfinite(s) & (s >= 0)):
            raise SensitivityError(f"standard deviations must be finite and >= 0, got {std}")
        C = np.diag(s * s)
    else:
        names = list(known) if variables is None else list(variables)
        C = np.asarray(cov, dtype=float)
        if C.shape != (len(names), len(names)) or not np.all(np.isfinite(C)):
            raise SensitivityError(f"cov must be a finite ({len(names)}, {len(names)}) array "
                                   f"for variables {names}, got shape {C.shape}")
        scale = float(np.max(np.abs(C))) or 1.0
        if np.max(np.abs(C - C.T)) > 1e-12 * scale:
            raise SensitivityError("cov must be symmetric")
        if np.linalg.eigvalsh(0.5 * (C + C.T)).min() < -1e-12 * scale:
            raise SensitivityError("cov must be positive semi-definite (a covariance)")
    unknown = [v for v in names if v not in known]
    if unknown:
        raise SensitivityError(f"no gradients with respect to {unknown} (known: {known})")
    return names, C


def exceedance(mean: float, std: float, lower: float | None,
               upper: float | None) -> tuple[float, float]:
    """``(P(r < lower), P(r > upper))`` of a normal response; a zero std gives 0 or 1."""
    def side(margin):  # P(N(0, std) > margin)
        if std > 0:
            return float(ndtr(-margin / std))
        return 1.0 if margin < 0 else 0.0

    below = 0.0 if lower is None else side(mean - lower)
    above = 0.0 if upper is None else side(upper - mean)
    return below, above


def fosm(sens, std: Mapping | None = None, cov: np.ndarray | None = None,
         variables: Sequence | None = None,
         allowables: Mapping | None = None) -> UncertaintyResult:
    """First-order second-moment propagation (module docstring).

    Parameters
    ----------
    sens : SensitivityResult or (values, gradients)
        Nominal response values and ``gradients[response][variable]``.
    std : dict[str, float], optional
        Standard deviations of independent variables (variable units).
    cov : ndarray, shape (n_v, n_v), optional
        Covariance of the variables, in the order of ``variables`` (default: the order of the
        gradients).
    variables : list[str], optional
        The scattered variables (default: those of ``std``, or all for ``cov``); the others
        are held at their nominal values.
    allowables : dict[str, (float or None, float or None)], optional
        ``(lower, upper)`` limit of responses whose exceedance probability is wanted.

    Returns
    -------
    UncertaintyResult
    """
    values, grads, known = _nominal(sens)
    names, C = _input_covariance(std, cov, variables, known)
    responses = list(values)
    G = np.array([[float(grads[k][v]) for v in names] for k in responses])
    if not np.all(np.isfinite(G)):
        raise SensitivityError("gradients must be finite")
    cov_r = G @ C @ G.T
    sd = np.sqrt(np.maximum(np.diag(cov_r), 0.0))
    out = UncertaintyResult(names, responses, {k: float(values[k]) for k in responses},
                            dict(zip(responses, sd.tolist())), cov_r)
    for k, lim in (allowables or {}).items():
        if k not in values:
            raise SensitivityError(f"allowable for unknown response {k!r} (known: "
                                   f"{responses})")
        if not (isinstance(lim, (tuple, list)) and len(lim) == 2):
            raise SensitivityError(f"allowables[{k!r}] must be (lower, upper), None for an "
                                   f"open side, got {lim!r}")
        lo, hi = (None if b is None else float(b) for b in lim)
        if lo is not None and hi is not None and lo > hi:
            raise SensitivityError(f"allowables[{k!r}]: lower {lo} > upper {hi}")
        out.allowables[k] = (lo, hi)
        out.p_sides[k] = exceedance(out.mean[k], out.std[k], lo, hi)
        out.p_exceed[k] = sum(out.p_sides[k])
    return out


@dataclass
class LinearizationCheck:
    """Second-order term against the first along perturbations ``d`` of the design.

    Attributes
    ----------
    responses : list[str]
    deltas : list[dict]
        The perturbations ``d`` (variable -> step).
    first_order : dict[str, ndarray]
        ``grad · d`` of each response for each perturbation, shape (n_d,).
    ratio : dict[str, ndarray]
        ``|f(p+d) + f(p-d) - 2 f(p)| / (2 |grad · d|)`` (inf where ``grad · d = 0`` and the
        second difference is not).
    """

    responses: list
    deltas: list
    first_order: dict
    ratio: dict

    def worst(self) -> dict:
        """Largest ratio of each response over the perturbations."""
        return {k: float(np.max(self.ratio[k])) for k in self.responses}

    def table(self) -> str:
        head = "response".ljust(18) + "".join(f"d{j}".rjust(11) for j in range(len(self.deltas)))
        rows = [k.ljust(18) + "".join(f"{r:11.3g}" for r in self.ratio[k])
                for k in self.responses]
        return "\n".join([head] + rows)


def axis_perturbations(std: Mapping, k: float = 1.0) -> list[dict]:
    """Perturbations ``d = k σ_i e_i``, one per variable, for :func:`linearization_check`
    (run the model at ``p0 + d`` and ``p0 - d`` for each)."""
    if not (isinstance(k, (int, float)) and k > 0):
        raise SensitivityError(f"k must be > 0, got {k!r}")
    return [{v: k * float(s)} for v, s in std.items()]


def linearization_check(sens, deltas: Sequence[Mapping], values_plus: Sequence[Mapping],
                        values_minus: Sequence[Mapping]) -> LinearizationCheck:
    """Where first order is not enough: the second-order term along perturbations ``d``.

    For each ``d`` (e.g. :func:`axis_perturbations`, or antithetic pairs of a sample) and each
    response, ``|f(p+d) + f(p-d) - 2 f(p)| / (2 |grad · d|)``: the quadratic term of the
    response along ``d`` against its linear term. For ``f = a t + b t²`` with ``t ~ N(0, σ²)``
    and ``d = σ`` this ratio ``ρ = |b| σ / |a|`` is the shift of the true mean from the nominal
    value in standard deviations, and FOSM's std is low by about ``ρ²`` relative: a ratio of
    0.1 is harmless for the std but moves tail probabilities.

    Parameters
    ----------
    sens : SensitivityResult or (values, gradients)
        Nominal values ``f(p)`` and gradients.
    deltas : sequence of dict
        Perturbations (variable -> step, variable units; missing variables are 0).
    values_plus, values_minus : sequence of dict
        Response values at ``p + d`` and ``p - d`` for each perturbation.

    Returns
    -------
    LinearizationCheck
    """
    values, grads, known = _nominal(sens)
    deltas = [dict(d) for d in deltas]
    if not deltas or len(values_plus) != len(deltas) or len(values_minus) != len(deltas):
        raise SensitivityError(f"need one values_plus and one values_minus per perturbation: "
                               f"{len(deltas)} deltas, {len(values_plus)} and "
                               f"{len(values_minus)} values")
    for d in deltas:
        unknown = [v for v in d if v not in known]
        if unknown:
            raise SensitivityError(f"perturbation of {unknown}: no gradients (known {known})")
    first, ratio = {}, {}
    for k in values:
        lin = np.array([sum(grads[k][v] * s for v, s in d.items()) for d in deltas])
        try:
            second = np.array([vp[k] + vm[k] - 2.0 * values[k]
                               for vp, vm in zip(values_plus, values_minus)], dtype=float)
        except KeyError as exc:
            raise SensitivityError(f"perturbed values lack response {exc}") from exc
        with np.errstate(divide="ignore", invalid="ignore"):
            r = np.abs(second) / (2.0 * np.abs(lin))
        first[k], ratio[k] = lin, np.where(second == 0.0, 0.0, r)
    return LinearizationCheck(list(values), deltas, first, ratio)
