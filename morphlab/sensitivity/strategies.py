"""The sensitivity methods as strategy objects that share the primal time loop.

Every method is a :class:`Strategy`: a small frozen dataclass of its options with one
:meth:`~Strategy.run`, which gets the nominal system, the settings, the design and the
responses (:class:`Setup`) and returns a :class:`Run` — the primal result, one perturbed result
per variable over which the responses are differentiated (:meth:`~Strategy.column`), the kept
sensitivity histories, timings and statistics (or the responses' values and gradients
themselves). :func:`morphlab.sensitivities` takes any strategy, a user's subclass included; its
method strings are aliases of the default strategies (:func:`resolve`).

* :class:`Direct`: direct differentiation with the primal's factorizations; its partial
  derivatives by complex step (exact) or, ``partials="forward-difference"``, by the paper's
  semi-analytical forward difference (``"direct-fd"``);
* :class:`Adjoint`: the discrete adjoint, one backward sweep for all variables;
* :class:`Auto`: whichever of the two costs less for the set-up (the default);
* :class:`ComplexStep`: the whole run in complex arithmetic per variable, the reference;
* :class:`FiniteDifference`: forward or central differences of whole runs.
"""

from __future__ import annotations

import abc
import time as _time
from dataclasses import dataclass, field
from functools import cached_property
from typing import NamedTuple

import numpy as np

from ..compile import System
from ..compile.system import time_table
from ..errors import SensitivityError
from ..results.result import Result
from ..solve.settings import Settings
from ..solve.timeloop import integrate
from . import beside
from .adjoint import adjoint_run
from .beside import spare_core
from .designs import CS_STEP, changes, compile_perturbed, pseudo_data, relative_steps
from .direct import direct_run
from .histories import HISTORIES, to_store


@dataclass
class Setup:
    """What every strategy starts from: the nominal system, the settings, the parametric
    model and design, the variables, the responses and the histories to keep (``store``).
    The complex-step changes of the variables are formed once, when a strategy first asks
    (:attr:`complex_changes`)."""

    sys0: System
    settings: Settings
    build: object
    p0: dict
    names: list
    responses: dict
    store: object = "auto"
    progress: bool = False

    @property
    def times(self) -> np.ndarray:
        s = self.settings
        return s.t_start + s.h * np.arange(s.n_steps + 1)

    @cached_property
    def complex_changes(self) -> list:
        """The complex-step :class:`~morphlab.sensitivity.designs.Change` of every variable
        (its perturbed system included)."""
        return changes(self.build, self.p0, self.names, self.sys0, self.times)

    @property
    def complex_systems(self) -> list:
        return [ch.system for ch in self.complex_changes]


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


class Strategy(abc.ABC):
    """A sensitivity method (module docstring). Subclasses set :attr:`name` and
    :attr:`complex_results` and implement :meth:`run`; :meth:`choose` lets a strategy pick
    another for a set-up (:class:`Auto`), :meth:`column` differentiates a response over a
    perturbed result and :meth:`primal_solves` is what one gradient costs in primal runs
    (a study's budget counts it)."""

    name: str = "strategy"
    #: Are the perturbed results complex (responses differentiated by complex step)?
    complex_results: bool = False

    def choose(self, setup: Setup) -> Strategy:
        """The strategy that runs for ``setup`` (itself, by default)."""
        return self

    @abc.abstractmethod
    def run(self, setup: Setup) -> Run:
        """The primal run and what the responses are differentiated over."""

    def column(self, fn, base: Result, pert, step):
        """``d fn / d p_i`` from the perturbed result ``pert`` of variable ``i``."""
        return np.imag(fn(pert)) / CS_STEP

    def primal_solves(self, n_x: int) -> int:
        """How many primal runs a gradient of ``n_x`` variables takes."""
        return 1


def design_data(setup: Setup, chs: list, pert: np.ndarray, T0) -> tuple:
    """What the direct and adjoint methods read of the variables' changes ``chs`` (their
    perturbations ``pert``, ``T0`` the nominal time values): ``(ps, dq0, dv0)``, the
    pseudo-load data and the derivatives of the initial state (n_dof, n_x) each."""
    ps = pseudo_data(setup.sys0, chs, pert, T0)
    return (ps, np.stack([ch.dq0 for ch in chs], axis=1),
            np.stack([ch.dv0 for ch in chs], axis=1))


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


