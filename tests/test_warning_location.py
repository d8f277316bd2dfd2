"""Warnings of a run point at the user's line: the file and line that called ``simulate``,
``static`` or ``sensitivities``, however deep in the library they arise
(:func:`morphlab.errors.warn`)."""

import inspect
import warnings

import numpy as np

import morphlab as ml

E, RHO, T, B, L = 70000.0, 2.7e-9, 2.0, 10.0, 100.0
EI = E * B * T**3 / 12.0


def bent(p):
    """A cantilever of one linear frame bent by a tip moment to a tip rotation ``p["phi"]``
    (0.1 rad: kinematic error 1.7e-3 of its length, above the default tolerance)."""
    m = ml.Model()
    nodes = np.stack([np.linspace(0.0, L, 5), np.zeros(5)], axis=1)
    b = m.add_beam(nodes, E=E, rho=RHO, thickness=T, width=B, frames=1, reference="first",
                   name="b")
    m.add_fix(b, at=(0.0, 0.0))
    m.add_torque(b, EI * p["phi"] / L, at=(L, 0.0), profile=ml.SmoothStep(0.0, 2e-3))
    return m


def _line() -> int:
    """The line number of the caller's call."""
    return inspect.currentframe().f_back.f_lineno


def _only_from_here(rec, line):
    """Every morphlab warning recorded came from this file, at ``line``."""
    ours = [w for w in rec if issubclass(w.category, ml.errors.MorphlabWarning)]
    assert ours, "no warning was emitted"
    for w in ours:
        assert (w.filename, w.lineno) == (__file__, line), (w.filename, w.lineno, w.message)


def test_simulate_static_and_sensitivities_warn_at_the_callers_line():
    """Before: simulate's warning pointed into the library (the strategy code for
    sensitivities) and static's one frame above the caller."""
    run = dict(t_end=4e-3, dt=2e-4)
    with warnings.catch_warnings(record=True) as rec:
        warnings.simplefilter("always")
        line = _line() + 1
        ml.simulate(bent({"phi": 0.1}), **run)
    _only_from_here(rec, line)
    with warnings.catch_warnings(record=True) as rec:
        warnings.simplefilter("always")
        line = _line() + 1
        ml.static(bent({"phi": 0.1}), t=1.0)
    _only_from_here(rec, line)
    resp = {"tip": ml.responses.point_displacement("b", (L, 0.0), 1)}
    for method in ("direct", "adjoint", "complex-step"):
        with warnings.catch_warnings(record=True) as rec:
            warnings.simplefilter("always")
            line = _line() + 1
            ml.sensitivities(bent, {"phi": 0.1}, resp, method=method, **run)
        _only_from_here(rec, line)


def test_a_units_warning_points_at_the_callers_line_too():
    """The units check runs inside the time loop; its warning names the user's call."""
    m = bent({"phi": 0.01})
    m.bodies[0].E = 70e9  # E in Pa with lengths in mm and rho in t/mm^3
    with warnings.catch_warnings(record=True) as rec:
        warnings.simplefilter("always")
        line = _line() + 1
        ml.simulate(m, t_end=4e-4, dt=2e-4, checks="off")
    units = [w for w in rec if issubclass(w.category, ml.errors.UnitsWarning)]
    assert units and all((w.filename, w.lineno) == (__file__, line) for w in units)
