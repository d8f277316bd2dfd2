"""The morphing leading edge's manufacturing tolerances as a reliability problem
(morphlab.morphing.optimization.reliability_problem / reliability).

* FORM's design point of ``KS stress > 160 MPa`` checked without the library's gradients:
  re-simulated, the stress there is the allowable; and the gradient of the stress there by
  central differences of plain simulations, mapped to the standard space, is parallel to
  the design point (the optimality condition of the nearest point of the limit surface).
* The probabilities of both events by FORM, importance sampling and plain Monte Carlo
  agree within their standard errors (slow: 2000 Monte Carlo runs).
"""

import math

import numpy as np
import pytest

import morphlab as ml
from morphlab import studies
from morphlab.morphing import leading_edge as le
from morphlab.morphing import optimization as opt

SETTINGS = dict(le.SETTINGS, dt=1e-3)  # 150 steps, as notebook 09 in its quick mode


@pytest.mark.slow
def test_form_design_point_of_the_stress_against_finite_differences():
    p = opt.start()
    rp = opt.reliability_problem(p, settings=SETTINGS)
    res = studies.form(rp.task, rp.distributions, {"ks_max_stress": rp.allowables[
        "ks_max_stress"]}, fixed=rp.fixed, executor="serial")
    ls = res.limit_states["ks_max_stress", "upper"]
    assert ls.converged, ls.message
    x_star = {**rp.fixed, **ls.design_point}

    def stress(q):
        run = ml.simulate(opt.build(q), **SETTINGS)
        return float(le.ks_max_stress(run))

    # on the limit surface: |g| <= 1e-6 |g(0)| = 1e-6 x 82 MPa by the stopping rule
    assert stress(x_star) == pytest.approx(opt.ALLOWABLE_MPA, abs=1e-4)
    names = rp.distributions.names
    grad = np.empty(len(names))
    for j, v in enumerate(names):
        h = 1e-5 * max(abs(x_star[v]), 1.0)
        grad[j] = (stress({**x_star, v: x_star[v] + h})
                   - stress({**x_star, v: x_star[v] - h})) / (2 * h)
    grad_u = rp.distributions.jacobian(ls.u).T @ grad
    cos = grad_u @ ls.u / (np.linalg.norm(grad_u) * np.linalg.norm(ls.u))
    # central differences: relative error ~1e-6 (h² of the curvature, 1e-16/h round-off
    # amplified by the Newton tolerance 1e-10 of the runs / h), so an angle below 1e-4 rad
    assert math.acos(min(cos, 1.0)) < 1e-4
    # FOSM's normal approximation puts this event at 1.5e-11; its design point is far
    # closer: the stress grows much faster than linearly towards it
    assert 2.0 < ls.beta < 4.0


@pytest.mark.slow
def test_form_importance_sampling_and_monte_carlo_agree():
    """About 80 s on 2 cores: FORM with its mirror search (~50 gradient runs), 2 x 200
    importance-sampling runs and 2000 Monte Carlo runs of the leading edge."""
    p = opt.start()
    form = opt.reliability(p, "importance-sampling", n=200, settings=SETTINGS, seed=1)
    mc = opt.reliability(p, "monte-carlo", n=2000, settings=SETTINGS, seed=2)
    stress = form.limit_states["ks_max_stress", "upper"]
    error = form.limit_states["max_error", "upper"]
    # the node error fails on both sides of the target: two design points, about opposite
    assert len(error.modes) == 2 and len(stress.modes) == 1
    assert error.modes[0]["alpha"] @ error.modes[1]["alpha"] < -0.5
    for ls in (stress, error):
        assert ls.converged and ls.is_cov < 0.25
        p_mc = mc.p_exceed[ls.response]
        se_mc = math.sqrt(ls.p_is * (1 - ls.p_is) / mc.n)  # binomial, at the IS estimate
        # both estimators are unbiased: within 3 standard errors of their difference
        assert abs(ls.p_is - p_mc) < 3 * math.hypot(ls.is_std_error, se_mc), \
            (ls.response, ls.p_is, p_mc)


def test_tolerances_monte_carlo_gives_bootstrap_intervals():
    """Issue 38: the std interval is the BCa bootstrap of the sample (it holds for skewed
    responses, tests/test_studies_statistics.py), no longer the chi-square one."""
    from scipy import stats as st

    from morphlab.studies import mean_std

    out, table = opt.tolerances_monte_carlo(opt.start(), 24, seed=3, executor="serial",
                                            settings=dict(le.SETTINGS, dt=2e-3))
    x = table.values["ks_max_stress"][table.ok]
    assert out["ks_max_stress"]["std_ci"] == mean_std(x, 0.95, seed=3)["std_ci"]
    lo, hi = st.chi2.ppf([0.975, 0.025], x.size - 1)
    sd = np.std(x, ddof=1)
    assert out["ks_max_stress"]["std_ci"] != (sd * np.sqrt((x.size - 1) / lo),
                                              sd * np.sqrt((x.size - 1) / hi))
    assert out["n"] == 24 and out["ks_max_stress"]["std"] == sd
