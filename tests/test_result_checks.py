"""A run never reads "ok" when its own histories show it is doubtful (morphlab.results.checks):
constraint drift, unbounded growth and implausible units are found, named and reported as a
warning, an error on request, or not at all."""

import warnings

import numpy as np
import pytest
from models import flexible_mechanism

import morphlab as ml


def _spinning_blade(omega, tau=0.05):
    """A 100 mm aluminium strip (1 mm) driven about one end, spun up to ``omega`` [rad/s]; its
    first bending frequency is 517 rad/s: above it a single linear floating frame diverges
    (no centrifugal stiffening)."""
    m = ml.Model()
    nodes = np.stack([np.linspace(0, 100.0, 5), np.zeros(5)], axis=1)
    b = m.add_beam(nodes, E=70000.0, rho=2.7e-9, thickness=1.0, width=10.0, frames=1,
                   reference="first", name="blade")
    m.add_revolute(m.ground, b, at=(0, 0), name="hub")
    m.add_drive(b, angle=ml.Custom(lambda t: omega * (t - tau * (1 - np.exp(-t / tau))),
                                   lambda t: omega * (1 - np.exp(-t / tau)),
                                   lambda t: omega * np.exp(-t / tau) / tau), name="spin")
    return m


def test_a_sound_run_is_ok_and_silent():
    with warnings.catch_warnings():
        warnings.simplefilter("error", ml.errors.MorphlabWarning)
        res = ml.simulate(flexible_mechanism(), t_end=0.02, dt=1e-3)
    assert res.status == "ok" and res.findings == []


def test_constraint_drift_is_named_and_warned_raised_or_silenced():
    """The four-bar without stabilization at a coarse step drifts (measured ~1 % of its size
    over 0.5 s); the joint and the time are named."""
    kw = dict(t_end=0.5, dt=5e-3, stabilization=0.0)
    with pytest.warns(ml.errors.AccuracyWarning, match=r"joint '\w' is violated by"):
        res = ml.simulate(flexible_mechanism(), **kw)
    assert res.status == "warning" and res.findings[0].check == "constraint drift"
    assert res.findings[0].value > res.findings[0].limit
    with pytest.raises(ml.errors.AccuracyError) as err:
        ml.simulate(flexible_mechanism(), checks="raise", **kw)
    assert err.value.result.status == "warning"
    quiet = ml.simulate(flexible_mechanism(), checks="off", **kw)
    assert quiet.status == "ok"


def test_a_diverging_run_says_so_when_it_fails():
    """Spun at about twice its first bending frequency, the single-frame blade's deformation
    grows until Newton fails: the error says what the run showed before."""
    with pytest.raises(ml.SolverError, match="before it:.*grows from") as err:
        ml.simulate(_spinning_blade(1100.0), t_end=0.25, dt=5e-4)
    assert "unbounded growth" in [f.check for f in err.value.result.findings]


def test_wrong_units_are_implausible():
    """E in Pa (70e9) and density in kg/m^3 (2700) while lengths are in mm and gravity in
    mm/s^2: mass and weight are 1e12 times too large and the stiffness 1e3 times, so the clamped
    rod's period is ~200 s and it falls nearly freely (0.5 g t^2 = 1.2 m in 0.5 s, four times
    its length) while clamped: its strain exceeds 1 (stress above E). Both checks
    fire and name the beam; the correct units are quiet (test_a_sound_run_is_ok_and_silent)."""
    nodes = np.stack([np.linspace(0.0, 300.0, 7), np.zeros(7)], axis=1)
    m = ml.Model(gravity=(0.0, -9.81e3))
    # one frame, clamped: the deformation check measures the deflection against it (with a
    # frame per element the frames fall with the rod and the kinematic check fires instead)
    rod = m.add_beam(nodes, E=70e9, rho=2700.0, thickness=2.0, width=10.0, frames=1,
                     reference="first", name="rod")
    m.add_fix(rod, at=(0.0, 0.0), name="clamp")
    with pytest.warns(ml.errors.AccuracyWarning, match="rod.*check the units"):
        res = ml.simulate(m, t_end=0.5, dt=1e-2)
    assert {"implausible deformation", "implausible stress"} <= {f.check for f in res.findings}
    assert res.status == "warning"
