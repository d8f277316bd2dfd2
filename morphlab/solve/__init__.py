"""Stage 4, solve: ``System -> Result``. The generalized-alpha scheme as data, one step (Newton
on the sparse saddle-point system), factorizations of the step matrix, the time loop and
statics."""

from .scheme import GeneralizedAlpha
from .settings import Settings, State, StaticSettings
from .statics import static
from .stepper import Stepper
from .timeloop import StepHook, StepInfo, integrate, simulate

__all__ = ["GeneralizedAlpha", "Settings", "State", "StaticSettings", "StepHook", "StepInfo",
           "Stepper", "integrate", "simulate", "static"]
