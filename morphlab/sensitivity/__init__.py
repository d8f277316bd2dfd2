"""Stage 5, sensitivity: ``build(p) -> gradients`` by strategies that share the primal time loop,
its factorizations and its residual kernels."""

from .api import SensitivityResult, sensitivities
from .strategies import Adjoint, Auto, ComplexStep, Direct, FiniteDifference, Strategy

__all__ = ["Adjoint", "Auto", "ComplexStep", "Direct", "FiniteDifference", "SensitivityResult",
           "Strategy", "sensitivities"]
