"""A sensitivity run's record made of the previous run's (``morphlab/solve/record.py``).

A run's record is handed back when its run is done and the next run of the same method and
sizes writes into it instead of fresh memory. That is safe only if every row a run reads was
written by its own run: the tests fill the released record with NaN (and the pivots with a
wrong row) before the next run and ask for the first run's gradients bit for bit: the adjoint
with the whole record and with checkpoints (the segments' records made of each other's), the
direct method with its record of a chunk of steps."""

import numpy as np
import pytest
from test_sensitivity_adjoint import adjoint_responses
from test_sensitivity_direct import CASES, RUN

import morphlab as ml
from morphlab.sensitivity import Adjoint
from morphlab.solve import record


def _pooled(method: str | None = None) -> list:
    """The arrays of the pool's records (of ``method``, or all; held, so that their ids stay
    theirs)."""
    return [x for m, held in record._POOL.items() if method in (None, m) for R in held
            for x in R[:-1] if x is not None]


def _poison() -> list:
    """Fill the pool's records with values no run could use; their arrays."""
    for x in _pooled():
        x[...] = 0 if x.dtype.kind == "i" else np.nan
    return _pooled()


def _same(a: list, b: list) -> bool:
    return len(a) == len(b) and all(x is y for x, y in zip(a, b))


@pytest.mark.parametrize("memory", [2**30, 30_000, None], ids=["whole", "checkpoints",
                                                                "direct"])
@pytest.mark.parametrize("name", CASES)
def test_a_reused_record_gives_the_same_gradients(name, memory):
    build, p0, resp = adjoint_responses(name)
    method = "direct" if memory is None else Adjoint(memory=memory)
    record.clear_pool()
    first = ml.sensitivities(build, p0, resp, method=method, **RUN)
    assert record.pooled_bytes() > 0
    old = _poison()
    again = ml.sensitivities(build, p0, resp, method=method, **RUN)
    for r in resp:
        for v in p0:
            assert again.gradients[r][v] == first.gradients[r][v], (r, v)
    if memory != 30_000:  # one record a run: the same arrays taken and handed back
        assert _same(_pooled(), old)


def test_each_method_takes_its_own_records_and_other_sizes_free_them():
    """A direct run leaves the adjoint's released records alone (and the adjoint the direct
    method's); an adjoint run of another model, whose record the pool cannot make, frees the
    adjoint's before allocating its own."""
    build, p0, resp = adjoint_responses("pendulum")
    record.clear_pool()
    ml.sensitivities(build, p0, resp, method="adjoint", **RUN)
    old = _pooled("adjoint")
    ml.sensitivities(build, p0, resp, method="direct", **RUN)
    assert _same(_pooled("adjoint"), old)
    old_direct = _pooled("direct")
    assert old_direct
    build, p0, resp = adjoint_responses("mechanism")
    ml.sensitivities(build, p0, resp, method="adjoint", **RUN)
    assert not any(x is y for x in _pooled("adjoint") for y in old)
    assert _same(_pooled("direct"), old_direct)
    record.clear_pool()
    assert record.pooled_bytes() == 0
