"""The parts of the model a design variable changes (``perturb.variable_parts``), read from the
incremental compile's record — only the rows compiled afresh compared — equal those of the
comparison of every array, for every kind of variable (a thickness per element group, a node
moved, a link point, Young's modulus, the damping, a torque) by complex step and by a real
step, on a multi-frame coupler and on the morphing model. The time tables are deduplicated:
a variable that changes no profile or constant shares the nominal's table."""

import numpy as np
import pytest

import morphlab as ml
from morphlab.compile import incremental, kernel_arrays
from morphlab.sensitivity import perturb
from tests.test_incremental_compile import P_COUPLER, coupler_model

mo = ml.morphing
TIMES = np.linspace(0.0, 0.1, 7)


def _parts_both_ways(build, p0):
    """Per variable and step: (parts from the record, parts from every array, fresh rows)."""
    sys0 = ml.compile_model(build(p0), record=True)
    out = {}
    for name in p0:
        for delta in (1e-30j, 1e-6 * (abs(p0[name]) or 1.0)):
            sys_p = perturb.compile_perturbed(build, p0, name, delta, sys0)
            dt = sys_p.dtype
            tab_of, tables = perturb.distinct_tables(sys0, [sys_p], TIMES, dt)
            tabi = tables[tab_of[0]] if tab_of[0] else None
            S0, Si = kernel_arrays(sys0, dt), kernel_arrays(sys_p, dt)
            fresh = incremental.fresh_rows(sys_p)
            out[name, type(delta)] = (
                perturb.variable_parts(sys0, S0, Si, tables[0], tabi, fresh),
                perturb.variable_parts(sys0, S0, Si, tables[0], tabi), fresh, sys0, tab_of)
    return out


def _assert_equal_parts(cases):
    for key, (rec, full, _, _, _) in cases.items():
        for kind, a, b in zip(("bodies", "elements", "flex", "rows", "loads", "torques"),
                              rec, full):
            assert np.array_equal(a, b), (key, kind)


@pytest.mark.parametrize("frames", ["element", 3])
def test_coupler_parts_from_the_record(frames):
    cases = _parts_both_ways(lambda p: coupler_model(p, frames), P_COUPLER)
    _assert_equal_parts(cases)
    # the record is used (a thickness of one group compares its frames' rows, not the beam's)
    # and the parts are not empty: a thickness changes elements, the torque its torque row
    rec, _, fresh, sys0, tab_of = cases["t1", complex]
    assert fresh is not None and fresh["elem_M"].size == 4 < sys0.elem_M.shape[0]
    assert np.array_equal(rec[1], [4, 5, 6, 7])
    assert tab_of[0] == 0
    rec, _, _, _, tab_of = cases["Mt", complex]
    assert rec[5].tolist() == [0] and rec[1].size == 0 and tab_of[0] == 1


def test_morphing_parts_from_the_record():
    cases = _parts_both_ways(lambda p: mo.build(p, skin="accurate"),
                             {**mo.DEFAULTS, **mo.GEOMETRY})
    _assert_equal_parts(cases)
    assert any(c[2] is not None for c in cases.values())


@pytest.mark.parametrize("delta", [1e-30j, 1e-6])
def test_design_rows_write_each_design_in_and_the_nominal_back(delta):
    """The pseudo-load kernels evaluate design ``i`` on a working copy of the nominal data
    with the rows design ``i`` changes written in (``set_design``) and written back after.
    For every variable of the coupler (thickness groups, a node, a link point, the modulus,
    the damping, the torque), by complex step and by a real step: after writing design ``i``
    in, every design field equals design ``i``'s own compiled arrays bit for bit; after writing
    it back, the nominal's; and the rows kept are far fewer than n_x copies of the data."""
    from morphlab.kernels.system import DESIGN_FIELDS, set_design

    build, p0 = (lambda p: coupler_model(p, "element")), P_COUPLER
    sys0 = ml.compile_model(build(p0), record=True)
    names = list(p0)
    psys = [perturb.compile_perturbed(build, p0, v, delta * (1 if isinstance(delta, complex)
                                                                else abs(p0[v]) or 1.0), sys0)
            for v in names]
    pert = np.array([delta] * len(names))
    data = perturb.pseudo_load_data(sys0, psys, pert, TIMES)
    W, S, D = data.W, data.S_nom, data.D
    for i, s in enumerate(psys):
        Si = kernel_arrays(s, data.dtype)
        set_design(W, S, D, i, True)
        for f in DESIGN_FIELDS:
            assert np.array_equal(getattr(W, f), getattr(Si, f)), (names[i], f)
        set_design(W, S, D, i, False)
        for f in DESIGN_FIELDS:
            assert np.array_equal(getattr(W, f), getattr(S, f)), (names[i], f)
    kept = sum(v.nbytes for _, _, v in D)
    full = len(names) * sum(getattr(S, f).nbytes for f in DESIGN_FIELDS)
    assert kept < 0.2 * full
