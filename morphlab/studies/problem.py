"""A design problem for :func:`morphlab.studies.optimize`: the model or function evaluated,
the objective, :class:`Constraint` limits, bounds and the map to the optimizer's variables.

``Problem.evaluate`` is the one place where a design is run: :func:`morphlab.sensitivities`
(values and gradients of every response in one call), :func:`morphlab.simulate` (values
only) or the user's function. The optimizer's vector is ``x = (p - offset) / factor``: the
bounds' [0, 1] map by default, ``p / scale`` with a user scale (see
:mod:`morphlab.studies.optimize`).
"""

from __future__ import annotations

import copy
import dataclasses
from collections.abc import Callable, Mapping
from dataclasses import dataclass

import numpy as np

from ..errors import ModelError, SensitivityError
from ..sensitivity.api import sensitivities
from ..sensitivity.strategies import resolve
from ..solve.settings import Settings
from ..solve.timeloop import simulate
from .robust import Robust

GRADIENTS = ("exact", "finite-difference")

# primal solves behind one gradient evaluation of n variables, by the method's name
_SIMULATIONS = {"direct": lambda n: 1, "direct-fd": lambda n: 1, "adjoint": lambda n: 1,
                "complex-step": lambda n: 1 + n, "forward-difference": lambda n: n + 1,
                "central-difference": lambda n: 2 * n + 1}


@dataclass(frozen=True)
class Constraint:
    """A limit on one response: ``lower <= r <= upper`` (either or both) or ``r == equals``.

    Parameters
    ----------
    response : str
        Name of a response of the problem.
    upper, lower, equals : float, optional
        Limits in the response's units; ``equals`` excludes the other two.
    """

    response: str
    upper: float | None = None
    lower: float | None = None
    equals: float | None = None

    def __post_init__(self):
        if not isinstance(self.response, str) or not self.response:
            raise ModelError(f"Constraint.response must be a response name, got "
                             f"{self.response!r}")
        limits = {"upper": self.upper, "lower": self.lower, "equals": self.equals}
        for k, v in limits.items():
            if v is not None and not (isinstance(v, (int, float)) and np.isfinite(v)):
                raise ModelError(f"constraint on {self.response!r}: {k} must be a finite "
                                 f"number or None, got {v!r}")
        if self.equals is not None and (self.upper is not None or self.lower is not None):
            raise ModelError(f"constraint on {self.response!r}: equals excludes upper/lower")
        if all(v is None for v in limits.values()):
            raise ModelError(f"constraint on {self.response!r} has no limit: give upper, "
                             "lower or equals")
        if self.upper is not None and self.lower is not None and self.lower > self.upper:
            raise ModelError(f"constraint on {self.response!r}: lower {self.lower} > upper "
                             f"{self.upper}")

    def rows(self) -> list[tuple[str, float, float]]:
        """``(kind, sign, limit)`` of each scipy row ``sign (r - limit)`` (>= 0 or == 0)."""
        if self.equals is not None:
            return [("eq", 1.0, float(self.equals))]
        out = [] if self.lower is None else [("ineq", 1.0, float(self.lower))]
        return out + ([] if self.upper is None else [("ineq", -1.0, float(self.upper))])


def _settings_keywords() -> set:
    """The options of a run (:class:`morphlab.Settings`), taken by :func:`simulate` and
    :func:`sensitivities` alike."""
    return {f.name for f in dataclasses.fields(Settings)}


