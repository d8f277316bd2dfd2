"""A four-bar started at speed by a speed drive: the initial velocities computed at compile time
satisfy the velocity-level constraints to round-off, match the closed-form velocity analysis,
and the run follows the closed-form kinematics from the first step (no start-up transient)."""

import numpy as np
import pytest

import morphlab as ml
from morphlab.errors import ModelError
from tests.models import flexible_mechanism

A, B_LEN, C_LEN, D = 20.0, 60.0, 50.0, 55.0  # crank, coupler, rocker, ground link [mm]
OMEGA = 10.0  # crank speed [rad/s]


def _closed_form(theta2):
    """Rocker and coupler angles of the four-bar (A at the origin, D at (D, 0)) and their rates
    for a crank at ``theta2`` turning at OMEGA (loop closure and its time derivative)."""
    Bp = A * np.array([np.cos(theta2), np.sin(theta2)])
    Dp = np.array([D, 0.0])
    dist = np.linalg.norm(Dp - Bp)
    # C: intersection of circles around B (coupler) and D (rocker), upper branch
    x = (dist**2 + B_LEN**2 - C_LEN**2) / (2 * dist)
    h = np.sqrt(B_LEN**2 - x**2)
    e = (Dp - Bp) / dist
    C = Bp + x * e + h * np.array([-e[1], e[0]])
    th3 = np.arctan2(*(C - Bp)[::-1])
    th4 = np.arctan2(*(C - Dp)[::-1])
    # a w2 e(th2) + b w3 e(th3) = c w4 e(th4), e(th) = (-sin, cos)
    M = np.array([[-B_LEN * np.sin(th3), C_LEN * np.sin(th4)],
                  [B_LEN * np.cos(th3), -C_LEN * np.cos(th4)]])
    rhs = -A * OMEGA * np.array([-np.sin(theta2), np.cos(theta2)])
    w3, w4 = np.linalg.solve(M, rhs)
    return C, th3, th4, w3, w4


def rigid_four_bar(speed=OMEGA):
    th2 = np.pi / 2
    C, th3, th4, _, _ = _closed_form(th2)
    Bp = A * np.array([np.cos(th2), np.sin(th2)])
    m = ml.Model(gravity=(0.0, 0.0), name="four-bar")
    crank = m.add_rigid_body(mass=1e-4, inertia=0.02, position=tuple(Bp / 2), angle=th2,
                             name="crank")
    coupler = m.add_rigid_body(mass=3e-4, inertia=0.1, position=tuple((Bp + C) / 2),
                               angle=th3, name="coupler")
    rocker = m.add_rigid_body(mass=2e-4, inertia=0.05, position=tuple((C + [D, 0.0]) / 2),
                              angle=th4, name="rocker")
    m.add_revolute(m.ground, crank, at=(0.0, 0.0), name="A")
    m.add_revolute(crank, coupler, at=tuple(Bp), name="B")
    m.add_revolute(coupler, rocker, at=tuple(C), name="C")
    m.add_revolute(rocker, m.ground, at=(D, 0.0), name="D")
    m.add_drive(crank, speed=speed, name="motor")
    return m


def test_initial_velocities_match_the_velocity_analysis():
    """v0 of every frame against the closed form (both are exact: tolerance round-off of a
    9x9 solve with entries ~60, 1e-12 relative)."""
    system = ml.compile_model(rigid_four_bar())
    _, th3, th4, w3, w4 = _closed_form(np.pi / 2)
    v = dict(zip(system.dof_names, system.v0))
    assert v["crank.theta"] == pytest.approx(OMEGA, rel=1e-12)
    assert v["coupler.theta"] == pytest.approx(w3, rel=1e-12)
    assert v["rocker.theta"] == pytest.approx(w4, rel=1e-12)
    # the rocker's centre moves on its circle about D: speed |w4| c/2
    assert np.hypot(v["rocker.x"], v["rocker.y"]) == pytest.approx(abs(w4) * C_LEN / 2,
                                                                   rel=1e-12)
    _, phid = system.constraint_violation(system.q0, system.v0, 0.0)
    assert np.max(np.abs(phid)) < 1e-12 * OMEGA * B_LEN


def test_run_at_speed_follows_the_kinematics_from_the_first_step():
    """Generalized-alpha (rho_inf 0.9, h = 1 ms) against the closed-form rocker angle: a global
    error O(h²) (~1e-7 rad here) from the first step on, while the same run started at rest
    (``v0=0``, the drive then jerks the mechanism) is off by ~h·|w4| = 2.5e-3 rad after one
    step. Velocity constraint violation at t = 0 is round-off (1e-12 of w·L)."""
    res = ml.simulate(rigid_four_bar(), t_end=0.1, dt=1e-3, rho_inf=0.9)
    assert res.velocity_violation[0] < 1e-12 * OMEGA * B_LEN
    _, th4 = res.reference("rocker")
    ref = np.array([_closed_form(np.pi / 2 + OMEGA * t)[2] for t in res.t])
    err = np.abs(th4 - ref)
    assert err.max() < 1e-6
    w4 = np.array([_closed_form(np.pi / 2 + OMEGA * t)[4] for t in res.t])
    assert np.abs(res.v[:, res.system.dof_names.index("rocker.theta")] - w4)[:5].max() \
        < 1e-4 * abs(w4[0])
    jerked = ml.simulate(rigid_four_bar(), t_end=0.005, dt=1e-3, rho_inf=0.9,
                         v0=np.zeros(res.system.n_dof))
    assert abs(jerked.reference("rocker")[1][1] - ref[1]) > 1e-3


