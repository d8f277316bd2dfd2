"""Reliability of responses under random variables: FORM with exact gradients, and
importance sampling around its design points.

A limit state is one side of an allowable: ``g = upper - r`` (failure ``r > upper``) or
``g = r - lower`` (failure ``r < lower``), in the standard normal space ``u`` of a
:class:`~.distributions.JointDistribution` (its Nataf transform ``x(u)``). Its gradient is
``∇_u g = (dx/du)ᵀ ∇_x g``, with ``∇_x r`` from the task (one
:func:`morphlab.sensitivities` run per point for a SimulationTask).

* :func:`form`: the design point of every limit state by the iHL-RF search (:mod:`.form`),
  ``β``, ``P_f = Φ(-β)``, importance factors; the searches of all limit states advance
  together, each round's points in one :func:`~.sweep.sweep`.
* :func:`importance_sampling`: ``n`` draws ``u = u* + v``, ``v ~ N(0, I)``, around each
  design point; ``P_f = mean(1[g(u) <= 0] w(u))`` with ``w = φ(u) / φ(u - u*) =
  exp(-u·u* + |u*|²/2)``, its standard error from the sample of ``1[g <= 0] w`` and the
  coefficient of variation ``SE / P_f`` (e.g. Melchers & Beck, *Structural Reliability
  Analysis and Prediction*, 3rd ed., Wiley 2018, §3.5). Unbiased for any design point; the
  closer the FORM point is to the most likely failure region, the smaller the variance.

Both the probabilities below a lower and above an upper limit are disjoint events, so the
exceedance probability of a two-sided allowable is their sum.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.special import ndtr, ndtri

from ..errors import StudyError
from .distributions import joint
from .form import SearchOptions, beta_of, importance_factors, search
from .function_task import values_only, with_gradients
from .statistics import _check_confidence, check_allowables
from .sweep import sweep
from .tasks import make_executor


@dataclass
class LimitState:
    """FORM (and importance sampling) of one limit state.

    Attributes
    ----------
    response, side : str
        The response and ``"upper"`` (failure ``r > limit``) or ``"lower"`` (``r < limit``).
    limit : float
    beta : float
        Reliability index (distance of the design point from the origin in ``u``, negative
        when the median design fails).
    p_form : float
        ``Φ(-β)``.
    design_point : dict[str, float]
        The design point in the variables (variable units).
    u : ndarray, shape (d,)
        The design point in the standard normal space.
    alpha : ndarray, shape (d,)
        Unit normal ``-∇g/|∇g|`` of the limit surface at ``u`` (towards failure).
    importance : dict[str, float]
        Importance factors ``γ_i²`` of the variables (sum 1; :func:`.form.importance_factors`).
    iterations, runs : int
        HL-RF iterations and model runs of the search.
    converged : bool
    message : str
    p_is, is_std_error, is_cov : float
        Importance-sampling estimate, its standard error and coefficient of variation (NaN
        before :func:`importance_sampling`).
    is_ci : (float, float)
        Its interval ``p_is ± z SE`` at the confidence asked (normal approximation).
    is_n, is_failures, is_failed_runs : int
        Draws, draws in the failure domain, runs that failed (left out).
    """

    response: str
    side: str
    limit: float
    beta: float
    p_form: float
    design_point: dict
    u: np.ndarray
    alpha: np.ndarray
    importance: dict
    iterations: int
    runs: int
    converged: bool
    message: str
    p_is: float = np.nan
    is_std_error: float = np.nan
    is_cov: float = np.nan
    is_ci: tuple = (np.nan, np.nan)
    is_n: int = 0
    is_failures: int = 0
    is_failed_runs: int = 0

    @property
    def p(self) -> float:
        """The best estimate: importance sampling when run, else FORM."""
        return self.p_is if self.is_n else self.p_form


@dataclass
class ReliabilityResult:
    """FORM (and importance sampling) of every limit state of the allowables.

    Attributes
    ----------
    variables : list[str]
    allowables : dict[str, (float or None, float or None)]
    limit_states : dict[(str, str), LimitState]
        By ``(response, side)``.
    p_sides : dict[str, (float, float)]
        ``(P(r < lower), P(r > upper))`` by the best estimate of each side.
    p_exceed : dict[str, float]
        Their sum (disjoint events).
    runs : int
        Model runs in all (shared points counted once).
    method : str
        ``"form"`` or ``"importance-sampling"``.
    """

    variables: list
    allowables: dict
    limit_states: dict
    p_sides: dict = field(default_factory=dict)
    p_exceed: dict = field(default_factory=dict)
    runs: int = 0
    method: str = "form"

    def _collect(self) -> None:
        for k, (lo, hi) in self.allowables.items():
            below = self.limit_states[k, "lower"].p if lo is not None else 0.0
            above = self.limit_states[k, "upper"].p if hi is not None else 0.0
            self.p_sides[k] = (below, above)
            self.p_exceed[k] = below + above

    def table(self) -> str:
        """One line per limit state: β, FORM and importance-sampling probabilities."""
        head = ["limit state".ljust(28), "beta".rjust(9), "P FORM".rjust(11),
                "P IS".rjust(11), "IS cov".rjust(8), "iter".rjust(5), "runs".rjust(5),
                "  top importance"]
        lines = ["".join(head)]
        for (r, side), ls in self.limit_states.items():
            sign = ">" if side == "upper" else "<"
            top = max(ls.importance, key=ls.importance.get) if ls.importance else "-"
            cells = [f"{r} {sign} {ls.limit:.5g}".ljust(28), f"{ls.beta:9.4f}",
                     f"{ls.p_form:11.3e}",
                     f"{ls.p_is:11.3e}" if ls.is_n else " " * 10 + "-",
                     f"{ls.is_cov:8.3f}" if ls.is_n else " " * 7 + "-",
                     f"{ls.iterations:5d}", f"{ls.runs:5d}",
                     f"  {top} {ls.importance.get(top, np.nan):.3f}"
                     + ("" if ls.converged else f"  [{ls.message}]")]
            lines.append("".join(cells))
        return "\n".join(lines)

    def __repr__(self) -> str:
        return f"ReliabilityResult({self.method}, {self.runs} runs)\n" + self.table()


def _limit_states(allowables):
    return [(k, side, lim) for k, (lo, hi) in allowables.items()
            for side, lim in (("lower", lo), ("upper", hi)) if lim is not None]


def _designs(dist, fixed: dict, X: np.ndarray) -> dict:
    cols = dist.columns(X)
    n = X.shape[0]
    cols.update({k: np.full(n, float(v)) for k, v in fixed.items() if k not in cols})
    return cols


def _check_fixed(fixed, names) -> dict:
    fixed = dict(fixed or {})
    clash = sorted(set(fixed) & set(names))
    if clash:
        raise StudyError(f"variables {clash} are both random and fixed")
    return {k: float(v) for k, v in fixed.items()}


class _Evaluator:
    """Limit-state values and standard-space gradients at points ``u``, through sweep."""

    def __init__(self, task, dist, fixed, executor):
        self.task, self.dist, self.fixed, self.executor = task, dist, fixed, executor
        self.runs = 0

    def __call__(self, points: list[np.ndarray]) -> list:
        """``(values, gradients by variable)`` or an error text for each point."""
        X = self.dist.from_standard(np.array(points))
        table = sweep(self.task, _designs(self.dist, self.fixed, X), executor=self.executor)
        self.runs += len(points)
        out = []
        for i in range(len(points)):
            if table.status[i] != "ok":
                out.append(table.errors[i])
                continue
            values = {r: float(a[i]) for r, a in table.values.items()}
            grads = {r: {v: float(g[i]) for v, g in by_v.items()}
                     for r, by_v in table.gradients.items()}
            out.append((values, grads))
        return out


def _g(row, response, side, limit, names, jac):
    """``(g, ∇_u g)`` of a limit state from an evaluated row, or None for a failed run."""
    if isinstance(row, str):
        return None
    values, grads = row
    missing = [v for v in names if v not in grads.get(response, {})]
    if response not in values or missing:
        raise StudyError(f"the task gave no value or no gradient of {response!r} by {missing}"
                         f" (responses: {sorted(values)})")
    sign = -1.0 if side == "upper" else 1.0
    gx = sign * np.array([grads[response][v] for v in names])
    return sign * (values[response] - limit), jac.T @ gx


def form(task, distributions, allowables, *, fixed=None, start=None, executor=None,
         options: SearchOptions | None = None) -> ReliabilityResult:
    """FORM of every side of every allowable, with exact gradients (module docstring).

    Parameters
    ----------
    task : SimulationTask or FunctionTask
        Responses and their gradients by the random variables (a SimulationTask without
        them is run with ``gradients=`` the random variables).
    distributions : JointDistribution or dict of str -> distribution
        The random variables.
    allowables : dict[str, (float or None, float or None)]
        ``(lower, upper)`` of responses; each finite side is a limit state.
    fixed : dict[str, float], optional
        The other design variables of the task, held at these values.
    start : dict[str, float], optional
        Start point in the variables (default: the medians, ``u = 0``).
    executor : None, "serial" or concurrent.futures.Executor
        As for :func:`~.sweep.sweep` (one process pool for the whole search by default).
    options : SearchOptions, optional
        Stopping rules (:class:`.form.SearchOptions`).

    Returns
    -------
    ReliabilityResult
    """
    dist = joint(distributions)
    fixed = _check_fixed(fixed, dist.names)
    allowables = check_allowables(allowables)
    if not allowables:
        raise StudyError("FORM needs allowables {response: (lower, upper)}")
    options = options or SearchOptions()
    task = with_gradients(task, dist.names)
    u0 = np.zeros(len(dist)) if start is None else dist.to_standard(
        np.array([[float(start[v]) for v in dist.names]]))[0]
    ex, owned = make_executor(executor)
    try:
        evaluate = _Evaluator(task, dist, fixed, ex)
        states = _run_searches(evaluate, dist, _limit_states(allowables), u0, options)
    finally:
        if owned:
            ex.shutdown(wait=True, cancel_futures=True)
    result = ReliabilityResult(list(dist.names), allowables, {}, runs=evaluate.runs)
    for (k, side, lim), (state, runs) in states.items():
        result.limit_states[k, side] = _limit_state(dist, k, side, lim, state, runs)
    result._collect()
    return result


def _run_searches(evaluate, dist, states, u0, options) -> dict:
    """All searches in lock step: each round evaluates every pending point once."""
    gens = {key: search(u0, options) for key in states}
    pending = {key: next(gen) for key, gen in gens.items()}
    runs = dict.fromkeys(states, 0)
    done = {}
    while pending:
        unique = {}
        for u in pending.values():
            unique.setdefault(u.tobytes(), u)
        rows = dict(zip(unique, evaluate(list(unique.values()))))
        for key in list(pending):
            k, side, lim = key
            u = pending[key]
            runs[key] += 1
            out = _g(rows[u.tobytes()], k, side, lim, dist.names, dist.jacobian(u))
            try:
                pending[key] = gens[key].send(out)
            except StopIteration as stop:
                done[key] = (stop.value, runs[key])
                del pending[key]
    return {key: done[key] for key in states}


def _limit_state(dist, response, side, limit, state, runs) -> LimitState:
    names = dist.names
    if state.grad is None:
        nan = np.full(len(names), np.nan)
        return LimitState(response, side, limit, np.nan, np.nan, {}, state.u, nan, {},
                          state.iterations, runs, False, state.message)
    beta = beta_of(state)
    alpha = -state.grad / np.linalg.norm(state.grad)
    gamma = importance_factors(alpha, dist.jacobian(state.u))
    x = dist.from_standard(state.u[None, :])[0]
    return LimitState(response, side, limit, beta, float(ndtr(-beta)),
                      dict(zip(names, x.tolist())), state.u.copy(), alpha,
                      dict(zip(names, (gamma * gamma).tolist())), state.iterations, runs,
                      state.converged, state.message)


def importance_sampling(task, distributions, result: ReliabilityResult, n: int, *,
                        fixed=None, seed=0, executor=None, confidence: float = 0.95
                        ) -> ReliabilityResult:
    """Importance sampling around the design points of a FORM result (module docstring):
    ``n`` draws per limit state, all limit states in one sweep (values only). Fills the
    ``p_is``, ``is_*`` fields of each limit state and returns the result with
    ``method="importance-sampling"``."""
    dist = joint(distributions)
    fixed = _check_fixed(fixed, dist.names)
    confidence = _check_confidence(confidence)
    if isinstance(n, bool) or not isinstance(n, int | np.integer) or n < 2:
        raise StudyError(f"n must be an integer >= 2 (draws per limit state), got {n!r}")
    if list(result.variables) != list(dist.names):
        raise StudyError(f"the FORM result is over {result.variables}, the distributions "
                         f"over {dist.names}")
    keys = [k for k, ls in result.limit_states.items() if np.all(np.isfinite(ls.u))
            and ls.design_point]
    if not keys:
        raise StudyError("no limit state of the FORM result has a design point")
    rng = np.random.default_rng(seed)
    U = np.concatenate([result.limit_states[k].u + rng.standard_normal((n, len(dist)))
                        for k in keys])
    table = sweep(values_only(task), _designs(dist, fixed, dist.from_standard(U)),
                  executor=executor)
    z = float(ndtri(0.5 + confidence / 2.0))
    for j, key in enumerate(keys):
        ls = result.limit_states[key]
        rows = slice(j * n, (j + 1) * n)
        ok = np.asarray(table.ok[rows])
        r = table.values[ls.response][rows][ok]
        u = U[rows][ok]
        fail = r > ls.limit if ls.side == "upper" else r < ls.limit
        w = np.exp(-u @ ls.u + 0.5 * ls.u @ ls.u)
        terms = np.where(fail, w, 0.0)
        p = float(np.mean(terms)) if terms.size else np.nan
        se = float(np.std(terms, ddof=1) / np.sqrt(terms.size)) if terms.size > 1 else np.nan
        ls.p_is, ls.is_std_error = p, se
        ls.is_cov = se / p if p > 0 else np.inf
        ls.is_ci = (max(0.0, p - z * se), p + z * se)
        ls.is_n, ls.is_failures, ls.is_failed_runs = int(ok.sum()), int(fail.sum()), \
            int((~ok).sum())
    result.runs += len(U)
    result.method = "importance-sampling"
    result._collect()
    return result
