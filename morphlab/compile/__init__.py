"""Stage 2, compile: ``Model -> System``, flat arrays only (float64 or complex128) with a fixed
sparsity pattern of the step matrix, and the checks that need the whole model."""

from .checks import check_initial, check_rank, constraint_rank
from .compile import compile_model
from .system import BodyInfo, System, kernel_arrays, table_at, time_table

__all__ = [
    "BodyInfo", "System", "check_initial", "check_rank", "compile_model", "constraint_rank",
    "kernel_arrays", "table_at", "time_table",
]
