"""Stage 3, results: the :class:`Result` of a run (stacked histories, accessors by name, energy,
statistics) and complex-safe responses built on it. The solver fills a Result, so this stage
comes before :mod:`morphlab.solve` in import order."""

from . import responses
from .result import Result, energy

__all__ = ["Result", "energy", "responses"]
