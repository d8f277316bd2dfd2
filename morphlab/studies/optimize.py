"""Design optimization on :func:`scipy.optimize.minimize`, with one cached run per design.

:func:`optimize` runs a scipy method on a :class:`~morphlab.studies.Problem` (model or
function, objective, constraints, bounds) and returns an :class:`OptimizationResult` that
holds the whole history.

Evaluations
    One evaluation of a design serves the objective, the constraints and their gradients.
    Gradient methods (``"SLSQP"``, ``"trust-constr"``) call :func:`morphlab.sensitivities` once
    per new design (``gradient="exact"``: the problem's sensitivity method;
    ``"finite-difference"``: forward differences, n + 1 simulations); derivative-free methods
    (``"COBYLA"``, ``"COBYQA"``, ``"Nelder-Mead"``) call :func:`morphlab.simulate` once and
    evaluate the responses on its result. Evaluations are cached by the optimizer's vector
    (its exact bits, or within 4 ulp of a cached one: the same design to round-off), so
    scipy's separate calls for the objective, its gradient, the constraints and their
    Jacobian at one design cost one *run*. ``n_runs`` counts those runs,
    ``n_simulations`` the primal solves behind them (n + 1 for a forward-difference run, 1 + n
    for complex step, 1 otherwise).
Scaling
    The optimizer works on ``x_i = (p_i - low_i) / (high_i - low_i)`` in [0, 1] (every variable
    then needs finite bounds), or on ``x_i = p_i / scale_i`` with a user ``scale``. With
    ``normalize=True`` the objective is divided by ``|f(p0)|`` and constraint k by
    ``|r_k(p0)|`` (1 where that value is 0), so that both are of order one at the start;
    otherwise they are used in their own units. Constraint violations (history, feasibility
    tolerance) are measured in these same units: ``max(0, r - upper) / s_k``,
    ``max(0, lower - r) / s_k``, ``|r - equals| / s_k``.
Budgets and resume
    ``max_runs`` and ``max_time`` [s] stop the optimizer cleanly before a run that would
    exceed them; the result is then the best feasible design seen, with status ``"budget"``.
    Both count the whole history, a resumed one included. ``resume=`` restarts from the best
    design of a previous result (or file), continues its history and reuses its evaluations
    (the history records the optimizer's vector bit for bit, so a restarted method that
    retraces earlier designs finds them in the cache). A ``progress`` function that raises
    ``StopIteration`` stops the optimizer cleanly: status ``"stopped"``.
Result
    Besides the best design, its values and the history, the result holds what a SciPy user
    looks for: ``x``, ``fun``, ``jac``, the Lagrange multipliers of SLSQP and trust-constr in
    the problem's units, the active constraints and bounds, ``nit``, ``nfev``, ``njev``.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
import scipy.optimize

from ..errors import ModelError, SolverError
from .optimize_result import History, OptimizationResult
from .problem import GRADIENTS, Problem

GRADIENT_METHODS = ("SLSQP", "trust-constr")
FREE_METHODS = ("COBYLA", "COBYQA", "Nelder-Mead")
_DIAGNOSTICS = ("nit", "barrier_parameter", "optimality", "constr_violation")


class _Budget(Exception):
    """Raised inside an evaluation when the next run would exceed a budget."""


ULP_MATCH = 4.0 * np.finfo(float).eps  # a cached vector this close is the same design
ACTIVE_TOL = 1e-6  # a row or bound within this (scaled units) is active


@dataclass
class _Run:
    """The evaluations of one optimization: cache, history, budgets, scaled functions."""

    problem: Problem
    gradient: str | None
    max_runs: int | None
    max_time: float | None
    progress: object
    history: History
    n_runs: int = 0
    n_simulations: int = 0
    t_offset: float = 0.0
    f_scale: float = 1.0
    c_scales: np.ndarray = None
    cache: dict = field(default_factory=dict)
    t0: float = field(default_factory=time.perf_counter)
    last_x: np.ndarray = None
    diagnostics: dict = field(default_factory=dict)
    current: dict = None  # design of the run under way
    stopped: str = ""  # why progress asked to stop, when it did
    cached_x: list = field(default_factory=list)  # the cache's vectors, for near matches
    _stack: np.ndarray = None  # cached_x as one array (rebuilt after a store)

    def lookup(self, x: np.ndarray):
        """The cache entry of ``x``: its exact bits, else a vector within 4 ulp of it."""
        entry = self.cache.get(x.tobytes())
        if entry is None and self.cached_x:
            if self._stack is None or len(self._stack) != len(self.cached_x):
                self._stack = np.array(self.cached_x)
            near = np.all(np.abs(self._stack - x) <= ULP_MATCH * np.maximum(np.abs(x), 1.0),
                          axis=1)
            if near.any():
                return self.cache[self.cached_x[int(np.argmax(near))].tobytes()]
        return entry

    def store(self, x: np.ndarray, entry) -> None:
        if x.tobytes() not in self.cache:
            self.cached_x.append(x.copy())
        self.cache[x.tobytes()] = entry

    def elapsed(self) -> float:
        return self.t_offset + time.perf_counter() - self.t0

    def get(self, x: np.ndarray) -> tuple[dict, dict | None]:
        """Values and gradients at ``x``: from the cache or one new run."""
        x = np.asarray(x, dtype=float)
        entry = self.lookup(x)
        new = entry is None or (self.gradient is not None and entry[1] is None)
        t_start = time.perf_counter()
        if new and self.n_runs:  # the first run of a history is always made
            if self.max_runs is not None and self.n_runs >= self.max_runs:
                raise _Budget(f"run budget max_runs={self.max_runs} reached")
            if self.max_time is not None and self.elapsed() >= self.max_time:
                raise _Budget(f"time budget max_time={self.max_time} s reached")
        if new:
            self.current = {v: self.problem.to_design(x)[v] for v in self.problem.variables}
            values, grads, n_sim = self.problem.evaluate(self.problem.to_design(x),
                                                         self.gradient)
            entry = (values, grads)
            self.store(x, entry)
            self.n_runs += 1
            self.n_simulations += n_sim
        values, grads = entry
        self.history.evaluations.append({
            "design": {v: self.problem.to_design(x)[v] for v in self.problem.variables},
            "x": x.tolist(), "values": values, "gradients": grads,
            "objective": values[self.problem.objective],
            "max_violation": self.violation(values), "time": self.elapsed(),
            "duration": time.perf_counter() - t_start if new else 0.0, "new": new,
            "simulations": n_sim if new else 0})
        return entry

    def fun(self, x) -> float:
        return self.get(x)[0][self.problem.objective] / self.f_scale

    def jac(self, x) -> np.ndarray:
        g, p = self.get(x)[1][self.problem.objective], self.problem
        return np.array([g[v] for v in p.variables]) * p.factor / self.f_scale

    def g_rows(self, values) -> np.ndarray:
        """Scipy's constraint rows ``sign (r - limit) / s``, all of them."""
        return np.array([s * (values[r] - lim) for r, _, s, lim in self.problem.rows]) / \
            self.c_scales

    def violation(self, values) -> float:
        g = self.g_rows(values)
        eq = np.array([k == "eq" for _, k, _, _ in self.problem.rows], dtype=bool)
        viol = np.where(eq, np.abs(g), np.maximum(-g, 0.0))
        return float(viol.max()) if viol.size else 0.0

    def scipy_constraints(self) -> list:
        out = []
        for kind in ("ineq", "eq"):
            idx = [i for i, r in enumerate(self.problem.rows) if r[1] == kind]
            if not idx:
                continue
            out.append({"type": kind,
                        "fun": lambda x, idx=idx: self.g_rows(self.get(x)[0])[idx]})
            if self.gradient is not None:
                out[-1]["jac"] = lambda x, idx=idx: self._g_jac(x)[idx]
        return out

    def _g_jac(self, x) -> np.ndarray:
        grads = self.get(x)[1]
        p = self.problem
        rows = [[s * grads[r][v] for v in p.variables] for r, _, s, _ in p.rows]
        return np.array(rows) * p.factor[None, :] / self.c_scales[:, None]

    def record_iteration(self, x) -> None:
        """One accepted iterate (scipy's callback): history and progress line."""
        x = np.array(x, dtype=float)
        values = self.get(x)[0]
        step = 0.0 if self.last_x is None else float(np.linalg.norm(x - self.last_x))
        its = self.history.iterations
        rec = {"iteration": its[-1]["iteration"] + 1 if its else 0,
               "objective": values[self.problem.objective],
               "max_violation": self.violation(values), "step_norm": step,
               "runs": self.n_runs, "time": self.elapsed(),
               "design": {v: self.problem.to_design(x)[v] for v in self.problem.variables}}
        its.append(rec)
        self.last_x = x
        if callable(self.progress):
            try:
                self.progress(rec)
            except StopIteration as exc:
                self.stopped = f"stopped by progress at iteration {rec['iteration']}" + (
                    f": {exc}" if str(exc) else "")
                raise
        elif self.progress:
            print(f"iter {rec['iteration']:4d}  objective {rec['objective']:.8g}  violation "
                  f"{rec['max_violation']:.2e}  step {step:.2e}  runs {self.n_runs}  "
                  f"{rec['time']:.2f} s", flush=True)