def _check_step(step) -> None:
    if not (isinstance(step, float) and 0 < step < 1):
        raise SensitivityError(f"step must be a float in (0, 1), got {step!r}")


def _check_refine(owner: str, refine) -> None:
    if not (isinstance(refine, int) and not isinstance(refine, bool) and refine >= 0):
        raise SensitivityError(f"{owner}: refine must be an integer >= 0, got {refine!r}")


def _check_overlap(owner: str, overlap) -> None:
    if overlap not in (None, True, False):
        raise SensitivityError(f"{owner}: overlap must be True, False or None, got "
                               f"{overlap!r}")


@dataclass(frozen=True)
class Direct(Strategy):
    """Direct differentiation (``docs/theory.md`` §6; :mod:`morphlab.sensitivity.direct`).

    Parameters
    ----------
    partials : {"complex-step", "forward-difference"}
        How the explicit partial derivatives of the residual are formed (where the residual
        is not linear in the data a variable changes).
    step : float
        Relative step of the forward-difference partials.
    reuse : bool
        Solve with the primal's last Newton matrix and its ``Dq``, ``Dv`` (no matrix formed;
        relative error of the order of the Newton tolerance); False forms them at the
        converged state and refines (exact to round-off).
    refine : int
        Refinement sweeps of the exact variant.
    overlap : bool, optional
        Form the variables' changes and pseudo-load data, and the sensitivities of each
        chunk of steps, in a thread while the primal's compiled steps go on
        (:mod:`morphlab.sensitivity.direct`: the same results, bit for bit; the wall time of
        the primal and the sensitivities' larger share, the other hidden, at the price of some
        more CPU time); None (the default): where a core is idle when the gradient starts
        (:func:`~morphlab.sensitivity.beside.spare_core`).
    vjp : bool
        Where every response has a ``vjp`` (the factories of :mod:`morphlab.responses`),
        differentiate each by the chain rule over the sensitivity histories, one pass per
        response (:func:`~morphlab.sensitivity.direct.response_gradients`); False, or a
        response without one: evaluate each response on every variable's complex result
        (one pass per response and variable). The two agree to round-off.
    """

    partials: str = "complex-step"
    step: float = 1e-6
    reuse: bool = True
    refine: int = 1
    overlap: bool | None = None
    vjp: bool = True

    complex_results = True

    @property
    def name(self) -> str:
        return "direct" if self.partials == "complex-step" else "direct-fd"

    def __post_init__(self):
        if self.partials not in ("complex-step", "forward-difference"):
            raise SensitivityError(f"Direct: partials must be 'complex-step' or "
                                   f"'forward-difference', got {self.partials!r}")
        _check_step(self.step)
        _check_refine("Direct", self.refine)
        _check_overlap("Direct", self.overlap)
        if not isinstance(self.vjp, bool):
            raise SensitivityError(f"Direct: vjp must be True or False, got {self.vjp!r}")

    def run(self, setup: Setup) -> Run:
        def design():  # the first piece of the sensitivity work (DirectHook)
            cs = setup.complex_changes  # the perturbed results' systems (and the partials)
            T0 = time_table(setup.sys0, setup.times)
            if self.partials == "complex-step":
                chs, pert = cs, np.full(len(setup.names), 1j * CS_STEP)
            else:
                steps = relative_steps(setup.p0, setup.names, self.step)
                chs = changes(setup.build, setup.p0, setup.names, setup.sys0, setup.times,
                              steps)
                pert = np.array([steps[v] for v in setup.names])
            kept = to_store(setup.store, setup.responses, setup.sys0, setup.settings)
            return (*design_data(setup, chs, pert, T0), kept)

        overlap = spare_core() if self.overlap is None else self.overlap
        by_vjp = self.vjp and all(hasattr(fn, "vjp") for fn in setup.responses.values())
        return Run(*direct_run(setup.sys0, setup.settings, design,
                               lambda: setup.complex_changes,
                               responses=setup.responses if by_vjp else None,
                               reuse=self.reuse, refine=self.refine, overlap=overlap,
                               progress=setup.progress))


