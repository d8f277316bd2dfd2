"""Propagate random design variables through a task: one front door to FOSM, Monte Carlo,
FORM and importance sampling, all through :func:`~.sweep.sweep` (so on any executor, Dask
included, with the same numbers on each).

===========================  ========================================  =====================
method                       what it gives                             model runs
===========================  ========================================  =====================
``"fosm"``                   mean = response at the means, std from    1 gradient run
                             ``G C Gᵀ``; normal exceedance
                             (:func:`~.uncertainty.fosm`)
``"monte-carlo"``            sample mean, std with BCa bootstrap       ``n``
                             intervals, exceedance frequencies with
                             Clopper–Pearson intervals
                             (:mod:`.statistics`)
``"form"``                   per limit state: design point, β,         ~5–20 gradient runs
                             ``Φ(-β)``, importance factors              per limit state
                             (:mod:`.reliability`)
``"importance-sampling"``    FORM, then ``n`` draws around each design  FORM + ``n`` per
                             point: unbiased ``P_f`` with its c.o.v.    limit state
===========================  ========================================  =====================
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from ..errors import StudyError
from .distributions import joint
from .form import SearchOptions
from .function_task import values_only, with_gradients
from .importance import importance_sampling
from .reliability import _check_fixed, _designs, form
from .samplers import SAMPLERS, sample
from .statistics import _check_confidence, check_allowables, sample_result
from .sweep import sweep
from .uncertainty import fosm

METHODS = ("fosm", "monte-carlo", "form", "importance-sampling")


def propagate(task, distributions, method: str = "monte-carlo", *,
              allowables: Mapping | None = None, fixed: Mapping | None = None,
              n: int | None = None, sampling: str = "lhs", seed=0, executor=None,
              confidence: float = 0.95, form_options: SearchOptions | None = None,
              progress: bool = False):
    """Distributions of the responses of ``task`` under random variables.

    Parameters
    ----------
    task : SimulationTask, FunctionTask or callable
        The model: a :class:`~.tasks.SimulationTask` (FOSM and FORM run it with gradients by
        the random variables, Monte Carlo and importance sampling without), a
        :class:`~.function_task.FunctionTask`, or (Monte Carlo only) a function
        ``p -> dict``.
    distributions : JointDistribution or dict of str -> distribution
        The random variables (:class:`~.distributions.JointDistribution`: any SciPy
        marginals, correlation through a Gaussian copula).
    method : {"fosm", "monte-carlo", "form", "importance-sampling"}
        Module docstring.
    allowables : dict[str, (float or None, float or None)], optional
        ``(lower, upper)`` per response: exceedance probabilities (FORM and importance
        sampling need them: each finite side is a limit state).
    fixed : dict[str, float], optional
        The task's other design variables, held at these values.
    n : int, optional
        Samples (Monte Carlo), draws per limit state (importance sampling).
    sampling : {"lhs", "sobol", "halton", "mc"}
        Monte Carlo's sampler (:func:`~.samplers.sample`; a Latin hypercube by default).
    seed : int
        Of the sample, the draws and the bootstrap.
    executor : None, "serial" or concurrent.futures.Executor
        As for :func:`~.sweep.sweep` (e.g. ``client.get_executor()`` of a Dask client).
    confidence : float
        Of the intervals.
    form_options : SearchOptions, optional
        Stopping rules of the FORM search.
    progress : bool
        Report the runs as they finish: a progress bar for the sweeps of Monte Carlo samples
        and importance-sampling draws, a line per round for the FORM search. (A function
        instead of the printed lines: ``progress=`` of :func:`~.sweep.sweep`,
        :func:`~.reliability.form` or :func:`~.importance.importance_sampling`.)

    Returns
    -------
    UncertaintyResult (fosm), SampleResult (monte-carlo) or ReliabilityResult (form,
    importance-sampling)
        Each with ``p_exceed`` and ``p_sides`` per response with allowables.
    """
    if method not in METHODS:
        raise StudyError(f"method must be one of {METHODS}, got {method!r}")
    dist = joint(distributions)
    fixed = _check_fixed(fixed, dist.names)
    confidence = _check_confidence(confidence)
    allowables = check_allowables(allowables)
    if not isinstance(progress, bool):
        raise StudyError(f"progress must be True or False, got {progress!r} (for a function, "
                         "call sweep, form or importance_sampling with progress=function)")
    if method == "fosm":
        return _fosm(task, dist, fixed, allowables, executor)
    if method == "monte-carlo":
        if sampling not in SAMPLERS:
            raise StudyError(f"sampling must be one of {sorted(SAMPLERS)}, got {sampling!r}")
        _count(n, "Monte Carlo needs n, the number of samples")
        table = sweep(values_only(task), {**sample(dist, n, sampling, seed=seed),
                                          **{k: np.full(n, v) for k, v in fixed.items()}},
                      executor=executor, progress=progress)
        return sample_result(table, dist.names, allowables, confidence, seed,
                             f"monte-carlo ({sampling})")
    if method == "importance-sampling":
        _count(n, "importance sampling needs n, the draws per limit state")
    result = form(task, dist, allowables, fixed=fixed, executor=executor,
                  options=form_options, progress=progress)
    if method == "form":
        return result
    return importance_sampling(task, dist, result, n, fixed=fixed, seed=seed,
                               executor=executor, confidence=confidence, progress=progress)


def _count(n, what: str) -> None:
    if isinstance(n, bool) or not isinstance(n, int | np.integer) or n < 2:
        raise StudyError(f"{what} (an integer >= 2), got {n!r}")


def _fosm(task, dist, fixed, allowables, executor):
    """FOSM at the means: one gradient run, the covariance of the copula's variables."""
    names = dist.names
    design = {**dict(zip(names, dist.mean().tolist())), **fixed}
    table = sweep(with_gradients(task, names), _designs(dist, fixed, dist.mean()[None, :]),
                  executor=executor)
    if not table.ok[0]:
        raise StudyError(f"the run at the means {design} failed: {table.errors[0]}")
    values = {r: float(a[0]) for r, a in table.values.items()}
    grads = {r: {v: float(by_v[v][0]) for v in names if v in by_v}
             for r, by_v in table.gradients.items()}
    missing = [r for r in values if len(grads.get(r, {})) < len(names)]
    if missing:
        raise StudyError(f"the task gave no gradients of {missing} by every variable of "
                         f"{names}")
    return fosm((values, grads), cov=dist.covariance(), variables=names,
                allowables=allowables)
