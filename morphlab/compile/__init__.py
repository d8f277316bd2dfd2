"""Stage 2, compile: ``Model -> System``, one table of arrays per kind of item (float64 or
complex128) with a fixed sparsity pattern of the step matrix, and the checks that need the whole
model."""

from .checks import check_initial, check_rank, constraint_rank
from .compile import compile_model, items_of
from .system import BodyInfo, System, time_table

__all__ = ["BodyInfo", "System", "check_initial", "check_rank", "compile_model",
           "constraint_rank", "items_of", "time_table"]