class Problem:
    """A design problem: minimise ``responses[objective]`` subject to constraints and bounds.

    Parameters
    ----------
    build : callable
        ``build(p) -> Model`` (complex-safe, as for :func:`morphlab.sensitivities`).
    p0 : dict[str, float]
        Start design; entries that are not ``variables`` stay fixed.
    responses : dict[str, callable]
        Complex-safe responses ``f(result) -> scalar``; all are recorded in the history.
    objective : str
        Name of the response to minimise.
    constraints : sequence of Constraint
    bounds : dict[str, (float, float)]
        ``(low, high)`` of the variables (every one when ``scale`` is None; ``None`` for an open
        side otherwise); ``p0`` must lie within them.
    variables : list[str], optional
        Design variables (default: all of ``p0``).
    settings : dict
        The options of the runs, fields of :class:`morphlab.Settings` (``t_end``, ``dt``,
        ``rho_inf``, ``tol``, ...).
    method : str or strategy
        Sensitivity method of ``gradient="exact"`` (see :func:`morphlab.sensitivities`;
        ``"auto"`` picks the adjoint for many variables when the responses have a vjp).
    scale : dict[str, float], optional
        Optimizer variable ``x_i = p_i / scale_i`` instead of the bounds' [0, 1] map.
    normalize : bool
        Divide the objective and the constraints by their magnitudes at ``p0`` (see
        :mod:`morphlab.studies.optimize`).
    robust : dict, optional
        Minimise ``mean + k std`` of the objective under scattered variables instead of its
        value (:mod:`morphlab.studies.robust`): ``{"std": {variable: sigma}, "k": 3.0}``.
        Gradient methods need ``gradient="exact"``; each design costs ``1 + n`` gradient runs.

    Attributes
    ----------
    p0, variables, responses, constraints, method, normalize :
        As given (``responses`` of a function problem: a dict of the recorded names).
    settings : Settings or None
        The options of the runs (None for a function problem).
    objective : str
        The minimised entry: the objective as given, or ``"<objective>.robust"``.
    recorded : list[str]
        Names recorded in the history: the responses, and the robust entries
        ``"<objective>.std"``, ``"<objective>.robust"``.
    robust : Robust or None
    bounds : list of (float, float)
        ``(low, high)`` of each variable, infinite for an open side.
    offset, factor : ndarray, shape (n_variables,)
        The optimizer's variables are ``x = (p - offset) / factor``.
    rows : list of (str, str, float, float)
        Scipy's constraint rows ``(response, "ineq" or "eq", sign, limit)``: ``sign (r - limit)
        >= 0`` or ``== 0``.
    """

    def __init__(self, build: Callable[[dict], object], p0: Mapping[str, float],
                 responses: Mapping[str, Callable], objective: str, *,
                 constraints=(), bounds: Mapping, variables: list | None = None,
                 settings: Mapping | Settings | None = None, method: str = "direct",
                 scale: Mapping | None = None, normalize: bool = False,
                 robust: Mapping | None = None):
        if not callable(build):
            raise ModelError("build must be a function p -> Model")
        if not isinstance(responses, Mapping) or not responses or not all(
                callable(f) for f in responses.values()):
            raise ModelError("responses must be a non-empty dict name -> function(result)")
        try:
            resolve(method)
        except SensitivityError as exc:
            raise ModelError(str(exc)) from None
        self.settings = _run_settings(settings)
        self.build, self._fn, self.method, self.step = build, None, method, 1e-6
        self.responses = dict(responses)
        self._setup(p0, list(self.responses), objective, constraints, bounds, variables,
                    scale, normalize, robust)

    @classmethod
    def from_function(cls, fn: Callable[[dict], tuple], p0: Mapping[str, float],
                      objective: str, *, constraints=(), bounds: Mapping,
                      variables: list | None = None, responses: list | None = None,
                      scale: Mapping | None = None, normalize: bool = False,
                      step: float = 1e-6, robust: Mapping | None = None) -> Problem:
        """A problem on ``fn(p) -> (values, gradients)`` instead of a simulation.

        ``values[response]`` is a float and ``gradients[response][variable]`` its derivative
        (or ``gradients`` None: then only derivative-free methods or
        ``gradient="finite-difference"``, by forward differences of relative step ``step``).
        ``responses`` lists the recorded names (default: the objective and the constraints');
        the other parameters are those of :class:`Problem` (``robust``: ``fn`` gives the
        gradients by the scattered variables too, and ``step`` is that of the differences of
        the gradients).
        """
        if not callable(fn):
            raise ModelError("fn must be a function p -> (values, gradients)")
        if not (isinstance(step, float) and 0.0 < step < 1.0):
            raise ModelError(f"step must be a float in (0, 1), got {step!r}")
        self = cls.__new__(cls)
        self.build, self._fn, self.settings, self.method, self.step = None, fn, None, None, step
        needed = [objective] + [c.response for c in constraints
                                if isinstance(c, Constraint)]
        names = list(dict.fromkeys(list(responses or []) + needed))
        self.responses = dict.fromkeys(names)
        self._setup(p0, names, objective, constraints, bounds, variables, scale, normalize,
                    robust)
        return self

    def _setup(self, p0, names, objective, constraints, bounds, variables, scale, normalize,
               robust=None):
        if not isinstance(p0, Mapping) or not p0:
            raise ModelError("p0 must be a non-empty dict of design variables")
        self.p0 = {k: float(np.real(v)) for k, v in p0.items()}
        self.variables = list(self.p0) if variables is None else list(variables)
        unknown = [v for v in self.variables if v not in self.p0]
        if len(set(self.variables)) != len(self.variables):
            raise ModelError(f"variables {self.variables} name a variable twice")
        if unknown or not self.variables:
            raise ModelError(f"variables {unknown or '[]'} are not design variables of p0 "
                             f"(known: {list(self.p0)})")
        if objective not in names:
            raise ModelError(f"objective {objective!r} is not a response (known: {names})")
        self.robust = None if robust is None else Robust(robust, objective, list(self.p0))
        self.recorded = list(names) + (list(self.robust.names) if self.robust else [])
        names = self.recorded
        if self.robust:
            objective = self.robust.names[1]
        constraints = tuple(constraints)
        for c in constraints:
            if not isinstance(c, Constraint) or c.response not in names:
                raise ModelError(f"constraints must be Constraint(response, ...) on one of "
                                 f"{names}, got {c!r}")
        if not isinstance(normalize, bool):
            raise ModelError(f"normalize must be True or False, got {normalize!r}")
        self.objective, self.constraints, self.normalize = objective, constraints, normalize
        self.rows = [(c.response,) + r for c in constraints for r in c.rows()]
        self.bounds, self.offset, self.factor = _scaling(self.p0, self.variables, bounds,
                                                           scale)

    def with_start(self, start: Mapping) -> Problem:
        """A copy of the problem starting from ``start`` (values of some or all variables;
        the rest of ``p0`` kept), checked within the bounds."""
        p0 = dict(self.p0)
        for k, v in start.items():
            if k not in self.variables:
                raise ModelError(f"start value of {k!r}, which is not a design variable "
                                 f"{self.variables}")
            p0[k] = float(v)
        for v, (lo, hi) in zip(self.variables, self.bounds):
            if not lo <= p0[v] <= hi:
                raise ModelError(f"start {v} = {p0[v]} lies outside its bounds ({lo}, {hi})")
        out = copy.copy(self)
        out.p0 = p0
        return out

    def to_x(self, design: Mapping) -> np.ndarray:
        """Optimizer vector of a design (dict of at least the variables)."""
        p = np.array([float(design[v]) for v in self.variables])
        return (p - self.offset) / self.factor

    def to_design(self, x: np.ndarray) -> dict:
        """Full design dict (fixed entries of ``p0`` included) of an optimizer vector."""
        p = dict(self.p0)
        p.update(zip(self.variables, (self.offset + self.factor * x).tolist()))
        return p

    def evaluate(self, p: dict, gradient: str | None) -> tuple[dict, dict | None, int]:
        """``(values, gradients or None, simulations)`` of a design; ``gradient`` None (primal
        only), ``"exact"`` or ``"finite-difference"``."""
        n = len(self.variables)
        if self.robust is not None:
            if gradient == "finite-difference":
                raise ModelError("a robust objective takes gradient='exact' (its std needs "
                                 "the gradients) or a derivative-free method")
            return self.robust.evaluate(self._gradient_run, p, self.variables,
                                        gradient is not None, self.step)
        if self._fn is not None:
            values, grads = self._call(p)
            if gradient == "finite-difference":
                grads = self._differences(p, values)
            elif gradient == "exact" and grads is None:
                raise SensitivityError("fn returned no gradients; use gradient="
                                       "'finite-difference' or a derivative-free method")
            return values, grads, (n + 1 if gradient == "finite-difference" else 1)
        if gradient is None:
            res = simulate(self.build(p), settings=self.settings)
            return {k: float(np.real(f(res))) for k, f in self.responses.items()}, None, 1
        method = self.method if gradient == "exact" else "forward-difference"
        s = sensitivities(self.build, p, self.responses, method=method,
                          variables=self.variables, settings=self.settings)
        return dict(s.values), s.gradients, _SIMULATIONS.get(s.method, lambda n: 1)(n)

    def _gradient_run(self, p: dict, variables: list) -> tuple[dict, dict, int]:
        """Values and exact gradients by ``variables`` (a sensitivity run, or ``fn``)."""
        if self._fn is not None:
            values, grads = self._call(p, variables)
            if grads is None:
                raise SensitivityError("fn returned no gradients; a robust objective needs "
                                       "them")
            return values, grads, 1
        s = sensitivities(self.build, p, self.responses, method=self.method,
                          variables=variables, settings=self.settings)
        return dict(s.values), s.gradients, _SIMULATIONS.get(s.method, lambda n: 1)(
            len(variables))

    def _call(self, p, variables=None):
        variables = self.variables if variables is None else variables
        out = self._fn(dict(p))
        if not (isinstance(out, tuple) and len(out) == 2 and isinstance(out[0], Mapping)):
            raise SensitivityError("fn must return (values dict, gradients dict or None)")
        values, grads = out
        missing = [k for k in self.responses if k not in values]
        if missing:
            raise SensitivityError(f"fn returned no value of {missing}")
        values = {k: float(values[k]) for k in self.responses}
        if grads is not None:
            try:
                grads = {k: {v: float(grads[k][v]) for v in variables}
                         for k in self.responses}
            except (KeyError, TypeError) as exc:
                raise SensitivityError(f"fn's gradients must be gradients[response][variable] "
                                       f"for {list(self.responses)} x {variables}: "
                                       f"missing {exc}") from exc
        return values, grads

    def _differences(self, p, values):
        grads = {k: {} for k in self.responses}
        for v in self.variables:
            h = self.step * (abs(p[v]) if p[v] != 0.0 else 1.0)
            vp = self._call({**p, v: p[v] + h})[0]
            for k in self.responses:
                grads[k][v] = (vp[k] - values[k]) / h
        return grads


