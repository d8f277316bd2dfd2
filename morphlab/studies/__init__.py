"""Stage 6, studies built on :func:`morphlab.simulate` and :func:`morphlab.sensitivities`:
parameter studies on any executor (:mod:`.sweep`, :mod:`.tasks`, :mod:`.samplers`), timing
comparisons, design optimization (:mod:`.optimize`, :mod:`.problem`), uncertainty
propagation (:mod:`.uncertainty`, :mod:`.propagate`: FOSM, Monte Carlo, FORM, importance
sampling over :mod:`.distributions`) and Sobol' indices (:mod:`.indices`)."""

from ..errors import StudyError
from .checkpoint import CheckpointWarning
from .distributions import JointDistribution
from .form import SearchOptions
from .function_task import FunctionTask
from .importance import importance_sampling
from .indices import SobolIndices, sobol_indices
from .multistart import MultiStartResult, multistart
from .optimize import FREE_METHODS, GRADIENT_METHODS, optimize
from .optimize_result import History, OptimizationResult
from .problem import Constraint, Problem
from .propagate import propagate
from .reliability import LimitState, ReliabilityResult, form, series_probability
from .samplers import (
    correlated_normal,
    full_factorial,
    halton,
    iman_conover,
    latin_hypercube,
    monte_carlo,
    normal,
    sample,
    sobol,
    uniform,
)
from .statistics import SampleResult, binomial_interval, mean_std
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
    "FREE_METHODS", "GRADIENT_METHODS", "CheckpointWarning", "Constraint", "FunctionTask",
    "History", "JointDistribution", "LimitState", "LinearizationCheck", "MultiStartResult",
    "OptimizationResult", "Problem", "ReliabilityResult", "SampleResult", "SearchOptions",
    "SimulationTask", "SobolIndices", "StudyError", "SweepAborted", "SweepResult", "SweepRow",
    "UncertaintyResult", "axis_perturbations", "binomial_interval", "correlated_normal",
    "exceedance", "form", "fosm", "full_factorial", "halton", "iman_conover",
    "importance_sampling", "interleaved_times", "latin_hypercube", "linearization_check",
    "mean_std", "median_time", "monte_carlo", "multistart", "normal", "optimize", "propagate",
    "sample", "series_probability", "sobol", "sobol_indices", "sweep", "sweep_iter", "uniform",
]
