"""The kinematic-accuracy check on beams with one frame per element (the default): its
estimate against the exact large-rotation statics, converged meshes quiet at the default
kinematic_tol (1e-3 of the length), coarse ones warned with the number of elements that
brings them below it, and that many elements do (docs/frames.md, "Calibration")."""

import re
import warnings

import numpy as np
import pytest
from scipy.integrate import solve_ivp
from scipy.optimize import brentq

import morphlab as ml
from morphlab.errors import KinematicAccuracyWarning

E, RHO, T, B, L = 70000.0, 2.7e-9, 2.0, 10.0, 200.0  # MPa, t/mm^3, mm
EI = E * B * T**3 / 12.0
TOL = 1e-3  # the default kinematic_tol


def straight(n):
    return np.stack([np.linspace(0.0, L, n + 1), np.zeros(n + 1)], axis=1)


def tip_moment(n, phi):
    """A cantilever of n elements rolled by a tip moment to the tip rotation ``phi``; the
    exact nodes lie on the arc of radius L/phi."""
    m = ml.Model()
    b = m.add_beam(straight(n), E=E, rho=RHO, thickness=T, width=B, name="b")
    m.add_fix(b, at=(0.0, 0.0))
    m.add_torque(b, EI * phi / L, at=(L, 0.0), profile=ml.Linear(1.0))
    R, s = L / phi, np.linspace(0.0, L, n + 1)
    return m, np.stack([R * np.sin(s / R), R * (1 - np.cos(s / R))], axis=1)


def elastica(n, alpha):
    """A cantilever of n elements under a dead tip load P = alpha EI/L^2; the exact nodes
    from the elastica theta'' = (P/EI) cos(theta), theta(0) = 0, theta'(L) = 0 (shooting on
    theta'(0), integrated to 1e-12)."""
    k = alpha / L**2

    def rhs(_, y):
        return [y[1], k * np.cos(y[0]), np.cos(y[0]), np.sin(y[0])]

    def end_curvature(d0):
        return solve_ivp(rhs, (0, L), [0, d0, 0, 0], rtol=1e-12, atol=1e-14).y[1, -1]

    d0 = brentq(end_curvature, -5 * alpha / L, 0.0, xtol=1e-15)
    s = np.linspace(0.0, L, n + 1)
    sol = solve_ivp(rhs, (0, L), [0, d0, 0, 0], rtol=1e-12, atol=1e-14, t_eval=s)
    m = ml.Model()
    b = m.add_beam(straight(n), E=E, rho=RHO, thickness=T, width=B, name="b")
    m.add_fix(b, at=(0.0, 0.0))
    m.add_force(b, at=(L, 0.0), force=(0.0, -alpha * EI / L**2), profile=ml.Linear(1.0))
    return m, np.stack([sol.y[2], sol.y[3]], axis=1)


def solve(model, **kw):
    return ml.static(model, t=1.0, steps=20, **kw)


def error(res, exact):
    """Largest node distance from the exact solution [mm]."""
    return float(np.max(np.hypot(*(res.node_positions("b")[-1] - exact).T)))


CASES = {"tip moment 60 deg": lambda n: tip_moment(n, np.pi / 3),
         "elastica 56 deg": lambda n: elastica(n, 3.0),
         "elastica 82 deg": lambda n: elastica(n, 10.0)}


@pytest.mark.parametrize("case, n", [("tip moment 60 deg", 8), ("tip moment 60 deg", 16),
                                     ("elastica 56 deg", 16), ("elastica 82 deg", 32)])
def test_converged_meshes_are_quiet_and_the_estimate_is_the_error(case, n):
    """The issue's cantilever of 16 elements at 60 degrees (error 0.034 mm, 1.7e-4 L) and
    its like read "ok" at the default; the estimate lies within 0.75-1.25 of the measured
    error (observed 0.80-1.05 on these: docs/frames.md)."""
    model, exact = CASES[case](n)
    with warnings.catch_warnings():
        warnings.simplefilter("error", ml.errors.MorphlabWarning)
        res = solve(model)
    assert res.status == "ok"
    err = error(res, exact)
    assert err < TOL * L
    assert 0.75 < res.kinematics["b"].estimate / err < 1.25


@pytest.mark.parametrize("case, n, advised", [("tip moment 60 deg", 4, 7),
                                              ("elastica 82 deg", 8, 13)])
def test_coarse_meshes_are_told_how_far_to_refine(case, n, advised):
    """4 elements at 60 degrees (estimate 2.9e-3 L) and 8 in the 82-degree elastica
    (2.3e-3 L) warn and advise ceil(n sqrt(estimate/tol)) elements, by the 1/n^2 law of the
    estimate (7 and 13: the old message advised frames='element', which they already have);
    at that mesh the run is quiet and the exact error below the tolerance."""
    model, exact = CASES[case](n)
    with pytest.warns(KinematicAccuracyWarning, match=r"beam 'b'.*refine the mesh to about "
                      rf"{advised} elements \(now {n}") as rec:
        res = solve(model)
    assert res.status == "warning"
    assert error(res, exact) > TOL * L  # the warning is right
    rel = res.kinematics["b"].relative
    assert int(np.ceil(n * np.sqrt(rel / TOL))) == advised
    assert re.search(rf"about {advised} elements", str(rec[0].message))
    model, exact = CASES[case](advised)
    with warnings.catch_warnings():
        warnings.simplefilter("error", ml.errors.MorphlabWarning)
        res = solve(model)
    assert res.status == "ok" and error(res, exact) < TOL * L


def test_a_beam_with_fewer_frames_is_told_frames_then_elements():
    """One frame on 8 elements, bent to Phi: its estimate is the stretch Phi^2 L/6
    (test_kinematics_diagnostic), so Phi = 0.25 asks ceil(sqrt(0.0104/1e-3)) = 4 frames, and
    Phi = 1 ceil(sqrt(0.167/1e-3)) = 13, more than the elements: one frame per element and
    13 elements."""
    for phi, hint in ((0.25, r"frames=4, reference='chord'"),
                      (1.0, r"frames='element'\) and refine the mesh to about 13 elements")):
        m = ml.Model()
        b = m.add_beam(straight(8), E=E, rho=RHO, thickness=T, width=B, frames=1,
                       reference="first", name="b")
        m.add_fix(b, at=(0.0, 0.0))
        m.add_torque(b, EI * phi / L, at=(L, 0.0), profile=ml.Linear(1.0))
        with pytest.warns(KinematicAccuracyWarning, match=hint):
            solve(m)
