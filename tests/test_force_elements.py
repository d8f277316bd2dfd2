"""Force elements (docs/theory.md §4.6): translational and rotational spring-dampers and line
loads on beams.

Each piece is checked against something independent: the Newton-matrix terms against
complex-step columns of the step residual; the spring-mass, damped and torsional oscillators
against their closed-form motions; the line load's integrals against Gauss quadrature of the
shape functions, its cantilever against beam theory and, on a tilted multi-frame beam, against
the gravity code (which forms the same generalized forces independently); the energy balance
with spring potential and damper dissipation; the sensitivities of every new design datum by
the direct and adjoint methods against the whole-run complex step.
"""

import numpy as np
import pytest
from models import (
    E_AL,
    RHO_AL,
    check_gradients_by_complex_step,
    check_step_matrix_by_complex_step,
    straight_nodes,
)

import morphlab as ml
from morphlab.compile import beam as kbeam
from morphlab.compile.forces import line_integrals


# ------------------------------------------------------------------ Newton-matrix terms
def _element_models():
    """Every kind of end: a spring between a rigid body and the ground, between a rigid body
    and a beam node, between two nodes of one beam in different frames and in one frame (the
    frame angle is shared by both ends); rotational springs across a beam-rigid revolute, from
    a rigid body to the ground and between two beam nodes; a line load on some elements of a
    two-frame beam and one on a single-frame beam. Damping and preload everywhere, so every
    term shows."""
    m = ml.Model(gravity=(0.0, -9.81e3), name="springs")
    nodes = straight_nodes(4, length=80.0, angle=0.3)
    beam = m.add_beam(nodes, E=E_AL, rho=RHO_AL, thickness=2.0, width=10.0, frames=2,
                      name="beam")
    body = m.add_rigid_body(mass=1e-4, inertia=0.1, position=(30.0, 40.0), angle=0.2,
                            name="body")
    m.add_revolute(m.ground, beam, at=(0.0, 0.0), name="pin")
    m.add_revolute(beam, body, at=tuple(nodes[4]), name="tip")
    m.add_spring("ground", body, m.ground, at_a=(35.0, 45.0), at_b=(50.0, 60.0),
                 stiffness=3.0, damping=0.02, rest_length=15.0, preload=1.5)
    m.add_spring("body-node", body, beam, at_a=(25.0, 38.0), at_b=tuple(nodes[1]),
                 stiffness=2.0, damping=0.01, preload=-0.7)
    m.add_spring("two-frames", beam, beam, at_a=tuple(nodes[1]), at_b=tuple(nodes[3]),
                 stiffness=5.0, damping=0.03, rest_length=30.0)
    m.add_spring("one-frame", beam, beam, at_a=tuple(nodes[0]), at_b=tuple(nodes[1]),
                 stiffness=4.0, damping=0.05, rest_length=21.0, preload=0.3)
    m.add_rotational_spring("hinge", "tip", stiffness=50.0, damping=0.5, rest_angle=0.1,
                            preload=2.0)
    m.add_rotational_spring("body-ground", (body, m.ground), stiffness=20.0, damping=0.2)
    m.add_rotational_spring("nodes", (beam, beam), at_a=tuple(nodes[1]), at_b=tuple(nodes[3]),
                            stiffness=30.0, damping=0.1, preload=-1.0)
    m.add_line_load("wind", beam, q=(0.02, -0.05), elements=[1, 2], profile=0.8)
    m2 = ml.Model(gravity=(0.0, 0.0), name="line load")
    nodes = straight_nodes(3, length=60.0, angle=-0.5, origin=(5.0, 5.0))
    beam = m2.add_beam(nodes, E=E_AL, rho=RHO_AL, thickness=2.0, width=10.0, frames=1,
                       reference="first", name="beam")
    m2.add_revolute(m2.ground, beam, at=(5.0, 5.0))
    m2.add_line_load("q", beam, q=(-0.03, 0.07))
    return [m, m2]


@pytest.mark.parametrize("model", _element_models(), ids=lambda m: m.name)
def test_newton_matrix_is_the_complex_step_of_the_residual(model):
    """Every column of the step matrix equals the complex-step derivative of the step
    residual (h = 1e-30: no truncation or cancellation error, so agreement to round-off; 1e-9
    of the column's largest entry asserted) at a random state far from any solution: nonzero
    velocities and accelerations, so the stiffness, geometric (f d²l/dq²), damping (c grad l
    (H q')^T and gh c grad l grad l^T) and line-load terms all show."""
    check_step_matrix_by_complex_step(model, seed=7)


