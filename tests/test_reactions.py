"""Joint reactions, drive torque and power, and the drives' work in the energy balance,
against closed forms (pendulum pin force, clamp moment, Coriolis force on a bead and the
torque that keeps its rod turning) and against the energy the mechanism stores."""

import numpy as np
import pytest
from models import (
    E_AL,
    RHO_AL,
    check_method_by_complex_step,
    inclined_slider_crank,
    straight_nodes,
    tip_loaded_cantilever,
)
from test_prismatic import bead_on_rotating_rod

import morphlab as ml


def test_pendulum_pin_force_is_mass_times_centripetal_plus_gravity():
    """A rigid pendulum released from the horizontal. At every step the pin's force on the
    bob is m a - m g with the step's own acceleration (Newton's law, to round-off). Against the
    closed form — along the rod, towards the pivot, m (omega² r + g cos(phi)), phi from the
    downward vertical — it differs by the integrator's error: second order (measured 5.7e-4,
    1.4e-4 N at dt = 5e-4, 2.5e-4 s: 7e-6 of m g; asserted order 2 +- 0.1 and 1e-5 m g). In
    the bob's frame (x along the rod, outwards) that force is the -x component."""
    g, mass, r = 9.81e3, 2e-3, 40.0
    errs = []
    for dt in (5e-4, 2.5e-4):
        m = ml.Model(gravity=(0.0, -g))
        bob = m.add_rigid_body(mass=mass, inertia=3.0, position=(r, 0.0), name="bob")
        m.add_revolute(m.ground, bob, at=(0.0, 0.0), name="pin")
        res = ml.simulate(m, t_end=0.3, dt=dt)
        R, _ = res.reference("bob")
        F = res.reaction("pin")
        np.testing.assert_allclose(F[:, :2], mass * (res.a[:, :2] - [0.0, -g]), rtol=0,
                                   atol=1e-13 * mass * g)
        assert np.all(F[:, 2] == 0.0)  # a revolute transmits no moment
        expected = mass * (res.v[:, 2]**2 * r + g * (-R[:, 1] / r))
        errs.append(np.abs(np.sum(F[:, :2] * (-R / r), axis=1) - expected).max())
        local = res.reaction("pin", frame="bob")
        assert np.abs(local[:, 0] + expected).max() < 2 * errs[-1]
        np.testing.assert_allclose(np.hypot(*local[:, :2].T), np.hypot(*F[:, :2].T),
                                   rtol=1e-12)
    assert np.log2(errs[0] / errs[1]) == pytest.approx(2.0, abs=0.1)
    assert errs[1] < 1e-5 * mass * g
    # the same pin with its bodies swapped: the action of the bob on the ground
    m2 = ml.Model(gravity=(0.0, -g))
    bob2 = m2.add_rigid_body(mass=mass, inertia=3.0, position=(r, 0.0), name="bob")
    m2.add_revolute(bob2, m2.ground, at=(0.0, 0.0), name="pin")
    res2 = ml.simulate(m2, t_end=0.3, dt=2.5e-4)
    np.testing.assert_allclose(res2.reaction("pin"), -F, rtol=1e-9, atol=1e-12 * mass * g)


def test_clamp_reaction_of_a_cantilever_is_force_and_moment_of_the_tip_load():
    """Static cantilever of length L = 100 mm, tip force F down: the clamp holds the beam with
    +F up and the moment F x_tip, x_tip the deformed tip's lever arm (equilibrium of the whole
    beam about the clamp): L exactly with one linear frame held at the clamp, slightly less
    with a frame per element (the bent beam shortens); exact equilibrium of the discrete
    model, so to the Newton tolerance (1e-9 relative)."""
    F, L = 5.0, 100.0
    for frames, shortened in ((1, False), ("element", True)):
        res = ml.static(tip_loaded_cantilever({"t": 2.0, "F": F}, length=L, frames=frames),
                        t=1.0)
        clamp = res.reaction("clamp")[-1]
        x_tip = res.node_positions("beam")[-1, -1, 0]
        assert (x_tip < L - 1e-3) if shortened else x_tip == pytest.approx(L, rel=1e-12)
        np.testing.assert_allclose(clamp, [0.0, F, F * x_tip], rtol=1e-9, atol=1e-9 * F)


