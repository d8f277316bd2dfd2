"""The design problem of :mod:`morphlab.morphing.optimization` solved three ways, to compare
what the gradients buy: SLSQP with exact (direct) gradients, SLSQP with forward-difference
gradients and the derivative-free COBYLA, each on its budget and with a progress line
(:func:`compare_optimizers`), and what each took to reach the exact solution (:func:`reached`).
``python -m morphlab.bench --cases optimizers`` runs the comparison on its full budget.
"""

from __future__ import annotations

from collections.abc import Callable

from ..errors import ModelError
from ..studies.problem import Problem


def reached(result, target: float) -> dict:
    """Runs, simulations and time [s] an optimization took until a feasible evaluation's
    objective was at most ``target`` (None each when it never was)."""
    sims = 0
    for ev in result.history.evaluations:
        sims += ev["simulations"] if ev["new"] else 0
        if ev["max_violation"] <= result.info["feasibility_tol"] and ev["objective"] <= target:
            runs = sum(1 for e in result.history.evaluations[:result.history.evaluations.index(
                ev) + 1] if e["new"])
            return {"runs": runs, "simulations": sims, "time": ev["time"]}
    return {"runs": None, "simulations": None, "time": None}


#: The optimizers of :func:`compare_optimizers`: key -> what its progress line calls it.
COMPARED = {"exact": "SLSQP, exact gradients", "finite_difference": "SLSQP, finite differences",
            "derivative_free": "COBYLA, derivative-free"}


class _Progress:
    """:func:`compare_optimizers`' report of one optimizer: after every iteration one line,
    rewritten in place, with the optimizer, its iteration and runs against their budgets, the
    objective and the time, and at the end how it ended; or the user's ``progress(name,
    record)``."""

    def __init__(self, progress, name: str, maxiter: int, max_runs: int | None, sims: int):
        self.progress, self.name = progress, name
        self.maxiter, self.max_runs, self.sims = maxiter, max_runs, sims

    def _runs(self, n: int) -> str:
        each = f" of {self.sims} simulations each" if self.sims > 1 else ""
        return f"{n}" + (f" of {self.max_runs}" if self.max_runs else "") + f" runs{each}"

    def __call__(self, rec: dict) -> None:
        if callable(self.progress):
            self.progress(self.name, rec)
            return
        print(f"\r{COMPARED[self.name]}: iteration {rec['iteration']} of at most "
              f"{self.maxiter}, {self._runs(rec['runs'])}, objective {rec['objective']:.6g}, "
              f"{rec['time']:.0f} s   ", end="", flush=True)

    def close(self, result=None) -> None:
        """The last line: how the optimizer ended (a newline only, when it raised)."""
        if self.progress is not True:
            return
        if result is None:
            print(flush=True)
            return
        why = result.message if len(result.message) <= 50 else result.message[:47] + "..."
        print(f"\r{COMPARED[self.name]}: {result.status} ({why}) after "
              f"{self._runs(result.n_runs)}, objective {result.objective:.6g}, "
              f"{result.wall_time:.0f} s   ", flush=True)


def compare_optimizers(pb: Problem, *, maxiter: int = 60, free_runs: int = 400,
                       fd_runs: int | None = None,
                       progress: bool | Callable[[str, dict], object] = False) -> dict:
    """The problem solved three ways: SLSQP with exact (direct) gradients, SLSQP with
    forward-difference gradients and COBYLA (derivative-free).

    Parameters
    ----------
    pb : Problem
        The design problem (:func:`problem`).
    maxiter : int
        SLSQP's iterations (both gradient sources).
    free_runs : int
        COBYLA's budget of runs (one simulation each).
    fd_runs : int, optional
        The finite-difference SLSQP's budget of runs, each a design and its ``n_x`` steps
        (``n_x + 1`` simulations); None: SLSQP's own limits (``maxiter``), which take the
        longest of the three by far (``python -m morphlab.bench --cases optimizers`` records
        that whole comparison, BENCHMARKS.md).
    progress : bool or callable
        True: for each optimizer one line, rewritten after every iteration, with its
        iteration and runs against their budgets, the objective and the time. A callable is
        called as ``progress(name, record)`` with the key of the optimizer
        (:data:`COMPARED`) and the iteration record of :func:`~morphlab.studies.optimize`.

    Returns
    -------
    dict
        Per key of :data:`COMPARED`: ``"result"`` (the OptimizationResult), ``"to_target"``
        (what it took to reach the exact solution's objective to within 0.1 % of the
        improvement it made, :func:`reached`) and ``"target"`` (that objective).
    """
    from ..studies.optimize import optimize

    if not (isinstance(progress, bool) or callable(progress)):
        raise ModelError(f"progress must be True, False or a function (name, record), got "
                         f"{progress!r}")
    n_x = len(pb.variables)
    opts = {"ftol": 1e-7, "maxiter": maxiter}
    plan = {"exact": ("SLSQP", "exact", None, opts, maxiter, 1),
            "finite_difference": ("SLSQP", "finite-difference", fd_runs, opts, maxiter,
                                  n_x + 1),
            "derivative_free": ("COBYLA", "exact", free_runs,
                                {"rhobeg": 0.1, "maxiter": free_runs}, free_runs, 1)}
    out = {}
    for name, (method, gradient, max_runs, options, limit, sims) in plan.items():
        report = _Progress(progress, name, limit, max_runs, sims) if progress else False
        try:
            out[name] = optimize(pb, method, gradient=gradient, max_runs=max_runs,
                                 options=options, progress=report)
        finally:
            if report:
                report.close(out.get(name))
    start_value = out["exact"].history.evaluations[0]["objective"]
    best = out["exact"].objective
    target = best + 1e-3 * (start_value - best)
    return {k: {"result": r, "to_target": reached(r, target), "target": target}
            for k, r in out.items()}
