"""Reliability of responses under random variables: FORM with exact gradients.

A limit state is one side of an allowable: ``g = upper - r`` (failure ``r > upper``) or
``g = r - lower`` (failure ``r < lower``), in the standard normal space ``u`` of a
:class:`~.distributions.JointDistribution` (its Nataf transform ``x(u)``). Its gradient is
``∇_u g = (dx/du)ᵀ ∇_x g``, with ``∇_x r`` from the task (one
:func:`morphlab.sensitivities` run per point for a SimulationTask).

* :func:`form`: the design point of every limit state by the iHL-RF search (:mod:`.form`),
  ``β``, ``P_f = Φ(-β)``, importance factors; the searches of all limit states advance
  together, each round's points in one :func:`~.sweep.sweep`.
* Two failure modes: a response that fails on both sides of its nominal behaviour (a norm
  such as the largest node error) has a second design point roughly opposite the first.
  With ``SearchOptions(mirror=True)`` each search is repeated from the mirror image ``-u*``
  of its design point; a distinct second point is kept as a second mode, and ``P_f`` is that
  of the series system of the two linearised modes, ``Φ(-β1) + Φ(-β2) - Φ2(-β1, -β2; ρ)``,
  ``ρ = α1 · α2`` (e.g. Ditlevsen & Madsen, *Structural Reliability Methods*, Wiley 1996,
  ch. 14).
* :func:`~.importance.importance_sampling` checks and corrects ``P_f`` around the design
  points.

Both the probabilities below a lower and above an upper limit are disjoint events, so the
exceedance probability of a two-sided allowable is their sum.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
from scipy.special import ndtr

from ..errors import StudyError
from .distributions import joint
from .executors import make_executor
from .form import SearchOptions, beta_of, importance_factors, search
from .function_task import with_gradients
from .statistics import check_allowables
from .sweep import sweep


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
        ``Φ(-β)``, or the series-system probability of both modes when a second was found.
    design_point : dict[str, float]
        The design point in the variables (variable units).
    u : ndarray, shape (d,)
        The design point in the standard normal space.
    alpha : ndarray, shape (d,)
        Unit normal ``-∇g/|∇g|`` of the limit surface at ``u`` (towards failure).
    importance : dict[str, float]
        Importance factors ``γ_i²`` of the variables (sum 1; :func:`.form.importance_factors`).
    iterations, runs : int
        HL-RF iterations and model runs of the search (both searches with ``mirror``).
    converged : bool
    message : str
    modes : list of dict
        Every design point kept: ``u``, ``beta``, ``alpha``, ``design_point``,
        ``importance``, ``converged``, ``message``; the first is the fields above.
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
    modes: list = field(default_factory=list)
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
                "P IS".rjust(11), "IS cov".rjust(8), "modes".rjust(6), "iter".rjust(5),
                "runs".rjust(5), "  top importance"]
        lines = ["".join(head)]
        for (r, side), ls in self.limit_states.items():
            sign = ">" if side == "upper" else "<"
            top = max(ls.importance, key=ls.importance.get) if ls.importance else "-"
            cells = [f"{r} {sign} {ls.limit:.5g}".ljust(28), f"{ls.beta:9.4f}",
                     f"{ls.p_form:11.3e}",
                     f"{ls.p_is:11.3e}" if ls.is_n else " " * 10 + "-",
                     f"{ls.is_cov:8.3f}" if ls.is_n else " " * 7 + "-",
                     f"{len(ls.modes):6d}", f"{ls.iterations:5d}", f"{ls.runs:5d}",
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
         options: SearchOptions | None = None,
         progress: bool | Callable[[dict], object] = False) -> ReliabilityResult:
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
    progress : bool or callable
        True: one line, rewritten after every round of the searches, with the phase
        (``"search"``, then ``"mirror"`` for the second modes), the round, the searches still
        running and the gradient runs so far. A callable receives that record as a dict
        (keys ``"phase"``, ``"round"``, ``"running"``, ``"searches"``, ``"runs"``) instead.

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
    if not (isinstance(progress, bool) or callable(progress)):
        raise StudyError(f"progress must be True, False or a function (record), got "
                         f"{progress!r}")
    task = with_gradients(task, dist.names)
    u0 = np.zeros(len(dist)) if start is None else dist.to_standard(
        np.array([[float(start[v]) for v in dist.names]]))[0]
    ex, owned = make_executor(executor)
    evaluate = _Evaluator(task, dist, fixed, ex)
    report = _Rounds(progress, evaluate, options.max_iter)
    try:
        keys = _limit_states(allowables)
        first = _run_searches(evaluate, dist, {key: u0 for key in keys}, options,
                              report.phase("search"))
        second = {}
        if options.mirror:
            starts = {key: -st.u for key, (st, _) in first.items()
                      if st.grad is not None and np.linalg.norm(st.u) > 0}
            second = _run_searches(evaluate, dist, starts, options, report.phase("mirror"))
    finally:
        report.close()
        if owned:
            ex.shutdown(wait=True, cancel_futures=True)
    result = ReliabilityResult(list(dist.names), allowables, {}, runs=evaluate.runs)
    for key in keys:
        k, side, lim = key
        result.limit_states[k, side] = _limit_state(dist, k, side, lim, *first[key],
                                                    mirror=second.get(key))
    result._collect()
    return result


class _Rounds:
    """FORM's progress (``progress`` of :func:`form`): a record per round of the searches,
    printed as one line that each round rewrites, or given to the user's function."""

    def __init__(self, progress, evaluate: _Evaluator, max_iter: int):
        self.progress, self.evaluate, self.max_iter = progress, evaluate, max_iter
        self.printed = False

    def phase(self, name: str):
        """The reporter of one phase's rounds: ``report(round, running, searches)``."""
        def report(rnd: int, running: int, searches: int) -> None:
            rec = {"phase": name, "round": rnd, "running": running, "searches": searches,
                   "runs": self.evaluate.runs}
            if callable(self.progress):
                self.progress(rec)
            elif self.progress:
                print(f"\rFORM {name}: round {rnd}, {running} of {searches} searches running "
                      f"(at most {self.max_iter} iterations each), {rec['runs']} gradient runs"
                      "   ", end="", flush=True)
                self.printed = True
        return report

    def close(self) -> None:
        if self.printed:
            print(flush=True)


