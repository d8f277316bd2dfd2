"""Numba kernels of morphlab (installed as ``morphlab.kernels``).

Plain-array functions compiled with ``@njit(cache=True)``; each runs for float64 and complex128
inputs alike. Nothing here imports from ``morphlab``.
"""
