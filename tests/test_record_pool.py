"""The adjoint's record made of the previous run's (``morphlab/solve/record.py``).

A run's record is handed back when its sweep is done and the next adjoint run of the same
sizes writes into it instead of fresh memory. That is safe only if every row a sweep reads was
written by its own run: the tests fill the released record with NaN (and the pivots with a
wrong row) before the next run and ask for the first run's gradients bit for bit, with the
whole record and with checkpoints (the segments' records made of each other's)."""

import numpy as np
import pytest
from test_sensitivity_adjoint import adjoint_responses
from test_sensitivity_direct import CASES, RUN

import morphlab as ml
from morphlab.sensitivity import Adjoint
from morphlab.solve import record


def _pooled() -> list:
    """The arrays of the pool's records (held, so that their ids stay theirs)."""
    return [x for R in record._POOL for x in R[:-1] if x is not None]


def _poison() -> list:
    """Fill the pool's records with values no run could use; their arrays."""
    for x in _pooled():
        x[...] = 0 if x.dtype.kind == "i" else np.nan
    return _pooled()


def _same(a: list, b: list) -> bool:
    return len(a) == len(b) and all(x is y for x, y in zip(a, b))


@pytest.mark.parametrize("memory", [2**30, 30_000], ids=["whole", "checkpoints"])
@pytest.mark.parametrize("name", CASES)
def test_a_reused_record_gives_the_same_gradients(name, memory):
    build, p0, resp = adjoint_responses(name)
    method = Adjoint(memory=memory)
    record.clear_pool()
    first = ml.sensitivities(build, p0, resp, method=method, **RUN)
    assert record.pooled_bytes() > 0
    old = _poison()
    again = ml.sensitivities(build, p0, resp, method=method, **RUN)
    for r in resp:
        for v in p0:
            assert again.gradients[r][v] == first.gradients[r][v], (r, v)
    if memory == 2**30:  # the whole run's record: the same arrays taken and handed back
        assert _same(_pooled(), old)


def test_only_the_adjoint_takes_the_pool_and_other_sizes_free_it():
    """A direct run (records of a chunk) leaves the pool alone; an adjoint run of another
    model, whose record the pool cannot make, frees it before allocating its own."""
    build, p0, resp = adjoint_responses("pendulum")
    record.clear_pool()
    ml.sensitivities(build, p0, resp, method="adjoint", **RUN)
    old = _pooled()
    ml.sensitivities(build, p0, resp, method="direct", **RUN)
    assert _same(_pooled(), old)
    build, p0, resp = adjoint_responses("mechanism")
    ml.sensitivities(build, p0, resp, method="adjoint", **RUN)
    assert not any(x is y for x in _pooled() for y in old)
    record.clear_pool()
    assert record.pooled_bytes() == 0