def test_line_integrals_equal_gauss_quadrature_of_the_shape_functions():
    """``int ds``, ``int u0 ds`` and ``int S_e ds`` in closed form against the 4-point Gauss
    rule applied to the kernel's own shape matrix (exact for these cubics: round-off)."""
    X1, X2 = np.array([3.0, -2.0]), np.array([10.0, 5.0])
    u0, N = line_integrals(X1, X2)
    L, c, s = kbeam.element_geometry(X1, X2)
    S = np.zeros((2, 6))
    ref_N, ref_u = np.zeros((2, 6)), np.zeros(2)
    for xi, wt in zip(kbeam.GAUSS_XI, kbeam.GAUSS_W):
        kbeam.shape_matrix(xi, L, c, s, S)
        ref_N += wt * L * S
        ref_u += wt * L * ((1 - xi) * X1 + xi * X2)
    np.testing.assert_allclose(N, ref_N, rtol=0, atol=1e-13 * L * L)
    np.testing.assert_allclose(u0, [L, *ref_u], rtol=1e-14)


# ------------------------------------------------------------------ closed-form motions
M_KG, K_SPRING = 1e-3, 10.0  # 1 kg on 10 N/mm: omega = 100 rad/s


def _oscillator(damping=0.0, preload=0.0, rest=40.0, x0=50.0):
    """A rigid mass on a spring along x from the ground at the origin (no gravity): it moves
    along the spring's line only, so ``l = x`` and the motion is the linear oscillator's."""
    m = ml.Model(name="oscillator")
    mass = m.add_rigid_body(mass=M_KG, inertia=1.0, position=(x0, 0.0), name="mass")
    m.add_spring("s", mass, m.ground, at_a=(x0, 0.0), at_b=(0.0, 0.0), stiffness=K_SPRING,
                 damping=damping, rest_length=rest, preload=preload)
    return m


def test_spring_mass_frequency_and_preload_offset():
    """x(t) = x_eq + (x0 - x_eq) cos(omega t), omega = sqrt(k/m), x_eq = l0 - f0/k (the
    preload shifts the centre of the oscillation). At rho_inf = 1 the scheme is the
    trapezoidal rule, whose phase error is O((omega h)^2): measured 2.97e-2 / 7.4e-3 mm
    (amplitude 12 mm) at 80 / 160 steps per period, ratio 4.00; asserted: error below 1e-3
    of the amplitude at 160 steps and the ratio between 3.5 and 4.5 (second order)."""
    f0, rest, x0 = 20.0, 40.0, 50.0
    x_eq = rest - f0 / K_SPRING
    omega = np.sqrt(K_SPRING / M_KG)
    errs = []
    for n in (80, 160):
        period = 2 * np.pi / omega
        res = ml.simulate(_oscillator(preload=f0, rest=rest, x0=x0), t_end=period,
                          dt=period / n, rho_inf=1.0)
        exact = x_eq + (x0 - x_eq) * np.cos(omega * res.t)
        errs.append(np.abs(res.dof("mass.x") - exact).max())
        assert np.abs(res.dof("mass.y")).max() < 1e-12
        spring = res.spring("s")  # the tension k (x - l0) + f0, x the length here
        np.testing.assert_allclose(spring["force"], K_SPRING * (res.dof("mass.x") - rest) + f0,
                                   rtol=1e-12, atol=1e-12 * f0)
    assert errs[1] < 1e-3 * (x0 - x_eq)
    assert 3.5 < errs[0] / errs[1] < 4.5, errs


