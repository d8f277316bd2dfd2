"""FORM and importance sampling (morphlab.studies.reliability) against closed forms and
independent references.

* A linear limit state ``g = c - aᵀx`` in correlated normal variables: ``β = (c - aᵀμ) /
  sqrt(aᵀ C a)`` exactly, the design point ``μ + β C a / sqrt(aᵀ C a)``, importance factors
  ``(a_i σ_i)² / Σ (a_j σ_j)²``, found in one HL-RF step.
* A product of lognormals ``x y >= c``: nonlinear in the variables, linear in ``u`` (``ln x
  + ln y``), so FORM is exact: ``P = Φ((ln c - ln x_m - ln y_m) / sqrt(s_x² + s_y²))``.
* ``x1³ + x2³ >= 18`` with ``x1 ~ N(10, 5)``, ``x2 ~ N(9.9, 5)``: a strongly curved limit
  state on which plain HL-RF cycles. The design point against SciPy's SLSQP on the
  minimum-distance problem (an independent solver), the exact probability by a 1-D
  quadrature ``∫ f1(x1) F2(cbrt(18 - x1³)) dx1``, which importance sampling must meet
  within its standard errors while FORM's ``Φ(-β)`` is off by the curvature.
* A simulation (the cantilever of ``tests/models.py``): FORM with exact gradients against
  SLSQP with finite differences of plain simulations.
"""

import math

import numpy as np
import pytest
from models import tip_loaded_cantilever
from scipy import integrate, optimize, stats
from scipy.special import ndtr

import morphlab as ml
from morphlab.studies import (
    FunctionTask,
    JointDistribution,
    SearchOptions,
    SimulationTask,
    StudyError,
    form,
    importance_sampling,
)

MU = np.array([1.0, -2.0, 4.0])
SD = np.array([0.5, 0.3, 1.0])
R = np.array([[1.0, 0.4, 0.0], [0.4, 1.0, -0.3], [0.0, -0.3, 1.0]])
A = np.array([2.0, -3.0, 0.5])
NAMES = ["a", "b", "c"]


def linear(p):
    return ({"r": float(A @ [p[v] for v in NAMES])}, {"r": dict(zip(NAMES, A.tolist()))})


def normals(correlated=True):
    margs = {v: stats.norm(m, s) for v, m, s in zip(NAMES, MU, SD)}
    return JointDistribution(margs, correlation=R) if correlated else JointDistribution(margs)


@pytest.mark.parametrize("correlated", [True, False])
def test_linear_limit_state_in_normal_variables_is_exact(correlated):
    C = np.outer(SD, SD) * (R if correlated else np.eye(3))
    s = math.sqrt(A @ C @ A)
    limit = 14.0
    beta = (limit - A @ MU) / s
    res = form(FunctionTask(linear), normals(correlated), {"r": (None, limit)},
               executor="serial")
    ls = res.limit_states["r", "upper"]
    assert ls.converged and ls.iterations == 1 and ls.runs == 2  # start and one step
    assert ls.beta == pytest.approx(beta, rel=1e-13)  # round-off
    assert ls.p_form == pytest.approx(ndtr(-beta), rel=1e-12)
    x_star = MU + beta * C @ A / s
    np.testing.assert_allclose([ls.design_point[v] for v in NAMES], x_star, rtol=1e-13)
    # for normal variables the importance vector is a_i σ_i / |a σ| even when correlated
    gamma2 = (A * SD) ** 2 / np.sum((A * SD) ** 2)
    np.testing.assert_allclose([ls.importance[v] for v in NAMES], gamma2, rtol=1e-12)
    assert res.p_exceed["r"] == ls.p_form and res.p_sides["r"] == (0.0, ls.p_form)


