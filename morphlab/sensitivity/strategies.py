"""The sensitivity methods as strategy objects that share the primal time loop.

Each strategy is a small frozen dataclass of its options with one ``run``: it gets the nominal
system, the settings, the design and the perturbed designs (:class:`Setup`) and returns a
:class:`Run` — the primal result, one perturbed result per variable over which the responses are
differentiated (:meth:`column`), the kept sensitivity histories, timings and statistics. The
strings of :func:`morphlab.sensitivities` are aliases (:func:`resolve`).

* :class:`Direct`: direct differentiation reusing the primal's factorizations; its partial
  derivatives by complex step (exact) or, ``partials="forward-difference"``, by the paper's
  semi-analytical forward difference (``"direct-fd"``);
* :class:`ComplexStep`: the whole run in complex arithmetic per variable, the reference;
* :class:`FiniteDifference`: forward or central differences of whole runs.
"""

from __future__ import annotations

import time as _time
from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np

from ..compile import System
from ..errors import SensitivityError
from ..results.result import Result
from ..solve.settings import Settings
from ..solve.timeloop import integrate
from .adjoint import adjoint_run
from .direct import direct_run
from .histories import HISTORIES, to_store
from .perturb import (
    CS_STEP,
    ComplexDesigns,
    pseudo_load_data,
    relative_steps,
    shifted_systems,
)


@dataclass
class Setup:
    """What every strategy starts from: the nominal system, the settings, the parametric
    model and design, the variables, their complex-step systems (``designs``, perhaps still
    compiling on a thread: :class:`~morphlab.sensitivity.perturb.ComplexDesigns`), the
    responses and the histories to keep (``store``)."""

    sys0: System
    settings: Settings
    build: object
    p0: dict
    names: list
    designs: ComplexDesigns | None
    responses: dict
    store: object = "auto"
    progress: bool = False
    steps: dict = field(default_factory=dict)

    @property
    def complex_systems(self) -> list:
        """The complex-step systems of the variables (waits for a background compile)."""
        return self.designs.result()


class Run(NamedTuple):
    """What a strategy returns (module docstring). A strategy that differentiates the
    responses itself (the adjoint) returns their ``values`` and ``gradients`` (name -> (n_x,))
    and no perturbed results."""

    result: Result
    perturbed: list
    state: dict
    timing: dict
    stats: dict
    values: dict | None = None
    gradients: dict | None = None


def _timed_runs(setup: Setup, systems_per_variable) -> Run:
    """The primal run and whole runs of perturbed systems (complex step, differences)."""
    t0 = _time.perf_counter()
    res0 = integrate(setup.sys0, setup.settings, progress=setup.progress)
    t_primal = _time.perf_counter() - t0
    perturbed, nfac = [], res0.n_factorizations
    for systems, polish in systems_per_variable:
        runs = [integrate(s, setup.settings, scale=res0.scale, polish=polish,
                          progress=setup.progress) for s in systems]
        nfac += sum(r.n_factorizations for r in runs)
        perturbed.append(runs[0] if len(runs) == 1 else tuple(runs))
    total = _time.perf_counter() - t0
    timing = {"primal": t_primal, "sensitivity": total - t_primal, "run": total}
    return Run(res0, perturbed, {}, timing, {"n_factorizations": nfac})


@dataclass(frozen=True)
class Direct:
    """Direct differentiation (``docs/theory.md`` §6).

    Parameters
    ----------
    partials : {"complex-step", "forward-difference"}
        How the explicit partial derivatives of the residual are formed.
    step : float
        Relative step of the forward-difference partials.
    refine : int
        Iterative-refinement sweeps against the exact converged matrix (each contracts the
        error by O(last Newton correction) <= 1e-10: one is enough).
    refine_tol : float
        Refine only where the last Newton position correction exceeds this (relative to the
        model size): below it the lagged factorization's O(|dz|) error is under the accuracy
        the sensitivities are verified to.
    block_bytes : int
        Memory of the converged steps and factorizations kept before their sensitivities are
        solved as one block (the results do not depend on it).
    """

    partials: str = "complex-step"
    step: float = 1e-6
    refine: int = 1
    refine_tol: float = 1e-12
    block_bytes: int = 64 * 2**20

    complex_results = True  # its perturbed results are complex: responses by complex step

    @property
    def name(self) -> str:
        return "direct" if self.partials == "complex-step" else "direct-fd"

    def __post_init__(self):
        if self.partials not in ("complex-step", "forward-difference"):
            raise SensitivityError(f"Direct: partials must be 'complex-step' or "
                                   f"'forward-difference', got {self.partials!r}")
        _check_step(self.step)
        if not (isinstance(self.refine, int) and self.refine >= 0):
            raise SensitivityError(f"Direct: refine must be an integer >= 0, got "
                                   f"{self.refine!r}")

    def run(self, setup: Setup) -> Run:
        times = setup.settings.t_start + setup.settings.h * np.arange(setup.settings.n_steps + 1)
        if self.partials == "complex-step":
            psys = setup.complex_systems
            pert = np.full(len(setup.names), 1j * CS_STEP)
        else:
            steps = relative_steps(setup.p0, setup.names, self.step)
            psys = shifted_systems(setup.build, setup.p0, setup.names, setup.sys0, steps)
            pert = np.array([steps[v] for v in setup.names])
        data = pseudo_load_data(setup.sys0, psys, pert, times)
        kept = to_store(setup.store, setup.responses, setup.sys0, setup.settings)
        return Run(*direct_run(setup.sys0, setup.settings, setup.complex_systems, data, kept,
                               refine=self.refine, refine_tol=self.refine_tol,
                               block_bytes=self.block_bytes, progress=setup.progress))

    def column(self, fn, base: Result, pert, step):
        return np.imag(fn(pert)) / CS_STEP


