"""The compiled kernels' runtime: where Numba caches them, and what a user is told while they
compile. (The kernels themselves are in :mod:`morphlab.kernels`; this stage ranks beside them:
it imports nothing of the library but the kernels.)"""

from .cache import announce_compilation, kernel_cache_dir, kernels_cached

__all__ = ["announce_compilation", "kernel_cache_dir", "kernels_cached"]