def test_two_sides_and_a_failing_median():
    # lower limit above the mean: the median fails, beta < 0, P > 1/2
    C = np.outer(SD, SD) * R
    s = math.sqrt(A @ C @ A)
    mean = A @ MU
    res = form(FunctionTask(linear), normals(), {"r": (mean + 0.3, mean + 3.0)},
               executor="serial")
    lower, upper = res.limit_states["r", "lower"], res.limit_states["r", "upper"]
    assert lower.beta == pytest.approx(-0.3 / s, rel=1e-12) and lower.p_form > 0.5
    assert upper.beta == pytest.approx(3.0 / s, rel=1e-12)
    # disjoint events: the exceedance is the sum of both sides
    assert res.p_exceed["r"] == pytest.approx(ndtr(0.3 / s) + ndtr(-3.0 / s), rel=1e-12)
    # both searches share their start point: one run for it
    assert res.runs == lower.runs + upper.runs - 1


def product(p):
    return {"xy": p["x"] * p["y"]}, {"xy": {"x": p["y"], "y": p["x"]}}


def test_lognormal_product_is_linear_in_standard_space():
    sx, sy, c = 0.3, 0.2, 3.0
    J = JointDistribution({"x": stats.lognorm(sx, scale=2.0), "y": stats.lognorm(sy, scale=3.0)})
    res = form(FunctionTask(product), J, {"xy": (c, None)}, executor="serial")
    ls = res.limit_states["xy", "lower"]
    beta = (math.log(6.0) - math.log(c)) / math.hypot(sx, sy)
    # beta is read off the linearization at the last point, exact for g linear in u
    assert ls.converged and ls.beta == pytest.approx(beta, rel=1e-12)
    assert ls.importance["x"] == pytest.approx(sx**2 / (sx**2 + sy**2), rel=1e-9)


def cubic(p):
    x1, x2 = p["x1"], p["x2"]
    return {"g": x1**3 + x2**3}, {"g": {"x1": 3 * x1 * x1, "x2": 3 * x2 * x2}}


CUBIC = {"x1": stats.norm(10.0, 5.0), "x2": stats.norm(9.9, 5.0)}


@pytest.fixture(scope="module")
def cubic_form():
    return form(FunctionTask(cubic), JointDistribution(CUBIC), {"g": (18.0, None)},
                executor="serial")


def test_curved_limit_state_design_point_against_slsqp(cubic_form):
    ls = cubic_form.limit_states["g", "lower"]
    def g_u(u):
        return (10.0 + 5.0 * u[0]) ** 3 + (9.9 + 5.0 * u[1]) ** 3 - 18.0

    ref = optimize.minimize(lambda u: 0.5 * u @ u, [-1.0, -1.0], jac=lambda u: u,
                            constraints=[{"type": "eq", "fun": g_u}], method="SLSQP",
                            options={"ftol": 1e-14})
    assert ref.success
    # the iHL-RF search stops at |g| <= 1e-6 |g(0)| and 1e-6 alignment: the distance of the
    # design points is of that order; beta (from the linearisation) is second order in it
    assert ls.converged, ls.message
    np.testing.assert_allclose(ls.u, ref.x, atol=1e-5)
    assert ls.beta == pytest.approx(np.linalg.norm(ref.x), abs=1e-8)


def test_importance_sampling_meets_the_exact_probability(cubic_form):
    f1, f2 = CUBIC["x1"], CUBIC["x2"]
    exact, err = integrate.quad(lambda x1: f1.pdf(x1) * f2.cdf(np.cbrt(18.0 - x1**3)),
                                -40.0, 60.0, points=[18.0 ** (1 / 3)], limit=200)
    assert err < 1e-8
    ls = cubic_form.limit_states["g", "lower"]
    # FORM's Φ(-β) misses by the curvature of the limit surface: here by a factor ~2.3
    assert ls.p_form > 2.0 * exact
    importance_sampling(FunctionTask(cubic), JointDistribution(CUBIC), cubic_form, 4000,
                        executor="serial", seed=3)
    # unbiased: within 4 of its standard errors (a fixed seed)
    assert abs(ls.p_is - exact) < 4.0 * ls.is_std_error, (ls.p_is, exact, ls.is_std_error)
    assert ls.is_cov < 0.05  # 4000 draws around the design point suffice for 5 %
    assert ls.is_ci[0] < exact < ls.is_ci[1]
    assert cubic_form.method == "importance-sampling"
    assert cubic_form.p_exceed["g"] == ls.p_is