@dataclass(frozen=True)
class ComplexStep:
    """Every variable's whole run in complex arithmetic with ``p + i h e_i``: no truncation
    error, the reference the other methods are verified against."""

    name = "complex-step"
    complex_results = True

    def run(self, setup: Setup) -> Run:
        return _timed_runs(setup, [([s], 1) for s in setup.complex_systems])

    def column(self, fn, base: Result, pert, step):
        return np.imag(fn(pert)) / CS_STEP


@dataclass(frozen=True)
class FiniteDifference:
    """Finite differences of whole runs: ``kind="forward"`` (n_x + 1 runs) or ``"central"``
    (2 n_x + 1), relative steps ``step |p_i|``."""

    kind: str = "forward"
    step: float = 1e-6

    complex_results = False

    def __post_init__(self):
        if self.kind not in ("forward", "central"):
            raise SensitivityError(f"FiniteDifference: kind must be 'forward' or 'central', "
                                   f"got {self.kind!r}")
        _check_step(self.step)

    @property
    def name(self) -> str:
        return f"{self.kind}-difference"

    def run(self, setup: Setup) -> Run:
        steps = setup.steps
        signs = (1.0,) if self.kind == "forward" else (1.0, -1.0)
        systems = [shifted_systems(setup.build, setup.p0, setup.names, setup.sys0, steps, s)
                   for s in signs]
        return _timed_runs(setup, [(list(per), 0) for per in zip(*systems)])

    def column(self, fn, base: Result, pert, step):
        if self.kind == "forward":
            return (np.asarray(fn(pert)) - np.asarray(fn(base))) / step
        plus, minus = pert
        return (np.asarray(fn(plus)) - np.asarray(fn(minus))) / (2.0 * step)


@dataclass(frozen=True)
class Adjoint:
    """The discrete adjoint of the time loop (:mod:`morphlab.sensitivity.adjoint`): one
    backward sweep for all responses, the variables entering only through the derivatives of
    the compiled data. Every response needs a ``vjp`` (the factories of
    :mod:`morphlab.responses` have one).

    Parameters
    ----------
    refine, refine_tol :
        As for :class:`Direct`: refinement of the transposed solves against the exact
        converged matrix.
    memory : int
        Bytes of converged states and factorizations kept for the backward sweep; a longer
        run keeps checkpoints instead and recomputes each segment of steps once more.
    """

    refine: int = 1
    refine_tol: float = 1e-12
    memory: int = 2**30

    name = "adjoint"
    complex_results = False

    #: The perturbed designs may compile on a thread during the primal run (they are first
    #: needed by the backward sweep).
    overlaps_designs = True

    def run(self, setup: Setup) -> Run:
        times = setup.settings.t_start + setup.settings.h * np.arange(setup.settings.n_steps + 1)

        def data():
            return pseudo_load_data(setup.sys0, setup.complex_systems,
                                    np.full(len(setup.names), 1j * CS_STEP), times)

        res0, values, gradients, timing, stats = adjoint_run(
            setup.sys0, setup.settings, setup.responses, setup.designs, data,
            refine=self.refine, refine_tol=self.refine_tol, memory=self.memory,
            progress=setup.progress)
        return Run(res0, [], {}, timing, stats, values, gradients)



@dataclass(frozen=True)
class Auto:
    """Direct differentiation or the adjoint, whichever costs less here: the adjoint when every
    response has a ``vjp`` and there are more than ``crossover`` design variables per response
    (its cost grows with the responses, the direct method's with the variables; the crossover
    is measured in BENCHMARKS.md, "Cost against the number of variables")."""

    crossover: float = 1.0

    complex_results = False

    def choose(self, setup: Setup):
        """The strategy for this set-up."""
        has_vjp = all(hasattr(fn, "vjp") for fn in setup.responses.values())
        if has_vjp and len(setup.names) > self.crossover * len(setup.responses):
            return Adjoint()
        return Direct()

    def run(self, setup: Setup) -> Run:
        raise SensitivityError("Auto chooses a strategy first (Auto.choose)")  # pragma: no cover


def _check_step(step) -> None:
    if not (isinstance(step, float) and 0 < step < 1):
        raise SensitivityError(f"step must be a float in (0, 1), got {step!r}")


#: The method strings of :func:`morphlab.sensitivities` and the strategies they stand for.
ALIASES = ("auto", "direct", "direct-fd", "adjoint", "complex-step", "forward-difference",
           "central-difference")


def resolve(method, step: float = 1e-6, refine: int = 1):
    """A strategy object for ``method`` (a strategy, or one of :data:`ALIASES`; ``step`` and
    ``refine`` configure the aliases)."""
    if isinstance(method, (Direct, Adjoint, ComplexStep, FiniteDifference, Auto)):
        return method
    if method == "auto":
        return Auto()
    if method == "direct":
        return Direct(refine=refine)
    if method == "adjoint":
        return Adjoint(refine=refine)
    if method == "direct-fd":
        return Direct(partials="forward-difference", step=step, refine=refine)
    if method == "complex-step":
        return ComplexStep()
    if method in ("forward-difference", "central-difference"):
        return FiniteDifference(method.split("-")[0], step)
    raise SensitivityError(f"unknown method {method!r}; choose one of {', '.join(ALIASES)} or "
                           "a strategy (Direct(), ComplexStep(), FiniteDifference())")


__all__ = ["ALIASES", "Adjoint", "Auto", "ComplexStep", "Direct", "FiniteDifference",
           "HISTORIES", "Run", "Setup", "resolve"]
