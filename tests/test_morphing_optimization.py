"""The morphing leading edge as a design problem (morphlab.morphing.optimization): the
clearance response against independent geometry and finite differences, the optimum against
the start design with an independent re-simulation, first-order propagation of the
manufacturing tolerances."""

import numpy as np
import pytest

import morphlab as ml
from morphlab.morphing import leading_edge as le
from morphlab.morphing import optimization as opt


@pytest.fixture(scope="module")
def nominal():
    p = opt.start()
    return p, ml.simulate(opt.build(p), **le.SETTINGS)


def test_the_zoned_build_is_the_study_model_at_the_start(nominal):
    """Six zones of the default thickness are the study's uniform skin: the same run."""
    p, res = nominal
    ref = ml.simulate(le.build(), **le.SETTINGS)
    assert np.array_equal(res.q, ref.q)
    assert len(opt.VARIABLES) >= 12


def test_clearance_against_sampled_geometry(nominal):
    """At t = 0 the distance of A, B, D from the undeformed skin contour, against the least
    distance to 4001 points sampled on every segment: sampling with spacing delta errs by at
    most delta^2 / (8 d) for a point at distance d (the chord of a circle), far below the
    bound asserted. The sign: all three joints lie inside the profile."""
    p, res = nominal
    c = opt.clearances(res)
    S = le.undeformed()
    closed = np.vstack([S, S[:1]])
    s = np.linspace(0.0, 1.0, 4001)[:, None, None]
    pts = (closed[:-1] + s * (closed[1:] - closed[:-1])).reshape(-1, 2)
    delta = np.max(np.linalg.norm(np.diff(closed, axis=0), axis=1)) / 4000
    for name, body in (("A", "crank"), ("B", "crank"), ("D", "arm")):
        P = np.real(res.point_positions(body, opt._joint_point(res.system.model, name))[0])
        d = np.min(np.linalg.norm(pts - P, axis=1))
        assert c[name][0].real == pytest.approx(d, abs=delta**2 / (8 * d) + 1e-12)
        assert c[name][0].real > 0


def test_clearance_gradient_against_central_differences():
    """The complex-step derivative of the clearance (direct method) against central
    differences with a relative step of 1e-6: their truncation error O(h^2) is ~1e-12 of the
    value and round-off ~1e-16 |f| / h ~ 1e-9 mm/unit, so 1e-5 relative holds where the
    minimiser (joint, time) does not switch within the step."""
    p = opt.start()
    names = ["t4", "x_A", "y_B", "M_t"]
    resp = {"joint_clearance": opt.joint_clearance}
    exact = ml.sensitivities(opt.build, p, resp, variables=names, method="direct",
                             settings=le.SETTINGS)
    fd = ml.sensitivities(opt.build, p, resp, variables=names,
                          method=ml.FiniteDifference("central", step=1e-6), settings=le.SETTINGS)
    for v in names:
        g, f = exact.gradients["joint_clearance"][v], fd.gradients["joint_clearance"][v]
        assert g == pytest.approx(f, rel=1e-5, abs=1e-9), v


@pytest.mark.slow
def test_optimum_is_better_feasible_and_verified():
    """SLSQP with exact gradients over the 13 variables (a short run): a lower RMS shape error
    than the start with every constraint satisfied, and an independent re-simulation of the
    optimum (no optimizer cache) gives the recorded values to round-off, no link crossing the
    skin and a monotone crank rotation during the torque ramp."""
    from morphlab.studies import optimize

    pb = opt.problem()
    res = optimize(pb, "SLSQP", options={"ftol": 1e-6, "maxiter": 8})
    start = res.history.evaluations[0]["objective"]
    assert res.feasible and res.objective < start - 1e-3 * start
    check = opt.verify(res.design)
    assert check["ok"], check
    for k in ("rms_error", "ks_max_stress", "joint_clearance"):
        assert check[k] == pytest.approx(res.values[k], rel=1e-12, abs=1e-14)
    assert check["ks_max_stress"] <= opt.ALLOWABLE_MPA
    assert check["joint_clearance"] >= opt.CLEARANCE_MM


def test_fosm_of_the_tolerances_is_linear_propagation(nominal):
    """FOSM standard deviations are sqrt(sum (dr/dp_i sigma_i)^2) of the direct gradients
    (independent variables): recomputed here from the sensitivity result."""
    unc, sens = opt.tolerances_fosm(opt.start())
    for k in ("rms_error", "ks_max_stress"):
        sd = np.sqrt(sum((sens.gradients[k][v] * s) ** 2 for v, s in opt.TOLERANCES.items()))
        assert unc.std[k] == pytest.approx(sd, rel=1e-12)
    assert unc.p_exceed["ks_max_stress"] < 1e-6  # 83 MPa, sigma ~5 MPa, allowable 160 MPa