def _run_searches(evaluate, dist, starts: dict, options, report=None) -> dict:
    """Searches from ``starts[key]``, all in lock step: each round evaluates every pending
    point once, then calls ``report(round, running, searches)``. Returns ``{key:
    (SearchState, runs)}``."""
    gens = {key: search(u0, options) for key, u0 in starts.items()}
    pending = {key: next(gen) for key, gen in gens.items()}
    runs = dict.fromkeys(starts, 0)
    done = {}
    rnd = 0
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
        rnd += 1
        if report is not None:
            report(rnd, len(pending), len(starts))
    return {key: done[key] for key in starts}


def _mode(dist, state) -> dict:
    """A design point of a finished search."""
    alpha = -state.grad / np.linalg.norm(state.grad)
    gamma = importance_factors(alpha, dist.jacobian(state.u))
    x = dist.from_standard(state.u[None, :])[0]
    return {"u": state.u.copy(), "beta": beta_of(state), "alpha": alpha,
            "design_point": dict(zip(dist.names, x.tolist())),
            "importance": dict(zip(dist.names, (gamma * gamma).tolist())),
            "converged": state.converged, "message": state.message}


def series_probability(beta1: float, beta2: float, rho: float) -> float:
    """``P(A1 ∪ A2)`` of two linearised modes ``A_k = {α_k · u >= β_k}`` with ``ρ = α1·α2``:
    ``Φ(-β1) + Φ(-β2) - Φ2(-β1, -β2; ρ)``, the bivariate term by quadrature of
    ``∫_{-∞}^{-β1} φ(x) Φ((-β2 - ρ x) / sqrt(1 - ρ²)) dx`` (accurate also in the far tails)."""
    from scipy.integrate import quad

    if rho >= 1.0 - 1e-12:
        return float(ndtr(-min(beta1, beta2)))
    s = np.sqrt(1.0 - rho * rho)
    both, _ = quad(lambda x: np.exp(-0.5 * x * x) / np.sqrt(2 * np.pi)
                   * ndtr((-beta2 - rho * x) / s), -np.inf, -beta1, epsabs=0.0,
                   epsrel=1e-10, limit=200)
    return float(ndtr(-beta1) + ndtr(-beta2) - both)


def _limit_state(dist, response, side, limit, state, runs, mirror=None) -> LimitState:
    if state.grad is None:
        nan = np.full(len(dist), np.nan)
        return LimitState(response, side, limit, np.nan, np.nan, {}, state.u, nan, {},
                          state.iterations, runs, False, state.message)
    modes = [_mode(dist, state)]
    iterations = state.iterations
    if mirror is not None:
        other, more = mirror
        runs += more
        iterations += other.iterations
        distinct = np.linalg.norm(other.u - state.u) > 1e-3 * max(np.linalg.norm(state.u), 1)
        if other.grad is not None and other.converged and distinct:
            modes.append(_mode(dist, other))
            modes.sort(key=lambda m: m["beta"])
    m = modes[0]
    p = float(ndtr(-m["beta"])) if len(modes) == 1 else series_probability(
        modes[0]["beta"], modes[1]["beta"], float(modes[0]["alpha"] @ modes[1]["alpha"]))
    return LimitState(response, side, limit, m["beta"], p, m["design_point"], m["u"],
                      m["alpha"], m["importance"], iterations, runs,
                      all(md["converged"] for md in modes), state.message, modes)
