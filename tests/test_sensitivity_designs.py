"""The changes of perturbed designs (morphlab.sensitivity.designs.changes).

A design that differs from the nominal in beams' sections alone takes the section path: the
changed frames' rows are computed, no system is compiled or copied. Its change must equal the
change read off the perturbed design compiled from scratch, position for position and bit for
bit (the element data of a frame are the same arithmetic on the same numbers either way), for
a complex step and for a finite-difference step; the perturbed system it builds on demand must
equal that compile too.
"""

import numpy as np
import pytest

import morphlab as ml
from morphlab.compile.compile import section_delta
from morphlab.compile.system import time_table
from morphlab.results.gradients import system_data
from morphlab.sensitivity.designs import (
    CS_STEP,
    change_of,
    changes,
    perturbed_model,
    section_change,
)


def _problem():
    from morphlab.bench.variables import problem

    return problem(20, n_elements=60)  # 18 thicknesses of a few elements each, 2 joint points


@pytest.mark.parametrize("step", [None, 1e-6], ids=["complex-step", "difference"])
def test_a_section_change_equals_the_change_of_a_compile_from_scratch(step):
    build, p0, _ = _problem()
    sys0 = ml.compile_model(build(p0))
    times = np.array([0.0, 1e-3, 2e-3])
    T0 = time_table(sys0, times)
    names = list(p0)
    steps = None if step is None else {v: step * abs(p0[v]) for v in names}
    fast = changes(build, p0, names, sys0, times, steps)
    sections = 0
    for v, ch in zip(names, fast):
        delta = 1j * CS_STEP if steps is None else steps[v]
        dtype = np.complex128 if steps is None else np.float64
        model = perturbed_model(build, p0, v, delta)
        scratch = ml.compile_model(model, dtype=dtype)  # no ``like``: every item compiled
        ref = change_of(sys0, scratch, delta, T0, times)
        is_section = section_delta(model, sys0, np.dtype(dtype)) is not None
        sections += is_section
        assert is_section == v.startswith("t"), v  # the joint points are not sections
        np.testing.assert_array_equal(ch.positions, ref.positions, err_msg=v)
        np.testing.assert_array_equal(ch.derivative, ref.derivative, err_msg=v)
        np.testing.assert_array_equal(ch.values, ref.values, err_msg=v)
        np.testing.assert_array_equal(ch.dq0, ref.dq0, err_msg=v)
        np.testing.assert_array_equal(ch.dv0, ref.dv0, err_msg=v)
        assert (ch.time is None) == (ref.time is None), v
        # the system built on demand is the compile from scratch
        np.testing.assert_array_equal(ch.system.design, scratch.design, err_msg=v)
        np.testing.assert_array_equal(ch.system.q0, scratch.q0, err_msg=v)
        assert ch.system.dtype == scratch.dtype
        if steps is None:  # the data a response reads, differentiated without the system
            for key in ("elements.B", "elements.K", "body:skin:X", "q0"):
                np.testing.assert_array_equal(
                    ch.data_derivative(sys0, key),
                    np.imag(system_data(scratch, key)) / CS_STEP, err_msg=f"{v} {key}")
    assert sections == sum(v.startswith("t") for v in names) > 0


def test_a_section_change_holds_the_changed_frames_rows_only():
    """The thickness of a few elements changes the rows of the frames holding them: their
    invariants and element data, nothing of the other frames (whose rows the section path
    never computes)."""
    build, p0, _ = _problem()
    sys0 = ml.compile_model(build(p0))
    v = "t3"
    model = perturbed_model(build, p0, v, 1j * CS_STEP)
    delta = section_delta(model, sys0, np.dtype(np.complex128))
    ch = section_change(sys0, delta, 1j * CS_STEP)
    from morphlab.compile.design import owners

    touched = {(kind, field): set(rows.tolist()) for kind, field, rows in
               owners(sys0.arrays, ch.positions)}
    assert {k for k, _ in touched} == {"bodies", "flex", "elements"}
    n_el = sys0.count("elements")
    elements = touched[("elements", "K")]
    # a few elements of 60, in the frames holding this variable's elements
    assert 0 < len(elements) < n_el // 4
    assert delta.positions.size < sys0.design.size // 4
