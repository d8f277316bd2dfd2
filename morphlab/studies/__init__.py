"""Stage 6, studies built on :func:`morphlab.simulate` and :func:`morphlab.sensitivities`:
timing comparisons, design optimization (:mod:`.optimize`, :mod:`.problem`) and first-order
uncertainty propagation (:mod:`.uncertainty`)."""

from .optimize import FREE_METHODS, GRADIENT_METHODS, optimize
from .optimize_result import History, OptimizationResult
from .problem import Constraint, Problem
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
    "OptimizationResult", "Problem", "UncertaintyResult", "axis_perturbations", "exceedance",
    "fosm", "interleaved_times", "linearization_check", "median_time", "optimize",
]