def _start(problem, optimizer, gradient, max_runs, max_time, progress, resume):
    """The run object and the start vector (fresh or resumed)."""
    if max_runs is not None and not (isinstance(max_runs, int) and max_runs >= 1):
        raise ModelError(f"max_runs must be an integer >= 1 or None, got {max_runs!r}")
    if max_time is not None and not (isinstance(max_time, (int, float)) and max_time > 0):
        raise ModelError(f"max_time must be a number > 0 [s] or None, got {max_time!r}")
    grad = gradient if optimizer in GRADIENT_METHODS else None
    names = list(problem.recorded)
    if resume is None:
        hist = History(list(problem.variables), names)
        run = _Run(problem, grad, max_runs, max_time, progress, hist)
        x0 = problem.to_x(problem.p0)
    else:
        prev = resume if isinstance(resume, OptimizationResult) else \
            OptimizationResult.load(resume)
        if prev.history.variables != problem.variables or prev.history.responses != names:
            raise ModelError(f"cannot resume: variables and responses of the previous result "
                             f"{prev.history.variables}, {prev.history.responses} differ from "
                             f"the problem's {problem.variables}, {names}")
        hist = History(list(problem.variables), names, list(prev.history.evaluations),
                       list(prev.history.iterations))
        run = _Run(problem, grad, max_runs, max_time, progress, hist, prev.n_runs,
                   prev.n_simulations, prev.wall_time)
        for rec in prev.history.evaluations:
            x = _recorded_x(problem, rec)
            if rec["new"] and (run.lookup(x) is None or run.lookup(x)[1] is None):
                run.store(x, (rec["values"], rec["gradients"]))
        best = [r for r in prev.history.evaluations
                if all(r["design"][v] == prev.design[v] for v in problem.variables)]
        x0 = _recorded_x(problem, best[-1]) if best else problem.to_x(prev.design)
        if problem.normalize and prev.info.get("normalized"):
            run.f_scale = prev.info["objective_scale"]
            run.c_scales = np.asarray(prev.info["constraint_scales"], dtype=float)
        run.last_x = x0
    return run, x0