@dataclass(frozen=True)
class Adjoint(Strategy):
    """The discrete adjoint of the time loop (:mod:`morphlab.sensitivity.adjoint`): one
    backward sweep for all responses. Every response needs a ``vjp`` (the factories of
    :mod:`morphlab.responses` have one).

    Parameters
    ----------
    reuse, refine :
        As for :class:`Direct`, for the transposed solves.
    memory : int
        Bytes of the primal's record the sweep reads (factors, matrices, states); a longer
        run keeps checkpoints instead and recomputes each segment of steps once more.
    overlap : bool, optional
        Form the variables' changes and pseudo-load data in a thread while the primal's
        compiled steps run (:mod:`morphlab.sensitivity.beside`: the same results, the wall
        time of the set-up hidden at the price of some more CPU time, the two threads
        slowing each other a little); None (the default): where a core is idle when the
        gradient starts (:func:`~morphlab.sensitivity.beside.spare_core`).
    """

    reuse: bool = True
    refine: int = 1
    memory: int = 2**30
    overlap: bool | None = None

    name = "adjoint"

    def __post_init__(self):
        _check_refine("Adjoint", self.refine)
        if not (isinstance(self.memory, int) and self.memory > 0):
            raise SensitivityError(f"Adjoint: memory must be a positive integer of bytes, got "
                                   f"{self.memory!r}")
        _check_overlap("Adjoint", self.overlap)

    def run(self, setup: Setup) -> Run:
        def design():  # what the sweep reads of the variables (module beside)
            cs = setup.complex_changes
            T0 = time_table(setup.sys0, setup.times)
            return (*design_data(setup, cs, np.full(len(setup.names), 1j * CS_STEP), T0), cs)

        overlap = spare_core() if self.overlap is None else self.overlap
        res0, values, gradients, timing, stats = adjoint_run(
            setup.sys0, setup.settings, setup.responses, design, overlap=overlap,
            reuse=self.reuse, refine=self.refine, memory=self.memory,
            progress=setup.progress)
        return Run(res0, [], {}, timing, stats, values, gradients)


@dataclass(frozen=True)
class Auto(Strategy):
    """Direct differentiation or the adjoint, whichever costs less here.

    The direct method's solves grow with the variables, the adjoint's with the responses; the
    direct method evaluates each variable's explicit part at every step, the adjoint those of
    the variables that are not sections or materials, which share one pass a step. Where the
    process may use two cores or more and the direct method's ``overlap`` is not False, its
    sensitivities run beside the primal's steps on the second core (:class:`Direct`), which
    hides them until they outgrow the primal: then the direct method is the faster in wall
    time up to some twenty variables, the adjoint beyond. So the rule is:

    * the direct method where a response has no ``vjp`` (the adjoint needs one for each), or
      where there are at most ``crossover`` variables per response;
    * else, with two usable cores or more (:func:`~morphlab.sensitivity.beside.usable_cores`)
      and ``direct.overlap`` not False, the direct method up to ``beside_variables``
      variables;
    * else the adjoint.

    Both figures are measured (BENCHMARKS.md, cases morphing, variables and pendulum).
    ``crossover`` (0.15) is the crossing of the two methods' costs without the direct method's
    thread: on the 240-element skin the adjoint is faster with one variable and one to three
    responses, the two tie at six, direct is faster at twelve. ``beside_variables`` (24) is
    where they cross with it on two idle cores: with three responses, over the last two
    records, the direct method cost 1.05-1.23 primal runs at 1, 5 and 20 variables on the skin
    and 1.04-1.16 with the morphing study's five, the adjoint 1.08-1.39 and 1.28-1.32 (at 20
    variables the two tie); at 32 variables of the flexible pendulum and 50 of the skin the
    adjoint is the faster.

    The choice reads the model and the cores the process may use, not the load of the moment:
    the two methods agree to round-off, not bit for bit, and a choice by the load would change
    a gradient's last bits from run to run. On a machine whose other core is busy the direct
    method runs without its thread (``overlap=None``: :func:`~morphlab.sensitivity.beside.
    spare_core`) and costs about its CPU time: on the skin 1.3-1.6 primal runs up to five
    variables and 1.8-2.0 at twenty (measured with the thread, which itself costs some), the
    adjoint 1.3-1.5.
    """

    crossover: float = 0.15
    beside_variables: int = 24
    direct: Direct = field(default_factory=Direct)
    adjoint: Adjoint = field(default_factory=Adjoint)

    name = "auto"

    def choose(self, setup: Setup) -> Strategy:
        """The strategy that runs: :attr:`direct` or :attr:`adjoint` (class docstring)."""
        n_x, m = len(setup.names), len(setup.responses)
        has_vjp = all(hasattr(fn, "vjp") for fn in setup.responses.values())
        if not has_vjp or n_x <= self.crossover * m:
            return self.direct
        beside_ok = self.direct.overlap is not False and beside.usable_cores() >= 2
        if beside_ok and n_x <= self.beside_variables:
            return self.direct
        return self.adjoint

    def run(self, setup: Setup) -> Run:
        return self.choose(setup).run(setup)


