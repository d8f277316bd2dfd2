"""morphlab: planar flexible multibody dynamics (FFRF) with generalized-alpha time integration
and direct-differentiation design sensitivities.

Reproduces Gufler, Wehrle, Achleitner, Vidoni: "Flexible multibody dynamics and sensitivity
analysis in the design of a morphing leading edge for high-performance sailplanes".
"""

from . import airfoil, io, morphing, responses
from .compile import System, compile_model
from .errors import (
    ConvergenceError,
    FormatError,
    ModelError,
    MorphlabError,
    NonFiniteError,
    SensitivityError,
    SingularMatrixError,
    SolverError,
)
from .integrator import GeneralizedAlpha
from .model import Beam, Model, RigidBody
from .profiles import Constant, Custom, Linear, Profile, Ramp, Sine, SmoothStep
from .results import Result
from .sensitivity import SensitivityResult, sensitivities
from .solver import Settings, State
from .statics import static
from .timeloop import simulate
from .warmup import warmup

__version__ = "0.1.0"

__all__ = [
    "Beam", "Constant", "ConvergenceError", "Custom", "FormatError", "GeneralizedAlpha",
    "Linear", "Model",
    "ModelError", "MorphlabError", "NonFiniteError", "Profile", "Ramp", "Result", "RigidBody",
    "SensitivityError", "SensitivityResult", "Settings", "Sine", "SingularMatrixError",
    "SmoothStep", "SolverError", "State", "System", "airfoil", "compile_model", "io",
    "morphing", "responses", "sensitivities", "simulate", "static", "warmup", "__version__",
]
