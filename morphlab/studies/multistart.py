"""Multi-start optimization: one :func:`~.optimize.optimize` per start design, on any
``concurrent.futures`` executor (a local process pool, ``"serial"``, a Dask client's).

An optimization is a chain of evaluations, each depending on the last, so the unit of work
sent to a worker is a whole optimization: the problem travels as bytes (cloudpickle, as a
sweep's task), each worker warms its kernels up once and runs ``optimize`` from its start.
Results come back in the order of the starts; each is deterministic, so they are the same
on every executor. A start whose job fails (an exception, a lost worker) keeps its error
text and no result; the others are kept.
"""

from __future__ import annotations

import pickle
from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np

from ..errors import ModelError, StudyError
from .executors import in_process, make_executor
from .optimize import optimize
from .optimize_result import OptimizationResult
from .problem import Problem
from .samplers import latin_hypercube
from .sweep_result import design_table
from .tasks import describe, ensure_warm


@dataclass
class MultiStartResult:
    """The optimizations of :func:`multistart`, in the order of the starts.

    Attributes
    ----------
    starts : list of dict
        The start designs (the variables).
    results : list of OptimizationResult or None
        None where the job failed.
    errors : list of str
        The failure of each job (``""`` where it ran).
    """

    starts: list
    results: list
    errors: list = field(default_factory=list)

    @property
    def best(self) -> OptimizationResult:
        """The feasible result of least objective (the least infeasible when none is); the
        first of equal ones."""
        done = [r for r in self.results if r is not None]
        if not done:
            raise StudyError(f"every start failed: {self.errors}")
        feasible = [r for r in done if r.feasible]
        return min(feasible, key=lambda r: r.objective) if feasible else \
            min(done, key=lambda r: r.max_violation)

    def table(self) -> str:
        lines = ["start".rjust(5) + "status".rjust(11) + "objective".rjust(15)
                 + "feasible".rjust(9) + "runs".rjust(6)]
        for i, (r, e) in enumerate(zip(self.results, self.errors)):
            lines.append(f"{i:5d}" + (f"{r.status:>11s}{r.objective:15.8g}"
                                      f"{str(r.feasible):>9s}{r.n_runs:6d}" if r is not None
                                      else f"{'error':>11s}  {e}"))
        return "\n".join(lines)

    def __repr__(self) -> str:
        return f"MultiStartResult({len(self.starts)} starts)\n" + self.table()


def _serialize(problem: Problem) -> bytes:
    """The problem as bytes for worker processes (cloudpickle when installed)."""
    try:
        import cloudpickle as pickler
    except ImportError:
        pickler = pickle
    try:
        return pickler.dumps(problem)
    except Exception as exc:
        raise StudyError(f"the problem cannot be sent to worker processes: "
                         f"{type(exc).__name__}: {exc} (define its functions at module "
                         f"level, or install cloudpickle)") from exc


def _job(payload, start: dict, optimizer: str, kwargs: dict) -> OptimizationResult:
    """The worker job: one optimization from ``start``."""
    ensure_warm()
    problem = payload if isinstance(payload, Problem) else pickle.loads(payload)
    return optimize(problem.with_start(start), optimizer, **kwargs)


def multistart(problem: Problem, starts, optimizer: str = "SLSQP", *, executor=None,
               seed=None, **kwargs) -> MultiStartResult:
    """Run ``optimize(problem, optimizer, **kwargs)`` from several start designs.

    Parameters
    ----------
    problem : Problem
        Every variable needs finite bounds when ``starts`` is a number.
    starts : int, list of dict or dict of columns
        A number of starts (a Latin hypercube within the bounds, ``seed``), or the start
        designs (values of the variables; the rest of ``p0`` is kept).
    optimizer : str
        As for :func:`~.optimize.optimize`.
    executor : None, "serial" or concurrent.futures.Executor
        ``None``: a local process pool (closed at the end); ``"serial"``: one after another
        here; or any Executor, e.g. a Dask ``client.get_executor()``.
    seed : int, optional
        Of the Latin hypercube of starts.
    **kwargs
        Options of :func:`~.optimize.optimize` (``max_runs``, ``options``, ...), for each
        start; ``resume`` is not taken.

    Returns
    -------
    MultiStartResult
    """
    if not isinstance(problem, Problem):
        raise ModelError(f"problem must be a Problem, got {type(problem).__name__}")
    if "resume" in kwargs:
        raise ModelError("multistart takes no resume: each start begins a new history")
    if isinstance(starts, int | np.integer) and not isinstance(starts, bool):
        if starts < 1:
            raise ModelError(f"starts must be >= 1, got {starts}")
        bounds = dict(zip(problem.variables, problem.bounds))
        if not all(np.isfinite(b).all() for b in bounds.values()):
            raise ModelError("starts as a number needs finite bounds of every variable; "
                             "give the start designs instead")
        starts = latin_hypercube(bounds, int(starts), seed=seed)
    if isinstance(starts, Mapping) or isinstance(starts, list | tuple):
        names, table = design_table(starts)
    else:
        raise ModelError("starts must be a number, a list of dicts or a dict of columns")
    missing = [v for v in problem.variables if v not in names]
    if missing:
        raise ModelError(f"the starts lack the variables {missing}")
    designs = [dict(zip(names, map(float, row))) for row in table]
    for d in designs:
        problem.with_start(d)  # every start within the bounds, before anything runs
    ex, owned = make_executor(executor)
    try:
        payload = problem if in_process(ex) else _serialize(problem)
        futures = [ex.submit(_job, payload, d, optimizer, dict(kwargs)) for d in designs]
        results, errors = [], []
        for f in futures:
            try:
                results.append(f.result())
                errors.append("")
            except Exception as exc:  # this start fails, the others are kept
                results.append(None)
                errors.append(describe(exc))
    finally:
        if owned:
            ex.shutdown(wait=True, cancel_futures=True)
    return MultiStartResult(designs, results, errors)