def test_damped_oscillator_logarithmic_decrement():
    """Log decrement of successive maxima ``2 pi zeta / sqrt(1 - zeta^2)`` with
    ``zeta = c / (2 sqrt(k m))`` (here 0.05: 0.3146), the maxima located by a parabola
    through the three samples around each; the whole motion against the closed form
    ``x_eq + A e^(-zeta omega t) (cos omega_d t + zeta/sqrt(1-zeta^2) sin omega_d t)``.
    At 400 steps per period the measured decrement is within 4.1e-5 relative (the peaks'
    interpolation and the scheme's period error) and the motion within 1.5e-4 of the
    amplitude; asserted 1e-4 and 5e-4."""
    zeta = 0.05
    c = 2 * zeta * np.sqrt(K_SPRING * M_KG)
    omega = np.sqrt(K_SPRING / M_KG)
    wd = omega * np.sqrt(1 - zeta**2)
    period = 2 * np.pi / wd
    res = ml.simulate(_oscillator(damping=c), t_end=4 * period, dt=period / 400, rho_inf=1.0)
    x = res.dof("mass.x") - 40.0
    t = res.t
    exact = 10.0 * np.exp(-zeta * omega * t) * (np.cos(wd * t)
                                                + zeta / np.sqrt(1 - zeta**2) * np.sin(wd * t))
    assert np.abs(x - exact).max() < 5e-4 * 10.0
    i = np.flatnonzero((x[1:-1] > x[:-2]) & (x[1:-1] >= x[2:])) + 1
    peaks = []
    for k in i:
        a, b, cc = x[k - 1], x[k], x[k + 1]
        peaks.append(b + (a - cc) ** 2 / (8 * (2 * b - a - cc)))  # parabola's top
    assert len(peaks) >= 3
    delta = np.log(np.array(peaks[:-1]) / np.array(peaks[1:]))
    expected = 2 * np.pi * zeta / np.sqrt(1 - zeta**2)
    np.testing.assert_allclose(delta, expected, rtol=1e-4)


def test_rotational_spring_frequency_on_a_pinned_body():
    """A rigid body pinned at its centre of mass (no gravity), a torsion spring across the
    pin (side a the ground, side b the body: psi = -theta + theta0) relaxed at psi = 0.1, i.e.
    0.1 rad behind the start: theta = theta0 - 0.1 (1 - cos(omega t)),
    omega = sqrt(k / I). The trapezoidal rule lengthens the period by (omega h)^2 / 12, so
    after a time t the motion lags by at most A omega t (omega h)^2 / 12: measured 0.88 of
    that bound at 200 and 400 steps per period (9.1e-5 and 2.3e-5 rad); asserted: below the
    bound, and second order."""
    k, inertia, th0 = 40.0, 0.1, 0.4
    m = ml.Model(name="torsion")
    body = m.add_rigid_body(mass=1e-3, inertia=inertia, position=(10.0, 5.0), angle=th0,
                            name="disk")
    m.add_revolute(m.ground, body, at=(10.0, 5.0), name="pin")
    m.add_rotational_spring("spring", "pin", stiffness=k, rest_angle=0.1)
    omega = np.sqrt(k / inertia)
    period = 2 * np.pi / omega
    errs = []
    for n in (200, 400):
        res = ml.simulate(m, t_end=2 * period, dt=period / n, rho_inf=1.0)
        exact = th0 - 0.1 * (1 - np.cos(omega * res.t))
        errs.append(np.abs(res.dof("disk.theta") - exact).max())
        assert errs[-1] < 0.1 * omega * res.t[-1] * (omega * period / n) ** 2 / 12
    assert 3.5 < errs[0] / errs[1] < 4.5, errs


# ------------------------------------------------------------------ line loads
def _cantilever(q, n_elem=4, length=100.0, frames=1):
    m = ml.Model(name="cantilever")
    beam = m.add_beam(straight_nodes(n_elem, length), E=E_AL, rho=RHO_AL, thickness=2.0,
                      width=10.0, frames=frames, reference="first" if frames == 1 else "chord",
                      name="beam")
    m.add_fix(beam, at=(0.0, 0.0), dofs="xyr", name="clamp")
    m.add_line_load("q", beam, q=q)
    return m


def test_cantilever_under_a_uniform_line_load():
    """Linear FFRF with the frame held at the clamp is linear beam theory; the consistent
    (work-equivalent) load vector makes the Hermite element's nodal values exact: tip
    deflection q L^4 / (8 EI), tip rotation q L^3 / (6 EI), axial tip displacement
    p L^2 / (2 EA), to round-off for any mesh (measured <= 3e-14 relative on 1 and 4 elements;
    1e-9 asserted)."""
    qy, px, L = -2e-3, 0.5, 100.0
    EI = E_AL * 10.0 * 2.0**3 / 12
    EA = E_AL * 10.0 * 2.0
    for n_elem in (1, 4):
        res = ml.static(_cantilever((px, qy), n_elem=n_elem))
        v = res.dof(f"beam.node{n_elem}.v")[-1]
        phi = res.dof(f"beam.node{n_elem}.phi")[-1]
        u = res.dof(f"beam.node{n_elem}.u")[-1]
        np.testing.assert_allclose(v, qy * L**4 / (8 * EI), rtol=1e-9)
        np.testing.assert_allclose(phi, qy * L**3 / (6 * EI), rtol=1e-9)
        np.testing.assert_allclose(u, px * L**2 / (2 * EA), rtol=1e-9)