def test_bead_reaction_is_the_coriolis_force_and_the_drive_torque_its_moment():
    """Bead on a rod turning at a constant rate omega (no gravity). At every step, to
    round-off: the guide's force on the bead is m a (the only force on it), and the drive's
    torque is the rate of angular momentum about the pivot, I_rod a_rod + I_bead a_bead +
    m (x a_y - y a_x) (the pivot's force has no moment there). Against the closed forms
    r = r0 cosh(omega t), N = 2 m omega r' sideways (Coriolis; no moment: the bead turns
    steadily) and torque 2 m omega r r', the integrator's error: (omega dt)² = 1e-5 relative
    at dt = 1e-4 s (asserted 3e-5); the drive's power is its torque times omega."""
    omega, r0, mass = 30.0, 10.0, 1e-4
    model = bead_on_rotating_rod(omega, r0)
    res = ml.simulate(model, t_end=0.1, dt=1e-4, rho_inf=1.0)
    bead, rod = res.system.body("bead").ref, res.system.body("rod").ref
    N = res.reaction("slide")
    scale = 2 * mass * omega**2 * r0 * np.sinh(omega * 0.1)
    np.testing.assert_allclose(N[:, :2], mass * res.a[:, bead[:2]], rtol=0, atol=1e-12 * scale)
    x, y = res.q[:, bead[0]], res.q[:, bead[1]]
    dH = (model.body("rod").inertia * res.a[:, rod[2]]
          + model.body("bead").inertia * res.a[:, bead[2]]
          + mass * (x * res.a[:, bead[1]] - y * res.a[:, bead[0]]))
    torque = res.drive_torque("motor")
    np.testing.assert_allclose(torque, dH, rtol=0, atol=1e-12 * scale * r0)
    # closed forms
    wt = omega * res.t
    local = res.reaction("slide", frame="rod")
    N_exact = 2 * mass * omega * r0 * omega * np.sinh(wt)
    assert np.abs(local[:, 1] - N_exact).max() < 3e-5 * scale
    assert np.abs(local[:, 0]).max() < 3e-5 * scale
    # the moment turns the bead: I a_bead, which the drive keeps at zero to Newton's tolerance
    assert np.abs(local[:, 2]).max() < 1e-9 * scale * r0
    T_exact = 2 * mass * omega * r0**2 * omega * np.cosh(wt) * np.sinh(wt)
    assert np.abs(torque - T_exact).max() < 3e-5 * T_exact.max()
    np.testing.assert_allclose(res.drive_power("motor"), torque * omega, rtol=1e-9)


def _driven_flexible_crank(n_elem=4):
    """A rigid crank driven from rest to 60 rad/s, a flexible rod pinned to it and to a
    slider on a ground guide: the drive's work goes into kinetic and strain energy."""
    m = ml.Model(name="flexible slider-crank")
    r, l = 15.0, 60.0
    crank = m.add_rigid_body(mass=2e-4, inertia=10.0, position=(r / 2, 0.0), name="crank")
    rod = m.add_beam(straight_nodes(n_elem, l, origin=(r, 0.0)), E=E_AL, rho=RHO_AL,
                     thickness=1.5, width=8.0, name="rod")
    slider = m.add_rigid_body(mass=5e-4, inertia=1.0, position=(r + l, 0.0), name="slider")
    m.add_revolute(m.ground, crank, at=(0.0, 0.0), name="O")
    m.add_revolute(crank, rod, at=(r, 0.0), name="A")
    m.add_revolute(rod, slider, at=(r + l, 0.0), name="B")
    m.add_prismatic(m.ground, slider, at=(r + l, 0.0), axis=(1.0, 0.0), name="guide")
    # 60 (t - T/pi sin(pi t/T)/... ): from rest, speed 60 rad/s after T, smooth
    T, w = 0.02, 60.0
    k = np.pi / T
    m.add_drive(crank, angle=ml.Custom(
        lambda t: w * (t - np.sin(k * t) / k) / 2 if t < T else w * (t - T / 2),
        lambda t: w * (1 - np.cos(k * t)) / 2 if t < T else w,
        lambda t: w * k * np.sin(k * t) / 2 if t < T else 0.0), name="motor")
    return m