def _recorded_x(problem, rec) -> np.ndarray:
    """The optimizer vector of a history record: as recorded (files written before it was
    recorded: from the design)."""
    x = rec.get("x")
    if x is not None and not np.any(np.isnan(x)):
        return np.array(x, dtype=float)
    return problem.to_x(rec["design"])


def _normalize(run) -> None:
    """Scales of the objective and constraint rows (their magnitudes at p0 if normalized)."""
    problem = run.problem
    if run.c_scales is not None:
        return
    run.c_scales = np.ones(len(problem.rows))
    if problem.normalize:
        v0 = run.get(problem.to_x(problem.p0))[0]
        run.f_scale = abs(v0[problem.objective]) or 1.0
        run.c_scales = np.array([abs(v0[r[0]]) or 1.0 for r in problem.rows])
        for rec in run.history.evaluations:  # made before the scales were known
            rec["max_violation"] = run.violation(rec["values"])


def optimize(problem: Problem, optimizer: str = "SLSQP", *, gradient: str = "exact",
             max_runs: int | None = None, max_time: float | None = None,
             tol: float | None = None, options: dict | None = None,
             feasibility_tol: float = 1e-6, progress: bool | Callable = False,
             resume=None) -> OptimizationResult:
    """Minimise ``problem`` with :func:`scipy.optimize.minimize`.

    Parameters
    ----------
    problem : Problem
    optimizer : str
        ``"SLSQP"`` or ``"trust-constr"`` (gradients), ``"COBYLA"``, ``"COBYQA"`` or
        ``"Nelder-Mead"`` (derivative-free; Nelder-Mead takes bounds but no constraints).
    gradient : {"exact", "finite-difference"}
        Gradient source of the gradient methods (module docstring).
    max_runs : int, optional
        Budget of runs (new designs evaluated), the resumed history included.
    max_time : float, optional
        Budget of wall time [s], the resumed history included.
    tol, options :
        Passed to scipy (e.g. ``options={"ftol": 1e-10}`` for SLSQP, ``{"gtol": 1e-10}``
        for trust-constr, ``{"maxiter": 50}``).
    feasibility_tol : float
        Largest constraint violation (module docstring) of a design counted as feasible.
    progress : bool or callable
        Print one line per iteration, or call ``progress(record)`` with the iteration record.
    resume : OptimizationResult or path, optional
        Continue from this result's best design and history.

    Returns
    -------
    OptimizationResult
        Status ``"converged"`` (scipy's success), ``"failed"`` (scipy stopped otherwise),
        ``"budget"`` (a budget was reached) or ``"error"`` (a run raised a SolverError; the
        message names the design).
    """
    if not isinstance(problem, Problem):
        raise ModelError(f"problem must be a Problem, got {type(problem).__name__}")
    known = {m.lower(): m for m in GRADIENT_METHODS + FREE_METHODS}
    if not isinstance(optimizer, str) or optimizer.lower() not in known:
        raise ModelError(f"unknown optimizer {optimizer!r}; gradient-based: "
                         f"{GRADIENT_METHODS}, derivative-free: {FREE_METHODS}")
    optimizer = known[optimizer.lower()]
    if gradient not in GRADIENTS:
        raise ModelError(f"gradient must be one of {GRADIENTS}, got {gradient!r}")
    if optimizer == "Nelder-Mead" and problem.rows:
        raise ModelError("Nelder-Mead takes no constraints: use COBYLA or COBYQA")
    if not (isinstance(feasibility_tol, float) and feasibility_tol >= 0):
        raise ModelError(f"feasibility_tol must be a float >= 0, got {feasibility_tol!r}")
    run, x0 = _start(problem, optimizer, gradient, max_runs, max_time, progress, resume)
    x_bounds = [((lo - o) / f, (hi - o) / f) for (lo, hi), o, f in
                zip(problem.bounds, problem.offset, problem.factor)]
    kwargs = {"bounds": x_bounds, "tol": tol, "options": dict(options or {}),
              "callback": lambda intermediate_result: run.record_iteration(
                  intermediate_result.x)}
    if run.gradient is not None:
        kwargs["jac"] = run.jac
    if problem.rows:
        kwargs["constraints"] = run.scipy_constraints()
    x_end, status, message, res = None, "budget", "", None
    try:
        _normalize(run)
        if resume is None:
            run.record_iteration(x0)
        res = scipy.optimize.minimize(run.fun, x0, method=optimizer, **kwargs)
        x_end, message = res.x, str(res.message)
        run.diagnostics = {k: float(res[k]) for k in _DIAGNOSTICS if k in res}
        status = "converged" if res.success else "failed"
        if run.stopped:
            status, message = "stopped", run.stopped
    except StopIteration:  # progress stopped at the start design, before scipy ran
        status, message = "stopped", run.stopped
    except _Budget as exc:
        message = str(exc)
    except SolverError as exc:
        if not any(r["new"] for r in run.history.evaluations):
            raise  # the start design itself does not run
        status, message = "error", f"the run at {run.current} failed: {exc}"
    return _finish(run, optimizer, x_end, status, message, feasibility_tol, res)