def _tilted(load: bool):
    """A beam of three frames tilted by 0.7 rad, pinned at one end, with an end mass: under
    gravity, or without gravity under the line load rho A g (and the end mass's weight as a
    point force)."""
    g = np.array([0.0, -9.81e3])
    m = ml.Model(gravity=(0.0, 0.0) if load else tuple(g), name="tilted")
    nodes = straight_nodes(6, length=90.0, angle=0.7, origin=(1.0, 2.0))
    beam = m.add_beam(nodes, E=E_AL, rho=RHO_AL, thickness=2.0, width=10.0, frames=3,
                      damping=1e-4, name="beam")
    m.add_revolute(m.ground, beam, at=(1.0, 2.0))
    tip = m.add_rigid_body(mass=2e-5, inertia=1e-3, position=tuple(nodes[-1]), name="tip")
    m.add_revolute(beam, tip, at=tuple(nodes[-1]))
    if load:
        m.add_line_load("weight", beam, q=tuple(RHO_AL * 20.0 * g))
        m.add_force(tip, at=tuple(nodes[-1]), force=tuple(2e-5 * g))
    return m


def test_line_load_equals_the_gravity_load_on_a_tilted_multiframe_beam():
    """Gravity's generalized forces on a beam (``Q_g`` of §2.7, from the body invariants) are
    those of the line load ``rho A g`` (§4.6, from the element integrals): two codes, the same
    numbers. The swinging pendulum's histories agree to round-off (measured 2e-19 of the
    motion; 1e-8 asserted, the Newton tolerance's order)."""
    a = ml.simulate(_tilted(False), t_end=0.02, dt=5e-4)
    b = ml.simulate(_tilted(True), t_end=0.02, dt=5e-4)
    scale = np.abs(a.q[-1] - a.q[0]).max()
    assert scale > 1.0  # it moves
    assert np.abs(a.q - b.q).max() < 1e-8 * scale


# ------------------------------------------------------------------ energy
def _spring_pendulum(h_frac=1.0):
    """A rigid pendulum under gravity with a translational spring-damper from its end to the
    ground and a torsion spring-damper across its pivot (nonlinear: the spring's direction
    and lever turn with the arm)."""
    m = ml.Model(gravity=(0.0, -9.81e3), name="spring pendulum")
    body = m.add_rigid_body(mass=1e-3, inertia=0.8, position=(20.0, 0.0), name="arm")
    m.add_revolute(m.ground, body, at=(0.0, 0.0), name="pivot")
    m.add_spring("s", body, m.ground, at_a=(40.0, 0.0), at_b=(40.0, 30.0), stiffness=0.5,
                 damping=2e-3, rest_length=20.0, preload=1.0)
    m.add_rotational_spring("r", "pivot", stiffness=100.0, damping=0.05)
    return m


def test_energy_of_an_undamped_spring_mass_is_conserved_to_round_off():
    """Linear and undamped at rho_inf = 1, the scheme is the trapezoidal rule, which
    conserves kinetic + spring energy exactly: the balance holds to round-off (measured 9e-15
    of the energy, 1e-12 asserted), and the spring energy is k x^2 / 2 + f0 x."""
    res = ml.simulate(_oscillator(preload=5.0), t_end=0.1, dt=5e-4, rho_inf=1.0)
    e = res.energy
    x = res.dof("mass.x") - 40.0
    np.testing.assert_allclose(e["spring"], 0.5 * K_SPRING * x**2 + 5.0 * x, rtol=1e-12)
    balance = e["total"] - e["work"] + e["damping"]
    assert np.abs(balance - balance[0]).max() < 1e-12 * e["spring"][0]


def test_energy_balance_of_a_damped_spring_pendulum_is_second_order():
    """Kinetic + gravity + spring - work + dissipated (springs' dampers) is constant up to the
    integrator's error and the trapezoidal quadrature of the dissipated power, both O(h^2):
    measured drift 1.08e-4 / 2.69e-5 N·mm at h = 1e-3 / 5e-4 s (ratio 4.00) against 0.60 N·mm
    dissipated; asserted: ratio between 3.5 and 4.5, and the dampers dissipating more than 10
    times the drift."""
    drift = []
    for dt in (1e-3, 5e-4):
        res = ml.simulate(_spring_pendulum(), t_end=0.3, dt=dt, rho_inf=1.0)
        e = res.energy
        assert np.abs(e["work"]).max() == 0.0
        balance = e["total"] + e["damping"]
        drift.append(np.abs(balance - balance[0]).max())
        assert e["damping"][-1] > 10 * drift[-1]
    assert 3.5 < drift[0] / drift[1] < 4.5, drift


