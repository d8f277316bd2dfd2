"""Stage 6, studies built on :func:`morphlab.simulate` and :func:`morphlab.sensitivities`:
parameter studies on any executor (:mod:`.sweep`, :mod:`.tasks`, :mod:`.samplers`), timing
comparisons, design optimization (:mod:`.optimize`, :mod:`.problem`) and first-order
uncertainty propagation (:mod:`.uncertainty`)."""

from ..errors import StudyError
from .optimize import FREE_METHODS, GRADIENT_METHODS, optimize
from .optimize_result import History, OptimizationResult
from .problem import Constraint, Problem
from .samplers import (
    correlated_normal,
    full_factorial,
    halton,
    latin_hypercube,
    monte_carlo,
    normal,
    sobol,
    uniform,
)
from .sweep import sweep
from .sweep_result import SweepResult
from .tasks import SimulationTask
from .timing import interleaved_times, median_time
from .uncertainty import (
    LinearizationCheck,
    UncertaintyResult,
    axis_perturbations,
    exceedance,
    fosm,
    linearization_check,
)

__all__ = [
    "FREE_METHODS", "GRADIENT_METHODS", "Constraint", "History", "LinearizationCheck",
    "OptimizationResult", "Problem", "SimulationTask", "StudyError", "SweepResult",
    "UncertaintyResult", "axis_perturbations", "correlated_normal", "exceedance", "fosm",
    "full_factorial", "halton", "interleaved_times", "latin_hypercube", "linearization_check",
    "median_time", "monte_carlo", "normal", "optimize", "sobol", "sweep", "uniform",
]
