import os
import signal
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


@pytest.fixture(autouse=True)
def _python_ctrl_c():
    """Every test runs with Python's own Ctrl-C handler (KeyboardInterrupt), however the runner
    was started: a shell's background job ignores SIGINT, and so do the pytest-xdist workers
    and child processes it starts (an ignored signal stays ignored across exec, a handled one
    is reset to the default). The tests of interrupts need the real behaviour."""
    before = signal.getsignal(signal.SIGINT)
    signal.signal(signal.SIGINT, signal.default_int_handler)
    yield
    signal.signal(signal.SIGINT, before if before is not None else signal.SIG_DFL)


@pytest.hookimpl(trylast=True)  # after -m and -k have deselected
def pytest_collection_modifyitems(config, items):
    """A notebook's reduced-size run (``test_notebook_runs``, ``MORPHLAB_QUICK=1``) is the
    fast subset's stand-in for its default-size run (``test_notebook_full_size``, slow): the
    same cells and assertions at a smaller size. Where a session runs both, the default-size
    run alone is kept (the reduced one would only add minutes)."""
    full = {item.callspec.id for item in items
            if item.originalname == "test_notebook_full_size"}
    if not full:
        return
    dropped = [item for item in items if item.originalname == "test_notebook_runs"
               and item.callspec.id in full]
    if dropped:
        config.hook.pytest_deselected(items=dropped)
        items[:] = [item for item in items if item not in dropped]
