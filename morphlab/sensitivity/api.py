"""Design sensitivities of dynamic responses (paper §3, ``docs/theory.md`` §6-§7):
:func:`sensitivities`, the one entry point, and its :class:`SensitivityResult`.

The method is a strategy object (:mod:`morphlab.sensitivity.strategies`): direct
differentiation (:mod:`morphlab.sensitivity.direct`), the discrete adjoint
(:mod:`morphlab.sensitivity.adjoint`), whichever is cheaper (``"auto"``, the default), or the
comparators — the whole run in complex arithmetic per variable (``"complex-step"``, the
reference: no truncation error) and finite differences of whole runs. Response gradients of the
direct and complex-step methods are taken by complex step of the response over each variable's
perturbed histories, so any complex-safe function of a
:class:`~morphlab.results.result.Result` works; the adjoint needs responses with a ``vjp``.
"""

from __future__ import annotations

import numbers
import time as _time
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field

import numpy as np

from ..compile import compile_model
from ..errors import Interrupted, MorphlabError, ResponseError, SensitivityError
from ..jit.progress import CompileProgress
from ..jit.threads import one_blas_thread
from ..results.result import Result
from ..solve.settings import Settings
from .designs import CS_STEP, call_build
from .histories import HISTORIES
from .strategies import FiniteDifference, Setup, Strategy, resolve


@dataclass(repr=False)
class SensitivityResult:
    """Values and gradients of responses, with the histories behind them.

    Attributes
    ----------
    method : str
        The method's name (``"direct"``, ``"direct-fd"``, ``"complex-step"``, ...).
    result : Result
        The primal run at ``p0``.
    values : dict[str, float]
        Response values at ``p0``.
    gradients : dict[str, dict[str, float]]
        ``gradients[response][variable]``.
    variables : list[str]
        Design variable names, in column order of the arrays below.
    state : dict[str, ndarray]
        Direct methods: the sensitivity histories kept (``store`` of :func:`sensitivities`;
        by default those the responses read), of ``"q"``, ``"v"``, ``"a"`` (n_t, n_dof, n_x)
        and ``"lam"`` (n_t, n_con, n_x). Empty for the other methods.
    timing : dict[str, float]
        Wall seconds: ``"primal"``, ``"sensitivity"`` (the extra work) and ``"total"``.
    stats : dict
        Factorizations, refinement residuals and other diagnostics.
    design : dict[str, float]
        The nominal design ``p0`` the sensitivities were taken at.
    """

    method: str
    variables: list
    result: Result
    values: dict
    gradients: dict
    state: dict = field(default_factory=dict)
    timing: dict = field(default_factory=dict)
    stats: dict = field(default_factory=dict)
    design: dict = field(default_factory=dict)
    _perturbed: list = field(default_factory=list, repr=False)
    _steps: dict = field(default_factory=dict, repr=False)
    _strategy: object = field(default=None, repr=False)

    def __repr__(self) -> str:
        """A few lines for a notebook: method, design, values, sizes (not the histories)."""
        def short(d: dict, k=6) -> str:
            items = [f"{n}: {float(np.real(v)):.4g}" for n, v in list(d.items())[:k]]
            return "{" + ", ".join(items) + (", ..." if len(d) > k else "") + "}"

        kept = ", ".join(f"{k} {tuple(np.shape(v))}" for k, v in self.state.items())
        r = self.result
        total = self.timing.get("total")
        return (f"<SensitivityResult {self.method!r}: {len(self.values)} responses x "
                f"{len(self.variables)} variables; design {short(self.design)}; values "
                f"{short(self.values)}; kept histories {kept or 'none'}; primal {r.status}, "
                f"{r.n_t} times" + (f"; total {total:.3g} s>" if total is not None else ">"))

    def derivative(self, fn: Callable[[Result], np.ndarray]) -> np.ndarray:
        """``d fn(result) / d p`` for any complex-safe accessor ``fn`` (e.g. ``lambda r:
        r.stress("skin")``); shape ``fn(result).shape + (n_x,)``."""
        if len(self._perturbed) != len(self.variables):
            raise SensitivityError(
                f"method {self.method!r} keeps no perturbed histories: it differentiates the "
                "given responses only; use method='direct' for derivatives of whole histories")
        cols = [self._strategy.column(fn, self.result, pert, self._steps.get(name))
                for name, pert in zip(self.variables, self._perturbed)]
        return np.stack(cols, axis=-1)

    def stress(self, body: str) -> np.ndarray:
        """d(stress)/dp of a beam, (n_t, n_elem, 2, 2, n_x)."""
        return self.derivative(lambda r: r.stress(body))

    def node_positions(self, body: str) -> np.ndarray:
        """d(node position)/dp of a beam, (n_t, n_nodes, 2, n_x)."""
        return self.derivative(lambda r: r.node_positions(body))

    def table(self, digits: int = 4) -> str:
        """The gradients as a text table (responses in rows, variables in columns)."""
        head = "response".ljust(18) + "".join(v.rjust(14) for v in self.variables)
        lines = [head]
        for name, g in self.gradients.items():
            lines.append(name.ljust(18) + "".join(f"{g[v]:14.{digits}g}" for v in self.variables))
        return "\n".join(lines)


