"""User code that fails inside a run (a time profile raising or returning NaN) stops the run at
that time with a typed error that names the load, torque or drive and the time, and keeps the
steps before it (the user's exception is the cause)."""

import numpy as np
import pytest
from models import flexible_mechanism

import morphlab as ml

RUN = dict(t_end=0.02, dt=1e-3)


def _with_torque_profile(f):
    m = flexible_mechanism()
    m.add_torque(m.body("crank"), 1.0, profile=ml.Custom(f, lambda t: 0.0, lambda t: 0.0),
                 name="motor")
    return m


def _breaks_after(t_fail, value=1.0):
    def f(t):
        if t > t_fail:
            raise ZeroDivisionError("the user's bug")
        return value
    return f


def test_a_raising_profile_names_the_torque_and_the_time_and_keeps_the_steps_before():
    with pytest.raises(ml.ProfileError) as err:
        ml.simulate(_with_torque_profile(_breaks_after(0.0075)), **RUN)
    e = err.value
    assert "torque 'motor'" in str(e) and "ZeroDivisionError" in str(e) and "t=0.008" in str(e)
    assert isinstance(e.__cause__, ZeroDivisionError)
    assert e.step == 8 and e.time == pytest.approx(0.008)
    assert e.result.status == "failed" and e.result.n_t == 8  # times 0 .. 0.007
    ref = ml.simulate(_with_torque_profile(lambda t: 1.0), **RUN)
    np.testing.assert_array_equal(e.result.q, ref.q[:8])


def test_a_nan_from_a_profile_is_named():
    def f(t):
        return np.nan if t > 0.0045 else 1.0
    with pytest.raises(ml.ProfileError, match=r"torque 'motor' gave a NaN or Inf.*t=0.005"):
        ml.simulate(_with_torque_profile(f), **RUN)


def test_a_profile_failing_at_the_start_fails_before_any_step():
    """(Set after add_force, which already refuses a profile that fails at t = 0.)"""
    m = flexible_mechanism()
    m.forces[0].profile = ml.Custom(lambda t: 1.0 / 0.0 if t >= 0 else 0.0)
    with pytest.raises(ml.ProfileError, match="force 'F' raised ZeroDivisionError.*at t=0") as err:
        ml.simulate(m, **RUN)
    assert err.value.step == 0 and err.value.result is None  # no run started


# ------------------------------------------------------------------- sensitivities
def _pendulum(p):
    from test_sensitivity_direct import pendulum
    return pendulum(p)


P0 = {"t": 1.5, "E": 70000.0, "rho": 2.7e-9, "M": 40.0, "x_pivot": 5.0, "m_tip": 2e-4}
TIP = ml.responses.point_displacement("beam", (60.0, -45.0), 1)


def test_a_raising_response_is_named_and_the_analysis_kept():
    calls = {"n": 0}

    def fragile(r):
        calls["n"] += 1
        if np.iscomplexobj(r.q):
            raise ValueError("no complex here")
        return r.q[-1, 0]

    with pytest.raises(ml.ResponseError, match="'fragile' raised ValueError.*perturbed") as err:
        ml.sensitivities(_pendulum, P0, {"tip": TIP, "fragile": fragile}, t_end=0.01, dt=1e-3)
    e = err.value
    assert e.response == "fragile" and isinstance(e.__cause__, ValueError)
    kept = e.sensitivity
    assert "tip" in kept.gradients and kept.result.status == "ok"
    d = kept.derivative(lambda r: r.q[-1])  # the analysis is usable
    assert d.shape == (kept.result.system.n_dof, len(P0)) and np.all(np.isfinite(d))


@pytest.mark.parametrize("bad", [None, "a string", np.nan, np.array([1.0, 2.0])])
@pytest.mark.parametrize("method", ["direct", "forward-difference"])
def test_a_response_that_is_not_a_finite_scalar_is_named(bad, method):
    with pytest.raises(ml.ResponseError, match="'odd' must return a finite real scalar"):
        ml.sensitivities(_pendulum, P0, {"odd": lambda r: bad}, method=method,
                         variables=["t"], t_end=0.005, dt=1e-3)


@pytest.mark.parametrize("value", [True, "2.0", None, [2.0], float("nan"), 1 + 2j])
def test_design_values_are_real_finite_numbers(value):
    with pytest.raises(ml.SensitivityError, match="'t' must be a finite real number"):
        ml.sensitivities(_pendulum, dict(P0, t=value), {"tip": TIP}, t_end=0.005, dt=1e-3)


def test_a_build_that_cannot_take_a_complex_step_is_named():
    import math

    def build(p):
        return _pendulum(dict(p, t=math.sqrt(p["t"] ** 2)))  # math.sqrt refuses complex

    with pytest.raises(ml.SensitivityError, match=r"build\(p\) raised TypeError.*'t' perturbed"
                       ) as err:
        ml.sensitivities(build, P0, {"tip": TIP}, variables=["t"], t_end=0.005, dt=1e-3)
    assert isinstance(err.value.__cause__, TypeError)


def test_a_variable_that_moves_a_load_to_another_node_is_refused():
    """Same counts and sparsity pattern (the beam's nodes all couple to its frame), but the
    force acts on another node under the perturbation: refused, naming the force."""
    def build(p):
        m = _pendulum(dict(P0, t=p["t"]))
        node = 3 if np.imag(p["t"]) != 0.0 else 2  # a bug: the node depends on the design
        m.add_force("beam", at=tuple(np.real(m.body("beam").nodes[node])), force=(0.0, -1.0),
                    name="Fk")
        return m

    with pytest.raises(ml.SensitivityError, match="moves force 'Fk'"):
        ml.sensitivities(build, {"t": 1.5}, {"tip": TIP}, t_end=0.005, dt=1e-3)
