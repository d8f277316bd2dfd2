"""morphlab: planar flexible multibody dynamics (FFRF) with generalized-alpha time integration
and direct-differentiation design sensitivities.

Reproduces Gufler, Wehrle, Achleitner, Vidoni: "Flexible multibody dynamics and sensitivity
analysis in the design of a morphing leading edge for high-performance sailplanes".
"""

from . import io
from ._version import __version__
from .compile import System, compile_model
from .errors import (
    ConvergenceError,
    FormatError,
    Interrupted,
    ModelError,
    MorphlabError,
    NonFiniteError,
    ProfileError,
    ResourceError,
    ResponseError,
    SensitivityError,
    SingularMatrixError,
    SolverError,
    StudyError,
)
from .model import Beam, Model, RigidBody, units
from .model.profiles import (
    Constant,
    Custom,
    Linear,
    Polynomial,
    Profile,
    Ramp,
    Sine,
    SmoothStep,
)
from .results import responses
from .results.result import Result
from .sensitivity import (
    Adjoint,
    Auto,
    ComplexStep,
    Direct,
    FiniteDifference,
    SensitivityResult,
    Strategy,
    sensitivities,
)
from .solve.scheme import GeneralizedAlpha
from .solve.settings import Settings, State, StaticSettings
from .solve.statics import static
from .solve.timeloop import simulate
from .warmup import warmup

# The application (the paper's model) and the figures are loaded on first use: ``import
# morphlab`` loads neither the morphing study nor matplotlib.
_LAZY = {"morphing": "morphlab.morphing", "airfoil": "morphlab.morphing.airfoil",
         "plots": "morphlab.plots", "studies": "morphlab.studies"}


def __getattr__(name: str):
    if name in _LAZY:
        import importlib

        module = importlib.import_module(_LAZY[name])
        globals()[name] = module
        return module
    raise AttributeError(f"module 'morphlab' has no attribute {name!r}")

__all__ = [
    "Adjoint", "Auto", "Beam", "ComplexStep", "Constant", "ConvergenceError", "Custom", "Direct",
    "FiniteDifference", "FormatError", "GeneralizedAlpha", "Interrupted", "Linear", "Model",
    "ModelError", "MorphlabError", "NonFiniteError", "Polynomial", "Profile", "ProfileError",
    "Ramp", "ResourceError", "ResponseError", "Result", "RigidBody", "SensitivityError",
    "SensitivityResult", "Settings", "Sine", "SingularMatrixError", "SmoothStep", "SolverError",
    "State", "StaticSettings", "Strategy", "StudyError", "System", "airfoil", "compile_model",
    "io", "morphing", "plots", "responses", "sensitivities", "simulate", "static", "studies",
    "units", "warmup", "__version__",
]