def test_drive_work_is_the_stored_energy_to_second_order():
    """Flexible slider-crank started from rest by its motor, no damping, rho_inf = 1 (no
    numerical dissipation): the motor's work equals kinetic + strain energy up to the
    integrator's error, which falls as dt² (measured 2.5e-4, 6.1e-5, 1.5e-5 of the work at
    dt = 4e-4, 2e-4, 1e-4 s, orders 2.00; asserted order 2 +- 0.1 and 3e-5)."""
    errs = []
    for dt in (4e-4, 2e-4, 1e-4):
        res = ml.simulate(_driven_flexible_crank(), t_end=0.04, dt=dt, rho_inf=1.0)
        e = res.energy
        assert np.all(e["load_work"] == 0.0)
        np.testing.assert_allclose(e["drive_work"], e["work"])
        work = e["drive_work"][-1]
        errs.append(np.abs(e["total"] - e["total"][0] - e["work"]).max() / work)
    orders = np.log2(np.array(errs[:-1]) / np.array(errs[1:]))
    assert np.all(np.abs(orders - 2.0) < 0.1), (errs, orders)
    assert errs[-1] < 3e-5


def test_reactions_of_a_saved_run(tmp_path):
    """A run read back from its file (whose model keeps its bodies only) gives the same
    reactions, drive torque and energy: they read the System's arrays alone."""
    res = ml.simulate(bead_on_rotating_rod(), t_end=0.02, dt=1e-3)
    path = tmp_path / "bead.npz"
    ml.io.save(res, path)
    back = ml.io.load(path)
    for name in ("slide", "pivot", "motor"):
        np.testing.assert_array_equal(back.reaction(name, frame="rod"),
                                      res.reaction(name, frame="rod"))
    np.testing.assert_array_equal(back.drive_power("motor"), res.drive_power("motor"))
    np.testing.assert_array_equal(back.energy["drive_work"], res.energy["drive_work"])


def test_reaction_errors_name_the_joint():
    m = ml.Model()
    b = m.add_rigid_body(mass=1.0, inertia=1.0, position=(1.0, 0.0), name="b")
    m.add_revolute(m.ground, b, at=(0.0, 0.0), name="pin")
    res = ml.simulate(m, t_end=0.01, dt=1e-3)
    with pytest.raises(ml.ModelError, match="no joint 'pn'.*'pin'"):
        res.reaction("pn")
    with pytest.raises(ml.ModelError, match="joint 'pin' is not a drive"):
        res.drive_torque("pin")


def _inclined_slider_crank(p):
    """The shared slider-crank (``models.inclined_slider_crank``): rod 50 mm, crank at 0.5 rad,
    driven to 30 rad/s."""
    return inclined_slider_crank(p)


@pytest.mark.parametrize("method", ["direct", "adjoint"])
def test_reaction_responses_have_exact_design_gradients(method):
    """Reaction responses (the guide's normal force in the slider's frame, the motor torque,
    a pin force in the crank's frame) differentiated through the guide angle (which moves
    the slide row's normal: the ``con_u0`` data), the slider mass and the crank radius agree
    with whole-run complex step to 1e-8 of the largest gradient (both exact; the residual
    difference is the Newton tolerance's)."""
    from morphlab.results import responses as rs

    p0 = {"alpha": 0.4, "m": 3e-4, "r": 20.0}
    resp = {"N": rs.reaction("guide", 1, time_index=-1, frame="slider"),
            "T": rs.reaction("motor", 2, time_index=-1),
            "A": rs.reaction("A", 0, time_index=12, frame="crank")}
    run = dict(t_end=0.03, dt=1e-3, tol=1e-12)
    check_method_by_complex_step(_inclined_slider_crank, p0, resp, method, run)
