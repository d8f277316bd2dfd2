"""Stage 5, sensitivity: ``build(p) -> gradients`` by strategies that share the primal time loop,
its factorizations and its residual kernels."""

from .api import SensitivityResult, sensitivities
from .strategies import ComplexStep, Direct, FiniteDifference

__all__ = ["ComplexStep", "Direct", "FiniteDifference", "SensitivityResult", "sensitivities"]
