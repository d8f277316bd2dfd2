"""The adjoint's units of evaluation (morphlab.sensitivity.units.share_units): variables on
the linear path whose items, coordinates and residual rows are disjoint are evaluated together,
and each takes its own rows of the common column.

The property the grouping rests on is asserted directly: at a random state, the explicit column
of a group equals the sum of its members' columns, and each member's rows of it equal that
member's own column. The gradients themselves are compared against the direct method in
``test_sensitivity_adjoint.py`` (thickness per element of the skin: grouped).
"""

import numpy as np
import pytest

import morphlab as ml
from morphlab.compile.system import time_table
from morphlab.kernels.pseudo import Column, explicit_column
from morphlab.kernels.types import Level, Weights
from morphlab.sensitivity.adjoint import _touched
from morphlab.sensitivity.designs import CS_STEP, changes, pseudo_data
from morphlab.sensitivity.units import share_units
from morphlab.solve.record import template
from morphlab.solve.settings import Settings
from morphlab.solve.stepper import Stepper
from tests.models import E_AL, RHO_AL, straight_nodes


def _units(build, p0):
    """The nominal system, the pseudo-load data, the rows and the units of ``build``'s
    variables (the rows probed in the sweep's kernel, as an adjoint run probes them, on the
    stepper of a run of one step)."""
    sys0 = ml.compile_model(build(p0))
    times = np.array([0.0, 1e-3])
    T0 = time_table(sys0, times)
    ps = pseudo_data(sys0, changes(build, p0, list(p0), sys0, times),
                     np.full(len(p0), 1j * CS_STEP), T0)
    stp = Stepper.dynamic(sys0, Settings(t_end=1e-3, dt=1e-3), T0, scale=1.0, rows=3)
    RO, RI = _touched(sys0, ps, None, stp, template(sys0, stp.newton.factorization, True),
                      None)
    return sys0, ps, RO, RI, share_units(ps, RO, RI)


def _column(sys0, ps, i, x):
    """Variable ``i``'s explicit column at the state ``x`` (all weights 1, time index 0)."""
    c = Column.zeros(sys0.n_dof, sys0.n_con, sys0.count("flex"), ps)
    explicit_column(ps, sys0.arrays, time_table(sys0, np.zeros(1)), i, x,
                    Weights(*([1.0] * 8)), 0, c)
    return c.R.copy()


def test_thicknesses_of_separate_frames_are_one_evaluation_with_each_its_own_rows():
    """The skin of the gradient bench, 8 thickness variables of 5 elements (one frame each)
    and the 4 bell-crank points: the thicknesses form one unit, the points (shape variables,
    perturbed path) one each; the group's column is the sum of its members' and each member's
    rows of it are its own column (1e-13 of the column's size: the same products summed in
    another order)."""
    from morphlab.bench.variables import problem

    build, p0, _ = problem(12, n_elements=40)
    sys0, ps, RO, RI, (gs, UO, UI, UV) = _units(build, p0)
    names = list(p0)
    members = [sorted(names[i] for i in UI[UO[u]:UO[u + 1]]) for u in range(UV.size)]
    thicknesses = sorted(k for k in names if k.startswith("t"))
    assert sorted(members, key=lambda m: (len(m), m)) == [["x_B"], ["x_D"], ["y_B"], ["y_D"],
                                                          thicknesses]
    group = int(np.flatnonzero(np.diff(UO) > 1)[0])
    rng = np.random.default_rng(1)
    x = Level(*(rng.standard_normal(n) for n in (sys0.n_dof,) * 3 + (sys0.n_con,)))
    total = _column(sys0, gs, int(UV[group]), x)
    own = [_column(sys0, ps, int(i), x) for i in UI[UO[group]:UO[group + 1]]]
    scale = np.max(np.abs(total))
    assert scale > 0
    assert np.max(np.abs(total - sum(own))) <= 1e-13 * scale
    for i, col in zip(UI[UO[group]:UO[group + 1]], own):
        rows = RI[RO[i]:RO[i + 1]]
        assert np.max(np.abs(total[rows] - col[rows])) <= 1e-13 * scale
        assert not np.any(np.delete(col, rows))  # nothing outside its rows
        assert np.array_equal(np.flatnonzero(col), rows)  # and nothing more probed


@pytest.mark.parametrize("frames", [1, 2])
def test_thicknesses_that_share_a_frame_are_not_grouped(frames):
    """A cantilever of 6 elements with a thickness each: on one frame every variable changes
    the frame's invariants and its reference rows, so none is grouped; on two frames (3
    elements each) the variables of different frames pair up, never two of one frame."""

    def build(p):
        t = np.array([p[f"t{k}"] for k in range(6)])
        m = ml.Model(gravity=(0.0, -9.81e3))
        beam = m.add_beam(straight_nodes(6, length=60.0), E=E_AL, rho=RHO_AL, thickness=t,
                          width=10.0, frames=frames, name="beam")
        m.add_fix(beam, at=(0.0, 0.0), name="clamp")
        return m

    p0 = {f"t{k}": 1.0 + 0.1 * k for k in range(6)}
    _, _, _, _, (_, UO, UI, UV) = _units(build, p0)
    units = [sorted(UI[UO[u]:UO[u + 1]].tolist()) for u in range(UV.size)]
    assert sorted(i for u in units for i in u) == list(range(6))
    if frames == 1:
        assert all(len(u) == 1 for u in units)
    else:
        assert max(len(u) for u in units) == 2
        assert all(len({i // 3 for i in u}) == len(u) for u in units)  # one per frame
