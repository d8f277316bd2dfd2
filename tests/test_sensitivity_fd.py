"""Finite-difference sensitivity methods against the whole-run complex step: observed order.

Against the complex-step reference (no truncation error), a forward difference of step h has
error (h/2) f'' + O(h²), first order; a central difference (h²/6) f''' + O(h⁴), second order
(e.g. Nocedal & Wright, Numerical Optimization, 2nd ed., §8.1). ``"direct-fd"`` (the paper's
semi-analytical variant) takes the explicit part ``dR/dp`` of each step's pseudo-load by a
forward difference (the state part is exact, from the Newton-matrix kernel), so its error is
first order in the variables the residual depends on nonlinearly (thickness, geometry) and at
round-off in those it depends on linearly (E, a torque, the density, a point mass). Each test
fits the slope of log(error) against log(step) over a range of steps above the round-off floor
and checks it against the declared order, or bounds the round-off.

The error of a gradient column is the largest relative error over the responses (a
displacement, the KS stress, an RMS shape error and a reaction), so one slope per variable and
method. Variables: thickness, E, torque magnitude and a geometry variable (the x coordinate of
the ground pivot, which changes the beam's length and direction).

Noise floor: the primal responses carry a relative error of ~1e-11 (Newton tolerance and
round-off accumulated over the run), which a difference quotient divides by the step; with
these models the quotient's noise reaches the truncation error at steps ~1e-5 (forward) and
~1e-3 (central), so the fitted ranges stop one decade or more above that.
"""

import numpy as np
import pytest

import morphlab as ml

R = ml.responses
RUN = dict(t_end=0.03, dt=1e-3)
TIP = np.array([60.0, -45.0])  # fixed tip point [mm]


def pendulum(p, n_elem=4):
    """Flexible pendulum: beam from the ground pivot (x_pivot, 0) to a fixed tip point, pinned
    to the ground, with a rigid tip mass pinned at the tip; gravity and a ramped torque."""
    m = ml.Model(gravity=(0.0, -9.81e3), name="pendulum")
    pivot = np.array([p["x_pivot"], 0.0])
    s = np.linspace(0.0, 1.0, n_elem + 1)[:, None]
    nodes = pivot + s * (TIP - pivot)
    beam = m.add_beam(nodes, E=p["E"], rho=p.get("rho", 2.7e-9), thickness=p["t"],
                      width=10.0, damping=1e-4, name="beam")
    m.add_revolute(m.ground, beam, at=pivot, name="pivot")
    tip = m.add_rigid_body(mass=p.get("m_tip", 2e-4), inertia=0.05, position=TIP, name="tip")
    m.add_revolute(beam, tip, at=TIP, name="T")
    m.add_torque(beam, p["M"], profile=ml.SmoothStep(0.0, 0.01), name="Mt")
    return m


# The library's step is relative, h_i = step * |p_i| (step itself only where p_i = 0:
# relative_steps in morphlab/sensitivity/perturb.py), so one list of steps serves variables of
# any magnitude (test_small_variables_... checks rho and the tip mass).
P0 = {"t": 1.5, "E": 70000.0, "M": 40.0, "x_pivot": 5.0}
TARGET = np.real(np.asarray(pendulum(P0).body("beam").nodes)) + np.array([3.0, -5.0])
RESPONSES = {
    "displacement": R.point_displacement("beam", tuple(TIP), 1),
    "ks_stress": R.ks_max_stress("beam", 0.5),
    "rms_error": R.rms_error("beam", TARGET),
    "reaction": lambda r: r.lam[-1, r.system.con_names.index("pivot.y")],
}


@pytest.fixture(scope="module")
def reference():
    return ml.sensitivities(pendulum, P0, RESPONSES, method="complex-step", **RUN)


def strategy(method: str, h: float) -> ml.Strategy:
    """The strategy of ``method`` with the relative step ``h``; the direct method's exact
    variant (its matrices at the converged states), so that the truncation error of the
    difference quotient is all that is measured."""
    if method == "direct-fd":
        return ml.Direct(partials="forward-difference", step=h, reuse=False)
    return ml.FiniteDifference(method.split("-")[0], step=h)


def column_errors(method, steps, p0, variables, ref):
    """errors[v][k]: max over responses of the relative gradient error at steps[k]."""
    errors = {v: [] for v in variables}
    for h in steps:
        s = ml.sensitivities(pendulum, p0, RESPONSES, method=strategy(method, h),
                             variables=variables, **RUN)
        for v in variables:
            errors[v].append(max(abs(s.gradients[r][v] / ref.gradients[r][v] - 1.0)
                                 for r in RESPONSES))
    return errors


def slope(steps, errors):
    return np.polyfit(np.log(steps), np.log(errors), 1)[0]