def test_energy_balance_with_a_line_load_is_second_order():
    """A flexible beam pendulum (two frames) swung by a line load that ramps up, with spring-
    dampers: the line load's work enters ``load_work``; the balance error is O(h^2)
    (measured drift 4.8e-4 / 1.2e-4 of the 0.95 N·mm of work at h = 1e-3 / 5e-4 s, ratio
    4.01; asserted: the ratio between 3.5 and 4.5)."""
    def build():
        m = ml.Model(name="loaded beam")
        nodes = straight_nodes(4, length=60.0)
        beam = m.add_beam(nodes, E=E_AL, rho=RHO_AL, thickness=3.0, width=10.0, frames=2,
                          name="beam")
        m.add_revolute(m.ground, beam, at=(0.0, 0.0), name="pivot")
        m.add_line_load("q", beam, q=(0.0, -0.02), profile=ml.Ramp(0.0, 0.02))
        m.add_spring("s", beam, m.ground, at_a=tuple(nodes[-1]), at_b=(60.0, 40.0),
                     stiffness=0.2, damping=1e-3)
        m.add_rotational_spring("r", "pivot", stiffness=200.0, damping=0.02)
        return m

    drift = []
    for dt in (1e-3, 5e-4):
        res = ml.simulate(build(), t_end=0.1, dt=dt, rho_inf=1.0)
        e = res.energy
        assert e["load_work"][-1] > 0.0
        balance = e["total"] - e["work"] + e["damping"]
        drift.append(np.abs(balance - balance[0]).max() / e["load_work"][-1])
    assert 3.5 < drift[0] / drift[1] < 4.5, drift


# ------------------------------------------------------------------ sensitivities
P_FE = {"k": 0.5, "l0": 20.0, "c": 2e-3, "q": -0.02, "k_rot": 100.0, "f0": 1.0,
        "y_anchor": 10.0, "rest_rot": 0.05}
RUN = dict(t_end=0.03, dt=1e-3)


def _design(p):
    """A flexible pendulum (two frames) with an end mass, a spring-damper from the mass to
    the ground, a torsion spring across the pivot and a line load: every new design datum
    is a variable."""
    m = ml.Model(gravity=(0.0, -9.81e3), name="force elements")
    nodes = straight_nodes(4, length=60.0, angle=-0.3)
    beam = m.add_beam(nodes, E=E_AL, rho=RHO_AL, thickness=2.0, width=10.0, frames=2,
                      name="beam")
    m.add_revolute(m.ground, beam, at=(0.0, 0.0), name="pivot")
    tip = m.add_rigid_body(mass=1e-5, inertia=1e-3, position=tuple(nodes[-1]), name="tip")
    m.add_revolute(beam, tip, at=tuple(nodes[-1]), name="end")
    m.add_spring("s", tip, m.ground, at_a=tuple(nodes[-1]), at_b=(70.0, p["y_anchor"]),
                 stiffness=p["k"], damping=p["c"], rest_length=p["l0"], preload=p["f0"])
    m.add_rotational_spring("r", "pivot", stiffness=p["k_rot"], damping=0.01,
                            rest_angle=p["rest_rot"])
    m.add_line_load("q", beam, q=(0.0, p["q"]), elements=[1, 2, 3])
    return m


def test_sensitivities_of_the_force_elements_direct_adjoint_complex_step():
    """Stiffness, damping, rest length, preload and ground anchor of a spring, the stiffness
    and rest angle of a torsion spring and a line load's magnitude: the direct and the
    adjoint method equal the whole-run complex step to 1e-8 of each response's largest scaled
    gradient (p_i dpsi/dp_i; measured <= 6.5e-14), and each other to 1e-10 (the same
    recursion transposed; measured 7e-16). Every variable moves each response by more than
    1e-4 of the largest (measured >= 9.6e-3), so no comparison is vacuous."""
    nodes = straight_nodes(4, length=60.0, angle=-0.3)
    resp = {"tip_y": ml.responses.point_displacement("tip", tuple(nodes[-1]), 1),
            "node_x": ml.responses.point_displacement("beam", tuple(nodes[2]), 0)}
    check_gradients_by_complex_step(_design, P_FE, resp, RUN, cross=1e-10)


