"""The JIT runtime of the kernels: where Numba caches them (:mod:`.cache`) and what the user
sees while they compile (:mod:`.progress`)."""

from .cache import kernel_cache_dir
from .progress import ESTIMATES, CompileProgress

__all__ = ["CompileProgress", "ESTIMATES", "kernel_cache_dir"]