@dataclass(frozen=True)
class ComplexStep(Strategy):
    """Every variable's whole run in complex arithmetic with ``p + i h e_i``: no truncation
    error, the reference the other methods are verified against."""

    name = "complex-step"
    complex_results = True

    def run(self, setup: Setup) -> Run:
        return _timed_runs(setup, [([s], 1) for s in setup.complex_systems])

    def primal_solves(self, n_x: int) -> int:
        return n_x + 1


@dataclass(frozen=True)
class FiniteDifference(Strategy):
    """Finite differences of whole runs: ``kind="forward"`` (n_x + 1 runs) or ``"central"``
    (2 n_x + 1), relative steps ``step |p_i|``."""

    kind: str = "forward"
    step: float = 1e-6

    def __post_init__(self):
        if self.kind not in ("forward", "central"):
            raise SensitivityError(f"FiniteDifference: kind must be 'forward' or 'central', "
                                   f"got {self.kind!r}")
        _check_step(self.step)

    @property
    def name(self) -> str:
        return f"{self.kind}-difference"

    def steps(self, setup: Setup) -> dict:
        return relative_steps(setup.p0, setup.names, self.step)

    def run(self, setup: Setup) -> Run:
        steps = self.steps(setup)
        signs = (1.0,) if self.kind == "forward" else (1.0, -1.0)
        per = [[compile_perturbed(setup.build, setup.p0, v, s * steps[v], setup.sys0)
                for s in signs] for v in setup.names]
        return _timed_runs(setup, [(systems, 0) for systems in per])

    def column(self, fn, base: Result, pert, step):
        if self.kind == "forward":
            return (np.asarray(fn(pert)) - np.asarray(fn(base))) / step
        plus, minus = pert
        return (np.asarray(fn(plus)) - np.asarray(fn(minus))) / (2.0 * step)

    def primal_solves(self, n_x: int) -> int:
        return n_x + 1 if self.kind == "forward" else 2 * n_x + 1


#: The method strings of :func:`morphlab.sensitivities` and the strategies they stand for.
ALIASES = {"auto": Auto(), "direct": Direct(), "direct-fd": Direct(
    partials="forward-difference"), "adjoint": Adjoint(), "complex-step": ComplexStep(),
    "forward-difference": FiniteDifference("forward"),
    "central-difference": FiniteDifference("central")}


def resolve(method) -> Strategy:
    """A strategy object for ``method`` (a :class:`Strategy`, or one of :data:`ALIASES`)."""
    if isinstance(method, Strategy):
        return method
    if isinstance(method, str) and method in ALIASES:
        return ALIASES[method]
    raise SensitivityError(f"unknown method {method!r}; choose one of {', '.join(ALIASES)} or "
                           "a Strategy object (Direct(...), Adjoint(...), Auto(...), "
                           "ComplexStep(), FiniteDifference(...), or a subclass of Strategy)")


__all__ = ["ALIASES", "Adjoint", "Auto", "ComplexStep", "Direct", "FiniteDifference",
           "HISTORIES", "Run", "Setup", "Strategy", "resolve"]