def _finish(run, optimizer, x_end, status, message, feas_tol, res=None):
    """The result: scipy's final design when feasible, else the best feasible one seen."""
    problem = run.problem
    pick = None
    if x_end is not None:
        try:
            if run.violation(run.get(x_end)[0]) <= feas_tol:
                pick = run.history.evaluations[-1]
        except (_Budget, SolverError):
            pass
    if pick is None:
        seen = [r for r in run.history.evaluations if r["new"]]
        if not seen:
            raise ModelError(f"no design was evaluated: {message}")
        feasible = [r for r in seen if r["max_violation"] <= feas_tol]
        pick = min(feasible, key=lambda r: r["objective"]) if feasible else \
            min(seen, key=lambda r: r["max_violation"])
    values, viol = pick["values"], pick["max_violation"]
    info = {"objective": problem.objective, "bounds": [list(b) for b in problem.bounds],
            "normalized": problem.normalize, "objective_scale": run.f_scale,
            "constraint_scales": run.c_scales.tolist(), "feasibility_tol": feas_tol,
            "constraints": [list(r) for r in problem.rows], "scipy": run.diagnostics}
    grads = pick["gradients"]
    jac = None if grads is None else np.array(
        [grads[problem.objective][v] for v in problem.variables], dtype=float)
    counts = {k: int(res[k]) if res is not None and k in res else None
              for k in ("nit", "nfev", "njev")}
    return OptimizationResult(
        design={**problem.p0, **pick["design"]}, values=dict(values),
        objective=values[problem.objective],
        feasible=viol <= feas_tol, max_violation=viol, status=status, message=message,
        n_runs=run.n_runs, n_simulations=run.n_simulations, wall_time=run.elapsed(),
        optimizer=optimizer, gradient=run.gradient, history=run.history, info=info, jac=jac,
        multipliers=_multipliers(run, res, x_end, pick),
        active=_active(run, res, x_end, pick), **counts)