def _check_response(name, value_c, value0):
    """A response of a complex-step perturbed result must be a complex scalar whose real part
    is the nominal value."""
    if not np.iscomplexobj(np.asarray(value_c)):
        raise SensitivityError(
            f"response {name!r} is not complex-safe: it returned a real number for a complex "
            "(perturbed) result, so the imaginary part carrying the derivative was dropped. "
            "Avoid abs, np.abs, np.max, float(), np.hypot on values that depend on the "
            "design; see morphlab.responses (ks, max_by_real, distance, rms)")
    if np.ndim(value_c) != 0:
        raise SensitivityError(f"response {name!r} must return a scalar, got shape "
                               f"{np.shape(value_c)}")
    if not np.isclose(np.real(value_c), value0, rtol=1e-9, atol=1e-300):
        raise SensitivityError(
            f"response {name!r} is not complex-safe: its real part changed under a complex "
            f"perturbation ({np.real(value_c)!r} vs {value0!r})")


def _check_inputs(p0, names, responses, store) -> None:
    if not isinstance(p0, Mapping) or not p0:
        raise SensitivityError("p0 must be a non-empty dict of design variables")
    for k, v in p0.items():
        if (isinstance(v, (bool, np.bool_)) or not isinstance(v, numbers.Real)
                or not np.isfinite(v)):
            raise SensitivityError(f"design variable {k!r} must be a finite real number, got "
                                   f"{_show(v)}")
    unknown = [v for v in names if v not in p0]
    if unknown:
        raise SensitivityError(f"design variables {unknown} are not in p0 (known: {list(p0)})")
    if not isinstance(responses, Mapping) or not responses:
        raise SensitivityError("responses must be a non-empty dict name -> function(result)")
    for k, fn in responses.items():
        if not callable(fn):
            raise SensitivityError(f"response {k!r} is not callable")
    if not (store in ("auto", "all") or (isinstance(store, (tuple, list)) and store
                                         and set(store) <= set(HISTORIES))):
        raise SensitivityError(f"store must be 'auto', 'all' or a non-empty tuple of "
                               f"{HISTORIES}, got {store!r}")