def _run_settings(settings) -> Settings:
    """The runs' options as Settings, from a Settings or a dict of its fields (checked)."""
    if isinstance(settings, Settings):
        out = settings
    else:
        settings = dict(settings or {})
        bad = sorted(set(settings) - _settings_keywords())
        if bad:
            raise ModelError(f"settings {bad} are not options of a run; valid: "
                             f"{sorted(_settings_keywords())}")
        if "t_end" not in settings or "dt" not in settings:
            raise ModelError("settings need the end time 't_end' and step 'dt' of the runs")
        out = Settings.of(**settings)  # every value valid
    if out.newton != "full":
        raise ModelError("settings newton must be 'full': the gradients need the exact "
                         "Newton matrix of every step")
    return out


def _scaling(p0, variables, bounds, scale):
    """Bounds list and the maps ``p = offset + factor * x`` of the optimizer variables."""
    if not isinstance(bounds, Mapping):
        raise ModelError("bounds must be a dict variable -> (low, high)")
    extra = sorted(set(bounds) - set(variables))
    if extra:
        raise ModelError(f"bounds of {extra}, which are not design variables {variables}")
    if scale is not None and (not isinstance(scale, Mapping) or set(scale) != set(variables)):
        raise ModelError(f"scale must be a dict with a value for each of {variables}")
    out, offset, factor = [], [], []
    for v in variables:
        lo, hi = bounds.get(v, (None, None))
        lo = -np.inf if lo is None else float(lo)
        hi = np.inf if hi is None else float(hi)
        if not lo <= p0[v] <= hi or lo == hi:
            raise ModelError(f"p0[{v!r}] = {p0[v]} must lie within bounds ({lo}, {hi}), "
                             "low < high")
        if scale is None:
            if not (np.isfinite(lo) and np.isfinite(hi)):
                raise ModelError(f"variable {v!r} needs finite bounds (or pass scale=)")
            offset.append(lo)
            factor.append(hi - lo)
        else:
            s = float(scale[v])
            if not (np.isfinite(s) and s > 0):
                raise ModelError(f"scale[{v!r}] must be finite and > 0, got {scale[v]!r}")
            offset.append(0.0)
            factor.append(s)
        out.append((lo, hi))
    return out, np.array(offset), np.array(factor)