def _row_name(response: str, kind: str, sign: float, limit: float) -> str:
    op = "==" if kind == "eq" else (">=" if sign > 0 else "<=")
    return f"{response} {op} {limit:g}"


def _raw_multipliers(run, res, x_end, pick):
    """Scipy's multipliers at its final design, in SLSQP's convention (``grad f = sum lam
    grad c`` in scaled units): ``(rows (n_rows,), bounds (n_v,) or None)``, or ``(None,
    None)`` where the method gives none or the result is not scipy's final design."""
    if res is None or x_end is None or pick.get("x") != np.asarray(x_end, float).tolist():
        return None, None
    rows = run.problem.rows
    eq = [i for i, r in enumerate(rows) if r[1] == "eq"]
    ineq = [i for i, r in enumerate(rows) if r[1] == "ineq"]
    lam = np.zeros(len(rows))
    if res.get("multipliers") is not None:  # SLSQP: equalities first, then inequalities
        m = np.asarray(res["multipliers"], dtype=float)
        lam[eq + ineq] = m[:len(eq) + len(ineq)]
        return lam, None
    if res.get("v") is not None:  # trust-constr: grad f + sum v grad c = 0
        groups = [g for g in (ineq, eq) if g]  # the order of scipy_constraints()
        for g, v in zip(groups, res["v"]):
            lam[g] = -np.asarray(v, dtype=float)
        bounds = -np.asarray(res["v"][-1], dtype=float) if len(res["v"]) > len(groups) \
            else None
        return lam, bounds
    return None, None


def _multipliers(run, res, x_end, pick) -> dict:
    """Lagrange multipliers in the problem's units: d(optimal objective)/d(limit) per row;
    trust-constr's bounds as well."""
    problem = run.problem
    lam, lam_b = _raw_multipliers(run, res, x_end, pick)
    if lam is None:
        return {}
    out = {_row_name(r, k, sgn, lim): float(sgn * run.f_scale * lam[i] / run.c_scales[i])
           for i, (r, k, sgn, lim) in enumerate(problem.rows)}
    if lam_b is not None:  # grad f = lam_b (per x unit): > 0 pushes on a lower bound
        for j, (v, (lo, hi)) in enumerate(zip(problem.variables, problem.bounds)):
            per_p = run.f_scale * lam_b[j] / problem.factor[j]
            if np.isfinite(hi):
                out[f"{v} <= {hi:g}"] = float(min(per_p, 0.0))
            if np.isfinite(lo):
                out[f"{v} >= {lo:g}"] = float(max(per_p, 0.0))
    return out


def _active(run, res, x_end, pick) -> list:
    """Rows and bounds active at the picked design: equality rows, and inequality rows and
    bounds within ACTIVE_TOL (scaled units) or, where scipy gives multipliers, whose
    multiplier exceeds their slack (an interior point ends slightly inside an active one)."""
    problem = run.problem
    lam, lam_b = _raw_multipliers(run, res, x_end, pick)
    g = run.g_rows(pick["values"])
    out = [_row_name(*r) for i, (r, gi) in enumerate(zip(problem.rows, g))
           if r[1] == "eq" or gi <= ACTIVE_TOL or (lam is not None and abs(lam[i]) > gi)]
    x = _recorded_x(problem, pick)
    for j, (v, (lo, hi)) in enumerate(zip(problem.variables, problem.bounds)):
        up = (hi - problem.offset[j]) / problem.factor[j] - x[j]
        down = x[j] - (lo - problem.offset[j]) / problem.factor[j]
        push = 0.0 if lam_b is None else lam_b[j]
        if np.isfinite(hi) and (up <= ACTIVE_TOL or -push > up):
            out.append(f"{v} <= {hi:g}")
        if np.isfinite(lo) and (down <= ACTIVE_TOL or push > down):
            out.append(f"{v} >= {lo:g}")
    return out