def test_a_spring_force_response_by_the_direct_method():
    """``Result.spring`` is complex-safe: a response reading the spring's force at the end
    of the run has direct-method gradients equal to the whole-run complex step (1e-8 of the
    largest scaled gradient, as above)."""
    resp = {"force": lambda r: r.spring("s")["force"][-1]}
    p0 = {k: P_FE[k] for k in ("k", "l0", "y_anchor", "q")}

    def build(p):
        return _design(dict(P_FE, **p))

    d = ml.sensitivities(build, p0, resp, method="direct", **RUN)
    cs = ml.sensitivities(build, p0, resp, method="complex-step", **RUN)
    largest = max(abs(p0[v] * cs.gradients["force"][v]) for v in p0)
    for v in p0:
        err = abs(p0[v] * (d.gradients["force"][v] - cs.gradients["force"][v]))
        assert err <= 1e-8 * largest, (v, err / largest)


# ------------------------------------------------------------------ bad input
def test_bad_input_is_refused_naming_the_element():
    m = ml.Model()
    body = m.add_rigid_body(mass=1.0, inertia=1.0, position=(0.0, 0.0), name="b")
    beam = m.add_beam(straight_nodes(2, 10.0, origin=(0.0, 5.0)), E=E_AL, rho=RHO_AL,
                      thickness=1.0, width=1.0, name="beam")
    m.add_fix(body, at=(0.0, 0.0), dofs="x", name="fx")
    with pytest.raises(ml.ModelError, match="spring 'neg'.*stiffness.*>= 0"):
        m.add_spring("neg", body, m.ground, at_a=(0, 0), at_b=(1, 0), stiffness=-1.0)
    with pytest.raises(ml.ModelError, match="spring 'd'.*damping"):
        m.add_spring("d", body, m.ground, at_a=(0, 0), at_b=(1, 0), stiffness=1.0, damping=-2)
    with pytest.raises(ml.ModelError, match="spring 'same'.*coincide"):
        m.add_spring("same", body, m.ground, at_a=(1, 1), at_b=(1, 1), stiffness=1.0)
    with pytest.raises(ml.ModelError, match="spring 'x'.*no body 'nobody'"):
        m.add_spring("x", "nobody", m.ground, at_a=(0, 0), at_b=(1, 0), stiffness=1.0)
    with pytest.raises(ml.ModelError, match="spring 'off'.*not at a node of beam 'beam'"):
        m.add_spring("off", beam, m.ground, at_a=(2.0, 5.0), at_b=(1, 0), stiffness=1.0)
    with pytest.raises(ml.ModelError, match="spring 'r'.*rest_length"):
        m.add_spring("r", body, m.ground, at_a=(0, 0), at_b=(1, 0), stiffness=1.0,
                     rest_length=-1.0)
    with pytest.raises(ml.ModelError, match="rotational spring 'j'.*'fx' is not a revolute"):
        m.add_rotational_spring("j", "fx", stiffness=1.0)
    with pytest.raises(ml.ModelError, match="rotational spring 'n'.*at_a.*node of beam"):
        m.add_rotational_spring("n", (beam, body), stiffness=1.0)
    with pytest.raises(ml.ModelError, match="line load 'q'.*elements.*0 to 1"):
        m.add_line_load("q", beam, q=(0, 1), elements=[2])
    with pytest.raises(ml.ModelError, match="line load 'b'.*acts on a beam"):
        m.add_line_load("b", body, q=(0, 1))
    with pytest.raises(ml.ModelError, match="line load 'nan'.*q"):
        m.add_line_load("nan", beam, q=(np.nan, 1))
    m.add_spring("ok", body, m.ground, at_a=(0, 0), at_b=(1, 0), stiffness=1.0)
    with pytest.raises(ml.ModelError, match="'ok' already exists"):
        m.add_line_load("ok", beam, q=(0, 1))
    assert len(m.springs) == 1 and not m.line_loads  # nothing half-added


def test_a_saved_result_keeps_the_force_elements(tmp_path):
    """The force elements live in the System arrays, which the result file stores: a loaded
    result has the same energy, spring potential included (bitwise)."""
    res = ml.simulate(_spring_pendulum(), t_end=0.01, dt=1e-3)
    ml.io.save(res, tmp_path / "run.npz")
    back = ml.io.load(tmp_path / "run.npz")
    for key, value in res.energy.items():
        np.testing.assert_array_equal(back.energy[key], value, err_msg=key)