@one_blas_thread()
def sensitivities(build: Callable[[dict], object], p0: Mapping[str, float],
                  responses: Mapping[str, Callable[[Result], float]], *,
                  method: str | Strategy = "auto", variables: list | None = None,
                  settings: Settings | None = None, store="auto", progress: bool = False,
                  **options) -> SensitivityResult:
    """Values and design gradients of ``responses`` of the model ``build(p0)``.

    Parameters
    ----------
    build : callable
        ``build(p) -> Model`` for a dict of design variables; must work with complex values
        (complex step) and keep the topology fixed.
    p0 : dict[str, float]
        Nominal design.
    responses : dict[str, callable]
        ``f(result) -> scalar``, complex-safe (see :mod:`morphlab.responses`).
    method : str or Strategy
        ``"auto"`` (the default: direct or adjoint, whichever is cheaper), ``"direct"``,
        ``"direct-fd"``, ``"adjoint"``, ``"complex-step"``, ``"forward-difference"``,
        ``"central-difference"`` (module docstring), or a strategy object of
        :mod:`morphlab.sensitivity.strategies` with its own options (``Direct(reuse=False)``,
        ``Adjoint(memory=...)``, ``FiniteDifference("central", 1e-5)``, a user's
        :class:`~morphlab.sensitivity.strategies.Strategy` subclass).
    variables : list[str], optional
        Subset of ``p0`` to differentiate (default: all).
    settings : Settings, optional; **options
        Solver settings, as in :func:`morphlab.simulate` (``t_end``, ``dt``, ``rho_inf``, ...).
    store : "auto", "all" or tuple of {"q", "v", "a", "lam"}
        Direct methods: the sensitivity histories kept for every step, (n_t, ..., n_x) each
        (the others keep only the two levels the time stepping needs). ``"auto"`` keeps those
        the responses read, found by calling them once on a two-step probe of the nominal
        model (all four if a response fails there); ``"all"`` keeps all four. What is kept is
        what :meth:`SensitivityResult.derivative` can differentiate afterwards.
    progress : bool
        Print a progress bar.

    Returns
    -------
    SensitivityResult

    Raises
    ------
    SensitivityError
        Unknown method, unknown or unused design variable, structure-changing variable,
        response that is not complex-safe.
    Interrupted
        Ctrl-C: ``error.result`` holds the primal result so far (or none, if the primal had
        not started), ``error.sensitivity`` the analysis so far.
    """
    strategy = resolve(method)
    names = list(p0) if variables is None else list(variables)
    _check_inputs(p0, names, responses, store)
    settings = Settings.of(settings, **options)
    p0 = {k: float(v) for k, v in p0.items()}

    t_start = _time.perf_counter()
    sys0 = compile_model(call_build(build, p0, "at the nominal design"))
    setup = Setup(sys0, settings, build, p0, names, dict(responses), store, progress)
    strategy = strategy.choose(setup)
    steps = strategy.steps(setup) if isinstance(strategy, FiniteDifference) else {}
    t_setup = _time.perf_counter() - t_start
    try:
        with CompileProgress(strategy.name):
            run = strategy.run(setup)
    except KeyboardInterrupt as err:
        partial = SensitivityResult(method=strategy.name, variables=names,
                                    result=getattr(err, "result", None), values={},
                                    gradients={}, design=dict(p0))
        stop = Interrupted(f"sensitivities interrupted ({strategy.name}): "
                           f"{err if str(err) else 'by the user'}",
                           time=getattr(err, "time", None), step=getattr(err, "step", None),
                           result=getattr(err, "result", None))
        stop.sensitivity = partial
        raise stop from err
    run.timing["setup"] = t_setup

    t_resp = _time.perf_counter()
    out = SensitivityResult(method=strategy.name, variables=names, result=run.result, values={},
                            gradients={}, state=run.state, timing=run.timing, stats=run.stats,
                            design=dict(p0), _perturbed=run.perturbed, _steps=steps,
                            _strategy=strategy)
    out.values, out.gradients = _differentiate(strategy, responses, run, names, steps, out)
    run.timing["responses"] = _time.perf_counter() - t_resp
    run.timing["total"] = _time.perf_counter() - t_start
    return out


def _differentiate(strategy, responses, run, names, steps, partial) -> tuple[dict, dict]:
    """Values of the responses on the primal result and their derivatives over the perturbed
    results (complex step over a complex result, or differences). A response that raises or
    returns something other than a finite real scalar raises :class:`ResponseError` with the
    analysis so far (``partial``, a SensitivityResult filled as the responses are)."""
    if run.gradients is not None:  # the strategy differentiated the responses itself
        return dict(run.values), {r: {v: float(g[i]) for i, v in enumerate(names)}
                                  for r, g in run.gradients.items()}
    values, gradients = partial.values, partial.gradients
    for rname, fn in responses.items():
        val0 = _evaluate(rname, fn, run.result, "the primal result", partial)
        values[rname] = float(np.real(val0))
        grad = {}
        for v, pert in zip(names, run.perturbed):
            if strategy.complex_results:
                vc = _evaluate(rname, fn, pert, f"the perturbed result of {v!r}", partial)
                _check_response(rname, vc, values[rname])
                grad[v] = float(np.imag(vc) / CS_STEP)
            else:
                col = _evaluate(rname, lambda r, fn=fn, pert=pert, v=v: strategy.column(
                    fn, r, pert, steps[v]), run.result, f"the differences of {v!r}", partial)
                grad[v] = float(np.real(col))
        gradients[rname] = grad
    return values, gradients


def _evaluate(name, fn, result, where, partial):
    """``fn(result)``, a finite scalar, or a :class:`ResponseError` naming the response."""
    try:
        out = fn(result)
    except MorphlabError as exc:
        raise ResponseError(f"response {name!r} failed on {where}: {exc}", response=name,
                            sensitivity=partial) from exc
    except Exception as exc:  # the user's function: keep the analysis, name the response
        raise ResponseError(f"response {name!r} raised {type(exc).__name__}: {exc} (on "
                            f"{where}; the analysis is kept in error.sensitivity)",
                            response=name, sensitivity=partial) from exc
    try:
        arr = np.asarray(out)
        ok = arr.dtype.kind in "iufc" and arr.ndim == 0 and np.isfinite(arr)
    except (TypeError, ValueError):
        ok = False
    if not ok:
        raise ResponseError(f"response {name!r} must return a finite real scalar, got "
                            f"{_show(out)} (on {where}; the analysis is kept in "
                            "error.sensitivity)", response=name, sensitivity=partial)
    return out


def _show(value, limit=60) -> str:
    text = repr(value)
    return text if len(text) <= limit else text[: limit - 3] + "..."
