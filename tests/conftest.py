import os
import sys

import matplotlib

matplotlib.use("Agg")
sys.path.insert(0, os.path.dirname(__file__))


import pytest  # noqa: E402


@pytest.fixture(scope="session", autouse=True)
def _compiled_kernels():
    """Compile (or load from the Numba cache) every kernel once, before the first test."""
    import morphlab

    morphlab.warmup()
