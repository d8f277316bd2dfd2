"""Joint reactions and drive torques in the first steps of a run (docs/accuracy.md, "The
first steps"): a rigid link driven through a cubic angle law under gravity, whose drive
torque has the closed form T = (I_c + m r^2) theta'' + m g r cos(theta).

Positions converge at order 2-3 from the first step, but the torque carries a transient of
first order in dt over the first ~20 steps (7.4e-5 of its peak at dt = 1e-4 s, rho_inf =
0.8), then second order. The transient comes from the constraint stabilization (omega =
stabilization / h), not from the generalized-alpha start: it stays with rho_inf = 1, where
the algorithmic acceleration starts exact, and vanishes with stabilization=0."""

import numpy as np
import pytest

import morphlab as ml

M, I_C, R, G = 2e-4, 0.5, 40.0, 9.81e3  # t, t mm^2, mm, mm/s^2
C2, C3, TH0 = 200.0, -3000.0, 0.3  # theta = TH0 + C2 t^2 + C3 t^3 [rad]
T_END = 0.02


def link():
    m = ml.Model(gravity=(0.0, -G), name="driven link")
    b = m.add_rigid_body(mass=M, inertia=I_C, position=(R * np.cos(TH0), R * np.sin(TH0)),
                         angle=TH0, name="link")
    m.add_revolute(m.ground, b, at=(0.0, 0.0), name="pin")
    m.add_drive(b, angle=ml.Polynomial([0.0, 0.0, C2, C3]), name="motor")
    return m


def exact_torque(t):
    th = TH0 + C2 * t**2 + C3 * t**3
    return (I_C + M * R * R) * (2 * C2 + 6 * C3 * t) + M * G * R * np.cos(th)


PEAK = np.max(np.abs(exact_torque(np.linspace(0.0, T_END, 2001))))


def errors(dt, **kw):
    """Largest torque error over the first 2 ms and after 10 ms, relative to the peak."""
    res = ml.simulate(link(), t_end=T_END, dt=dt, tol=1e-13, **kw)
    e = np.abs(res.drive_torque("motor") - exact_torque(res.t)) / PEAK
    return e[res.t <= 2e-3].max(), e[res.t >= 1e-2].max()


def order(f, dts=(2e-4, 1e-4, 5e-5), **kw):
    """Observed order of the early (0) or late (1) error over the step sizes."""
    e = [errors(dt, **kw)[f] for dt in dts]
    return np.polyfit(np.log(dts), np.log(e), 1)[0], e


@pytest.mark.xfail(strict=True, reason="first-order start-up transient of the multipliers: "
                   "the stabilization (omega = stabilization/h, in the kernels' residual) "
                   "turns the first steps' constraint residuals into O(h) accelerations; its "
                   "removal needs the core kernels (docs/accuracy.md)")
def test_reactions_are_second_order_from_the_first_step():
    """What issue 38 asks: the early torque error of order 2. Observed: 1.00."""
    p, _ = order(0)
    assert p > 1.8


def test_the_start_up_transient_has_the_documented_size_and_order():
    """Early error 7.4e-5 of the peak at dt = 1e-4 (rho_inf 0.8), halving with dt (order
    1.0), 2.0e-4 at rho_inf 0.5; after it, order 2. The numbers of docs/accuracy.md, with
    10 % margin."""
    p, e = order(0)
    assert 0.9 < p < 1.1 and e[1] < 8.2e-5
    p_late, _ = order(1)
    assert p_late > 1.8
    assert errors(1e-4, rho_inf=0.5)[0] < 2.2e-4
    # rho_inf = 1: no numerical damping and g0 = a0 exact; the transient stays
    assert errors(1e-4, rho_inf=1.0)[0] > 1e-5


def test_without_stabilization_reactions_are_second_order_from_the_start():
    """The workaround for short runs: stabilization=0 removes the transient (early error
    3e-8 of the peak at dt = 2e-4, order 2), at the price of a position drift of second
    order instead of third."""
    p, e = order(0, stabilization=0.0)
    assert p > 1.8 and e[0] < 1e-7
