"""Stage 6, studies built on :func:`morphlab.simulate` and :func:`morphlab.sensitivities`:
parameter studies on any executor (:mod:`.sweep`, :mod:`.tasks`, :mod:`.samplers`), timing
comparisons, design optimization (:mod:`.optimize`, :mod:`.problem`) and first-order
uncertainty propagation (:mod:`.uncertainty`)."""

from ..errors import StudyError
from .checkpoint import CheckpointWarning
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
from .sweep import sweep, sweep_iter
from .sweep_result import SweepAborted, SweepResult, SweepRow
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
    "FREE_METHODS", "GRADIENT_METHODS", "CheckpointWarning", "Constraint", "History",
    "LinearizationCheck", "OptimizationResult", "Problem", "SimulationTask", "StudyError",
    "SweepAborted", "SweepResult", "SweepRow",
    "UncertaintyResult", "axis_perturbations", "correlated_normal", "exceedance", "fosm",
    "full_factorial", "halton", "interleaved_times", "latin_hypercube", "linearization_check",
    "median_time", "monte_carlo", "normal", "optimize", "sobol", "sweep", "sweep_iter",
    "uniform",
]
