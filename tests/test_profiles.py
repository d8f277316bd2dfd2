"""Profile algebra (sums, multiples, products) and exact integrals, checked against complex-step
and finite-difference derivatives and against quadrature of the integrand."""

import numpy as np
import pytest
from scipy.integrate import quad

import morphlab as ml
from morphlab.errors import ModelError
from morphlab.model.profiles import Integral, Polynomial, Product, Scaled, Sum

TIMES = np.array([-0.1, 0.0, 0.013, 0.05, 0.11, 0.2, 0.37])

PROFILES = {
    "sum": ml.SmoothStep(0.0, 0.1) + 0.5 * ml.Sine(20.0, 0.3),
    "difference": ml.Ramp(0.02, 0.2) - ml.Linear(3.0) / 4.0,
    "product": ml.SmoothStep(0.0, 0.1) * ml.Sine(20.0, 0.3),
    "polynomial": Polynomial((1.0, -2.0, 3.0, 0.5)),
    "number plus": 2.0 + ml.Linear(1.5) - 1.0,
    "negated": -ml.Sine(7.0),
    "integral": (ml.SmoothStep(0.0, 0.1) * 3.0 + 1.0).integral(0.25),
}


def _fd(f, t, e=1e-6):
    return (f(t + e) - f(t - e)) / (2 * e)


@pytest.mark.parametrize("name", PROFILES)
def test_derivatives_match_differences_of_the_value(name):
    """d1, d2 against central differences of value and d1 (error ~ e² f''' ~ 1e-12 · 1e4;
    tolerance 1e-6 relative to the scale of the derivative)."""
    p = PROFILES[name]
    for t in TIMES[(TIMES != 0.0) & (TIMES != 0.2)]:  # away from the steps' and ramp's kinks
        assert p.d1(t) == pytest.approx(_fd(p.value, t), rel=1e-6, abs=1e-6)
        assert p.d2(t) == pytest.approx(_fd(p.d1, t), rel=1e-6, abs=1e-4)


@pytest.mark.parametrize("name", PROFILES)
def test_table_equals_pointwise_values(name):
    """The vectorized table gives the pointwise values to round-off."""
    p = PROFILES[name]
    f, f1, f2 = p.table(TIMES)
    for k, t in enumerate(TIMES):
        assert (f[k], f1[k], f2[k]) == pytest.approx((p.value(t), p.d1(t), p.d2(t)),
                                                     rel=1e-13, abs=1e-12)


def test_operators_build_the_expected_tree():
    a, b = ml.Ramp(0, 1), ml.Sine(2.0)
    assert isinstance(a + b, Sum) and isinstance(2 * a, Scaled) and isinstance(a * b, Product)
    assert (a * 2.0).factor == 2.0 and (a / 4).factor == 0.25
    with pytest.raises(ModelError, match="division by zero"):
        a / 0
    with pytest.raises(ModelError, match="numbers and other profiles"):
        a + "1"
    with pytest.raises(ModelError, match="numbers and other profiles"):
        a * True


@pytest.mark.parametrize("prof", [
    ml.Constant(2.5), ml.Linear(-3.0), Polynomial((1.0, 2.0, -1.0)), ml.Ramp(0.05, 0.2),
    ml.Ramp(-0.1, 0.1), ml.SmoothStep(0.02, 0.3), ml.Sine(15.0, 0.4),
    2.0 * ml.SmoothStep(0.0, 0.1) + ml.Sine(3.0) - 1.0,
], ids=repr)
def test_integral_is_exact(prof):
    """F(t) - c0 against adaptive quadrature of f (quad's error ~1e-14 here), F' = f, F'' = f'."""
    F = prof.integral(c0=0.7)
    assert isinstance(F, Integral) and F.value(0.0) == 0.7
    for t in TIMES:
        ref, _ = quad(prof.value, 0.0, t, epsabs=1e-13, epsrel=1e-13, points=None, limit=200)
        assert F.value(t) - 0.7 == pytest.approx(ref, rel=1e-11, abs=1e-12)
        assert F.d1(t) == prof.value(t) and F.d2(t) == prof.d1(t)
    f, f1, f2 = F.table(TIMES)
    assert np.allclose(f, [F.value(t) for t in TIMES], rtol=1e-14, atol=1e-14)


def test_integral_of_a_complex_parameter_carries_the_derivative():
    """Complex step through a speed: d/dw of int_0^t w·SmoothStep = int_0^t SmoothStep."""
    h = 1e-30
    F = (complex(4.0, h) * ml.SmoothStep(0.0, 0.1)).integral()
    G = ml.SmoothStep(0.0, 0.1).integral()
    for t in TIMES:
        assert F.value(t).imag / h == pytest.approx(G.value(t), rel=1e-14, abs=1e-16)
        assert F.value(t).real == pytest.approx(4.0 * G.value(t), rel=1e-14, abs=1e-16)


@pytest.mark.parametrize("prof", [ml.Custom(np.sin), ml.Ramp(0, 1) * ml.Sine(2.0),
                                  ml.Sine(1.0).integral()])
def test_profiles_without_closed_form_integral_refuse(prof):
    with pytest.raises(ModelError, match="no closed-form integral"):
        prof.integral()


def test_drive_needs_exactly_one_of_angle_and_speed():
    m = ml.Model()
    body = m.add_rigid_body(mass=1.0, inertia=1.0, position=(0.0, 0.0))
    with pytest.raises(ModelError, match="exactly one of angle= .* and speed="):
        m.add_drive(body)
    with pytest.raises(ModelError, match="exactly one"):
        m.add_drive(body, angle=ml.Linear(1.0), speed=1.0)
    with pytest.raises(ModelError, match="closed-form integral"):
        m.add_drive(body, speed=ml.Custom(np.cos))
    d = m.add_drive(body, speed=2.0 * ml.SmoothStep(0.0, 0.5))
    assert d.profile.d1(0.25) == 2.0 * ml.SmoothStep(0.0, 0.5).value(0.25)