# Bands. Forward: the next term changes the error by a relative O(h f'''/f'') <~ 1e-2 at these
# steps and the noise (~1e-7 at h = 1e-4) is below 1/100 of the smallest column error fitted
# (4.5e-5), so the slope is 1 to within a few per cent; measured 0.998-1.000. Central: steps
# down to 3e-3 keep the noise (~3e-9) 300 times below the column errors (>= 1e-6 at 3e-3); the
# O(h⁴) term at the largest step is what bends the fit: measured 2.000-2.009. Direct-fd: the
# pseudo-load's second-order term accumulates over the run and the reaction's error is still
# slightly pre-asymptotic at 3e-4; measured 0.976-1.006 over 3e-4..3e-5.
CASES = {
    "forward-difference": ([3e-3, 1e-3, 3e-4, 1e-4], 1.0, 0.1),
    "central-difference": ([3e-2, 1e-2, 3e-3], 2.0, 0.2),
}


@pytest.mark.parametrize("method", list(CASES))
def test_difference_quotients_converge_at_their_order(reference, method):
    steps, order, band = CASES[method]
    errors = column_errors(method, steps, P0, list(P0), reference)
    for v, e in errors.items():
        assert abs(slope(steps, e) - order) < band, (method, v, e)
    # and the error is of the size the step predicts, C h^order with C of order one to ten on
    # these responses (measured C <= 10 forward, <= 24 central): bound C < 100
    assert max(e[-1] for e in errors.values()) < 100.0 * steps[-1] ** order


DIRECT_FD_STEPS = [3e-4, 1e-4, 3e-5]


def test_direct_fd_converges_at_first_order(reference):
    """Thickness enters the residual nonlinearly (A ~ t, I ~ t³): first order."""
    errors = column_errors("direct-fd", DIRECT_FD_STEPS, P0, ["t"], reference)
    assert abs(slope(DIRECT_FD_STEPS, errors["t"]) - 1.0) < 0.1, errors


# The residual is linear in E (K ~ E) and in the torque, so the forward difference of the
# explicit part has no truncation error; what is left is round-off, eps |R_p| / h, with R_p the
# residual over the parts the variable changes: on this swinging pendulum the beam's inertia
# and gravity forces exceed its elastic forces by ~1e5, so the relative error is about
# 1e-16 * 1e5 / h (measured h * error: 5e-11..6e-11 for E, <= 3e-13 for the torque). Bound
# 1e-9 / h: a margin of ~16, and a first-order truncation error of size h (what a wrong state
# part would leave) fails it at the largest step by a factor of ~30.
def test_direct_fd_is_exact_to_round_off_for_linear_variables(reference):
    errors = column_errors("direct-fd", DIRECT_FD_STEPS, P0, ["E", "M"], reference)
    for v, e in errors.items():
        assert np.all(np.asarray(e) < 1e-9 / np.asarray(DIRECT_FD_STEPS)), (v, e)


# Moving the pivot changes the joint rows' partial derivatives by ~2e3 (scaled rows) while the
# total derivative, after the state part cancels them, is small: the forward difference's
# relative truncation error of the partials (~h) is amplified by that ratio. This is the known
# weakness of the semi-analytical method for shape variables (Barthelemy & Haftka, AIAA J. 28
# (1990) 1533); the complex-step pseudo-load ("direct") has no truncation error. Measured
# error / h = 470 (the KS stress, whose pivot sensitivity is 2e-4 of its thickness
# sensitivity), 0.7 for the displacement; bound 2000 h: a margin of 4, and the first-order
# slope is checked as well.
def test_direct_fd_geometry_variable_converges(reference):
    errors = column_errors("direct-fd", DIRECT_FD_STEPS, P0, ["x_pivot"], reference)
    assert abs(slope(DIRECT_FD_STEPS, errors["x_pivot"]) - 1.0) < 0.1, errors
    assert np.all(np.asarray(errors["x_pivot"]) < 2000.0 * np.asarray(DIRECT_FD_STEPS)), errors


@pytest.mark.filterwarnings("ignore::RuntimeWarning")  # overflow of the 370x-perturbed runs
@pytest.mark.parametrize("method", list(CASES) + ["direct-fd"])
def test_small_variables_converge_at_their_order(method):
    p0 = dict(P0, rho=2.7e-9, m_tip=2e-4)
    variables = ["rho", "m_tip"]
    ref = ml.sensitivities(pendulum, p0, RESPONSES, method="complex-step", variables=variables,
                           **RUN)
    steps, order, band = CASES.get(method, (DIRECT_FD_STEPS, 1.0, 0.1))
    errors = column_errors(method, steps, p0, variables, ref)
    for v, e in errors.items():
        if method == "direct-fd":
            # The step residual of the default (Arnold-Bruls) scheme is linear in rho and in
            # a point mass (inertia terms at t_{n+1} only), so the forward-difference
            # pseudo-load has no truncation error in them: measured 1.5e-9..3.6e-8 relative at
            # steps 3e-4..3e-5, i.e. round-off. Bound: the first-order estimate 100 h plus a
            # round-off floor of 1e-6 (eps / h = 7e-12 / 3e-5 times the response scale).
            assert np.all(np.asarray(e) < 100 * np.asarray(steps) + 1e-6), (v, e)
        else:
            assert abs(slope(steps, e) - order) < band, (method, v, e)