def test_flexible_four_bar_starts_with_rigid_frames():
    """The paper-like mechanism (rigid crank, flexible coupler beam, rigid rocker) driven at
    speed: the beam's elastic rates start at zero, the rocker turns at the rigid-body rate
    given by the frames' geometry, and the velocity constraints hold to round-off."""
    m = flexible_mechanism(gravity=(0.0, 0.0))
    m.add_drive(m.body("crank"), speed=OMEGA, name="motor")
    system = ml.compile_model(m)
    _, phid = system.constraint_violation(system.q0, system.v0, 0.0)
    assert np.max(np.abs(phid)) < 1e-12 * OMEGA * 60.0
    info = system.body("coupler")
    flex = info.node_dofs[info.node_dofs >= 0]
    assert np.all(system.v0[flex] == 0.0)
    assert system.v0[system.body("crank").ref[2]] == pytest.approx(OMEGA, rel=1e-12)


def test_given_inconsistent_velocities_are_still_refused():
    """A model that gives velocities keeps them: they must be consistent (no silent fix)."""
    m = rigid_four_bar()
    m.body("coupler").angular_velocity = 1.0
    with pytest.raises(ModelError, match="initial velocities violate"):
        ml.compile_model(m)


def test_drive_at_rest_keeps_zero_velocities():
    system = ml.compile_model(rigid_four_bar(speed=OMEGA * ml.SmoothStep(0.0, 0.05)))
    assert np.all(system.v0 == 0.0)


def test_sensitivity_to_the_drive_speed_goes_through_the_initial_velocities():
    """d(rocker angle at t_end)/d(speed): the initial velocities depend on the speed, and the
    direct method (dv0 by complex step through compile) agrees with the whole-run complex step
    (both exact: 1e-9 relative) and with the closed-form kinematics (d th4/d w = t_end ·
    d th4/d th2 = t_end w4/w; integrator error O(h²))."""
    resp = {"rocker": lambda r: r.reference("rocker")[1][-1]}
    kw = dict(t_end=0.02, dt=1e-3, rho_inf=0.9)
    build = lambda p: rigid_four_bar(speed=p["w"])  # noqa: E731
    direct = ml.sensitivities(build, {"w": OMEGA}, resp, method="direct", **kw)
    cs = ml.sensitivities(build, {"w": OMEGA}, resp, method="complex-step", **kw)
    g = direct.gradients["rocker"]["w"]
    assert g == pytest.approx(cs.gradients["rocker"]["w"], rel=1e-9)
    w4 = _closed_form(np.pi / 2 + OMEGA * 0.02)[4]
    assert g == pytest.approx(0.02 * w4 / OMEGA, rel=2e-5)  # O(h²): 4e-6 at h = 1 ms


def _refuse(*args, **kwargs):
    raise AssertionError("a constraint kernel ran")


def test_the_need_for_initial_velocities_is_read_from_the_rates_at_the_start(monkeypatch):
    """At ``q' = 0`` a row's velocity-level violation is minus its target's rate, so whether a
    model needs initial velocities is read from its time values at ``t = 0``. It agrees with
    the violation the constraint kernels give (a drive at speed, one that starts at rest, one
    at a speed of zero) and runs no constraint kernel (a complex-step perturbed design
    compiles none for it)."""
    from morphlab.compile import initial
    from morphlab.kernels import joints, slides

    cases = {"at speed": OMEGA, "from rest": OMEGA * ml.SmoothStep(0.0, 0.05), "zero": 0.0}
    for name, speed in cases.items():
        system = ml.compile_model(rigid_four_bar(speed=speed))
        system.v0 = np.zeros_like(system.v0)  # as before the compile gave them
        _, phid = system.constraint_violation(system.q0, np.zeros_like(system.q0), 0.0)
        with monkeypatch.context() as mp:
            mp.setattr(joints, "values", _refuse)
            mp.setattr(slides, "values", _refuse)
            assert initial.needs_initial_velocities(system) == bool(np.any(phid != 0)), name
    # velocities given (here the compile's own): none asked for
    assert not initial.needs_initial_velocities(ml.compile_model(rigid_four_bar()))


def test_a_drive_speed_of_zero_as_the_variable_starts_the_derivatives_moving():
    """At a speed of zero the nominal starts at rest, but its initial velocities' derivative in
    the speed is not zero: the perturbed design's rate at the start is zero in its real part
    only, and the direct method must take the velocities of the perturbed design. The crank
    then turns by ``w t``, so d(rocker angle at t_end)/d(speed) is t_end times the four-bar's
    velocity ratio ``w4 / w`` at the start (closed form). The kinematics are linear in ``t``
    here (the crank's angle, the rocker's through the fixed ratio), which the integrator
    follows exactly: the gradient agrees with the closed form and with the whole-run complex
    step to round-off (measured 3e-16 relative to both; asserted 1e-9)."""
    resp = {"rocker": lambda r: r.reference("rocker")[1][-1]}
    kw = dict(t_end=0.02, dt=1e-3, rho_inf=0.9)
    build = lambda p: rigid_four_bar(speed=p["w"])  # noqa: E731
    direct = ml.sensitivities(build, {"w": 0.0}, resp, method="direct", **kw)
    cs = ml.sensitivities(build, {"w": 0.0}, resp, method="complex-step", **kw)
    g = direct.gradients["rocker"]["w"]
    assert g == pytest.approx(cs.gradients["rocker"]["w"], rel=1e-9)
    assert g == pytest.approx(0.02 * _closed_form(np.pi / 2)[4] / OMEGA, rel=1e-9)
