"""The time loop in compiled chunks (``morphlab.kernels.steps``, Newton by
``morphlab.kernels.newton``) against the step-by-step loop of the solver, which chains the same
kernels from Python (``compiled_newton=False``): on both kinds of factor (dense LU of small
matrices, sparse refactorization with a kept row order) the runs must be the same bit for bit,
with as many iterations and factorizations, and a failing step must stop both where it fails,
with the same error."""

import numpy as np
import pytest
from models import flexible_mechanism

import morphlab as ml
from morphlab.solve import superlu


def _runs(monkeypatch, system, **kw):
    """The same run in compiled chunks and with every iteration in Python; the number of row
    orders SuperLU chose in each."""
    orders = []
    choose = superlu.NaturalOrderLU.__call__

    def counted(self, data):
        orders[-1] += 1
        return choose(self, data)

    monkeypatch.setattr(superlu.NaturalOrderLU, "__call__", counted)
    out = []
    for compiled in (True, False):
        orders.append(0)
        out.append(ml.simulate(system, compiled_newton=compiled, **kw))
    return out, orders


def test_compiled_loop_gives_the_run_of_the_python_loop(monkeypatch):
    """The morphing leading edge with a 60-element skin (213 unknowns: sparse): in compiled
    chunks and with every iteration from Python the run is the same bit for bit, with as many
    iterations and factorizations. SuperLU renews the row order during this run (a pivot
    fails the threshold inside a compiled chunk, which hands the step back to Python), the
    same in both. The mechanism is the study's former design (E = node 22, x_A = 102 mm), kept
    here because its run exercises those renewals; the current design's run keeps its first
    order."""
    from morphlab import morphing as mo

    former = {"x_A": 102.0, "y_A": -0.25, "x_B": 99.29, "y_B": -8.25, "x_D": 108.85,
              "y_D": -5.88}
    system = ml.compile_model(mo._assemble(former, 60, drive=False, nodes=(4, 22),
                                           skin="accurate", sense=1))
    (fast, slow), orders = _runs(monkeypatch, system, settings=mo.SETTINGS)
    assert orders[0] == orders[1] >= 2  # the order of the second matrix, then renewals
    for name in ("q", "v", "a", "lam", "newton_iterations", "constraint_violation"):
        np.testing.assert_array_equal(getattr(fast, name), getattr(slow, name))
    assert fast.n_factorizations == slow.n_factorizations
    assert [len(s) for s in fast.newton_history] == [len(s) for s in slow.newton_history]


def test_compiled_dense_loop_gives_the_run_of_the_python_loop(monkeypatch):
    """The same on dense factors (the flexible four-bar, 35 unknowns, factored dense)."""
    system = ml.compile_model(flexible_mechanism())
    (fast, slow), _ = _runs(monkeypatch, system, t_end=0.02, dt=1e-3, dense_max=1000)
    for name in ("q", "lam", "newton_iterations"):
        np.testing.assert_array_equal(getattr(fast, name), getattr(slow, name))
    assert fast.n_factorizations == slow.n_factorizations


@pytest.mark.parametrize("dense_max", [1000, 0])
def test_a_failing_step_stops_both_loops_at_that_step(dense_max):
    """A torque that jumps to a huge value at t = 5 ms makes Newton fail there: both loops
    raise the same error at the same step, with the steps before it in ``error.result``."""
    model = flexible_mechanism()
    model.add_torque("crank", 1.0, profile=ml.Custom(lambda t: 0.0 if np.real(t) < 4.5e-3
                                                     else 1e12, lambda t: 0.0, lambda t: 0.0),
                     name="jump")
    system = ml.compile_model(model)
    errors = []
    for compiled in (True, False):
        with pytest.raises(ml.SolverError) as err:
            ml.simulate(system, t_end=0.02, dt=1e-3, dense_max=dense_max, max_iter=4,
                        compiled_newton=compiled)
        errors.append(err.value)
    fast, slow = errors
    assert type(fast) is type(slow) and fast.step == slow.step == 5
    assert fast.result.n_t == slow.result.n_t == 5
    np.testing.assert_array_equal(fast.result.q, slow.result.q)