# ---------------------------------------------------------------- a simulation
SETTINGS = {"t_end": 0.012, "dt": 2.5e-4}
STRESS = {"stress": ml.responses.ks_max_stress("beam", 2.0)}
CANTILEVER = {"t": stats.norm(2.0, 0.1), "F": stats.lognorm(0.2, scale=1.0)}
LIMIT = 34.0  # MPa; the KS stress at the medians is 26.2


def stress_of(p):
    res = ml.simulate(tip_loaded_cantilever(p), **SETTINGS)
    return float(STRESS["stress"](res))


def test_form_on_a_simulation_against_finite_difference_slsqp():
    J = JointDistribution(CANTILEVER)
    task = SimulationTask(tip_loaded_cantilever, STRESS, SETTINGS, gradients=True)
    res = form(task, J, {"stress": (None, LIMIT)}, executor="serial")
    ls = res.limit_states["stress", "upper"]
    assert ls.converged, ls.message

    def g_u(u):
        x = J.from_standard(u[None, :])[0]
        return LIMIT - stress_of({"t": x[0], "F": x[1]})

    ref = optimize.minimize(lambda u: 0.5 * u @ u, np.zeros(2), jac=lambda u: u,
                            constraints=[{"type": "eq", "fun": g_u}], method="SLSQP",
                            options={"ftol": 1e-12})
    assert ref.success
    # forward differences (step ~1.5e-8) leave ~1e-7 in the constraint's gradient, and the
    # two stopping rules 1e-6: both design points agree to ~1e-5
    np.testing.assert_allclose(ls.u, ref.x, atol=2e-5)
    assert ls.beta == pytest.approx(np.linalg.norm(ref.x), abs=1e-5)
    # the design point lies on the limit surface: re-simulated, the stress is the limit
    assert stress_of(ls.design_point) == pytest.approx(LIMIT, rel=1e-6)
    assert ls.runs < 20


@pytest.mark.parametrize("call, match", [
    (lambda: form(FunctionTask(linear), normals(), {}), "needs allowables"),
    (lambda: form(lambda p: {"r": 1.0}, normals(), {"r": (None, 1.0)}), "needs gradients"),
    (lambda: form(FunctionTask(linear), normals(), {"q": (None, 1.0)}, executor="serial"),
     "no value or no gradient of 'q'"),
    (lambda: form(FunctionTask(linear), normals(), {"r": (None, 1.0)}, fixed={"a": 1.0}),
     "both random and fixed"),
    (lambda: form(SimulationTask(tip_loaded_cantilever, STRESS, dict(SETTINGS, max_halvings=2)),
                  CANTILEVER, {"stress": (None, 30.0)}), "max_halvings"),
])
def test_bad_input_is_a_typed_error(call, match):
    with pytest.raises(StudyError, match=match):
        call()


def test_a_failing_start_keeps_the_message():
    def broken(p):
        raise ml.ConvergenceError("Newton did not converge")

    res = form(FunctionTask(broken), normals(), {"r": (None, 1.0)}, executor="serial")
    ls = res.limit_states["r", "upper"]
    assert not ls.converged and "start point failed" in ls.message and math.isnan(ls.beta)


def test_options_bound_the_search():
    res = form(FunctionTask(cubic), JointDistribution(CUBIC), {"g": (18.0, None)},
               executor="serial", options=SearchOptions(max_iter=3))
    ls = res.limit_states["g", "lower"]
    assert not ls.converged and "not converged in 3 iterations" in ls.message
    assert ls.iterations == 3 and "not converged" in res.table()

