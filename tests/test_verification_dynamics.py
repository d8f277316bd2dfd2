"""Multibody dynamics (generalized-alpha + Newton) against independent references.

References
----------
* Rigid pendulum released from rest at ``theta0``: period
  ``T = 4 sqrt(I_O/(m g d)) K(k)``, ``k = sin(theta0/2)`` (complete elliptic integral of the first
  kind; the plane pendulum of Thornton & Marion, *Classical Dynamics*, §4.4, with ``l/g``
  replaced by ``I_O/(m g d)``; ``scipy.special.ellipk`` takes the parameter ``m = k²``).
* Slider-crank (crank ``r``, rod ``l``, slider on the line through the crank pivot): slider
  position ``x = r cos(phi) + sqrt(l² - r² sin²(phi))`` (loop closure).
* Trapezoidal rule (generalized-alpha with ``rho_inf = 1``: ``alpha_m = alpha_f = 1/2``,
  ``beta = 1/4``, ``gamma = 1/2``) on a linear oscillator of frequency ``omega``: the discrete
  solution oscillates exactly at ``omega_h = (2/h) arctan(omega h/2)`` (Hughes, *The Finite
  Element Method*, 1987, ch. 9), so its period error ~ ``(omega h)²/12``.
* Clamped-free beam: ``omega_1 = 1.8751² sqrt(EI/(rho A L⁴))``; the cubic Hermite element with
  consistent mass overestimates ``omega`` by ``(beta_1 h)⁴/1440`` (see test_verification_beam).
* Newton's method with the exact Jacobian: ``e_{k+1} <= C e_k²`` near the solution.
* A slowly loaded, damped mechanism comes to rest at the static equilibrium of the final loads
  (``ml.static``).

The first-order convergence of the paper's generalized-alpha weighting for ``rho_inf < 1`` on
constrained systems is documented in ``test_convergence_dt.py``.
"""

import numpy as np
from models import E_AL, RHO_AL, flexible_mechanism, straight_nodes
from scipy.linalg import eigh
from scipy.special import ellipk

import morphlab as ml

# ---------------------------------------------------------------------------------------------
# helpers


def zero_crossings(t, x, xd):
    """Times where ``x`` changes sign, from the cubic Hermite interpolant of ``(x, xd)`` on each
    step (interpolation error O(h⁴), below the O(h²) integration error we measure).

    Parameters
    ----------
    t, x, xd : (n_t,)
        Times, a signal and its time derivative.

    Returns
    -------
    (n_cross,) crossing times.
    """
    out = []
    for i in np.flatnonzero(x[:-1] * x[1:] < 0.0):
        h = t[i + 1] - t[i]
        p0, p1, m0, m1 = x[i], x[i + 1], xd[i] * h, xd[i + 1] * h
        roots = np.roots([2 * p0 - 2 * p1 + m0 + m1, -3 * p0 + 3 * p1 - 2 * m0 - m1, m0, p0])
        real = roots[np.abs(roots.imag) < 1e-9].real
        s = real[(real >= -1e-12) & (real <= 1.0 + 1e-12)]
        out.append(t[i] + h * s[np.argmin(np.abs(s - p0 / (p0 - p1)))])
    return np.array(out)


def pulse(t1):
    """Smooth load pulse: 0 -> 1 on [0, t1], 1 -> 0 on [t1, 2 t1], zero afterwards."""
    up, down = ml.SmoothStep(0.0, t1), ml.SmoothStep(t1, 2.0 * t1)
    return ml.Custom(lambda t: up(t) - down(t))


# ---------------------------------------------------------------------------------------------
# rigid pendulum: period at large amplitude

PEND_L, PEND_M, PEND_G = 1.0, 1.0, 9.81  # SI units (the library is unit-agnostic)


def rigid_pendulum(theta0):
    """Uniform bar (length PEND_L) pinned at one end to ground, released from rest at
    ``theta0`` from the downward vertical. Returns ``(model, exact period)``."""
    d = PEND_L / 2.0
    m = ml.Model(gravity=(0.0, -PEND_G), name="pendulum")
    bar = m.add_rigid_body(mass=PEND_M, inertia=PEND_M * PEND_L**2 / 12.0,
                           position=(d * np.sin(theta0), -d * np.cos(theta0)),
                           angle=theta0 - np.pi / 2, name="bar")
    m.add_revolute(m.ground, bar, at=(0.0, 0.0), name="O")
    I_O = PEND_M * PEND_L**2 / 3.0
    period = 4.0 * np.sqrt(I_O / (PEND_M * PEND_G * d)) * ellipk(np.sin(theta0 / 2.0) ** 2)
    return m, period


def pendulum_period(res):
    """Measured period: time between the 1st and 3rd zero crossing of the swing angle."""
    i = res.system.dof_names.index("bar.theta")
    swing = res.q[:, i] + np.pi / 2  # body angle - (-pi/2) = angle from the downward vertical
    c = zero_crossings(res.t, swing, res.v[:, i])
    return c[2] - c[0]


def test_rigid_pendulum_period_at_90_degrees():
    model, T = rigid_pendulum(np.pi / 2)  # T = 1.933335 s
    n = 200  # steps per period
    estimate = (2.0 * np.pi / n) ** 2 / 12.0  # trapezoidal period error of a linear oscillator
    bare = ml.simulate(model, t_end=1.3 * T, dt=T / n, rho_inf=1.0, stabilization=0.0)
    err = pendulum_period(bare) / T - 1.0
    # Observed err = 7.85e-5 = 0.955 estimate (8.22e-5); max |Phi| = 2.9e-4 m (unstabilised
    # drift, 1 m bar). The anharmonic pendulum at 90 deg has its own constant, not far from the
    # linear one: allow 0.5 to 1.5 times the estimate.
    assert 0.5 * estimate < err < 1.5 * estimate
    res = ml.simulate(model, t_end=1.3 * T, dt=T / n, rho_inf=1.0)  # default stabilization
    err = pendulum_period(res) / T - 1.0
    # Observed err = 2.05e-4 = 2.5 estimate; max |Phi| = 2.5e-5 m. The Baumgarte term raises
    # the error constant towards 3.8 times the unstabilised one (test_convergence_dt): bound 4.
    assert 0 < err < 4.0 * estimate
    assert res.constraint_violation.max() < 1e-4 * PEND_L


# ---------------------------------------------------------------------------------------------
# rigid slider-crank driven at constant speed

SC_R, SC_L, SC_OMEGA, SC_PHI0 = 20.0, 60.0, 2.0 * np.pi * 5.0, np.pi / 6  # mm, rad/s, rad


def slider_crank():
    """Crank (pivot at the origin, driven by ``ml.Linear``), rod and slider on the x axis, all
    rigid, with initial velocities consistent with the drive (the compiler checks them)."""
    r, l, w, p = SC_R, SC_L, SC_OMEGA, SC_PHI0
    B = r * np.array([np.cos(p), np.sin(p)])
    psi = -np.arcsin(r * np.sin(p) / l)  # rod angle
    C = np.array([B[0] + l * np.cos(psi), 0.0])
    psid = -r * np.cos(p) * w / (l * np.cos(psi))
    Bd = w * r * np.array([-np.sin(p), np.cos(p)])
    Cd = np.array([Bd[0] - l * np.sin(psi) * psid, 0.0])
    m = ml.Model(name="slider-crank")
    crank = m.add_rigid_body(mass=1e-4, inertia=1e-4 * r**2 / 12, position=tuple(B / 2),
                             angle=p, velocity=tuple(Bd / 2), angular_velocity=w, name="crank")
    rod = m.add_rigid_body(mass=2e-4, inertia=2e-4 * l**2 / 12, position=tuple((B + C) / 2),
                           angle=psi, velocity=tuple((Bd + Cd) / 2), angular_velocity=psid,
                           name="rod")
    slider = m.add_rigid_body(mass=3e-4, inertia=1e-2, position=tuple(C), velocity=tuple(Cd),
                              name="slider")
    m.add_revolute(m.ground, crank, at=(0.0, 0.0), name="O")
    m.add_revolute(crank, rod, at=tuple(B), name="B")
    m.add_revolute(rod, slider, at=tuple(C), name="C")
    m.add_fix(slider, at=tuple(C), dofs="yr", name="guide")
    m.add_drive(crank, angle=ml.Linear(w), name="motor")
    return m


def test_slider_crank_follows_closed_form_kinematics():
    T = 2.0 * np.pi / SC_OMEGA
    err, viol = [], []
    for n in (100, 200):  # steps per revolution, two revolutions
        res = ml.simulate(slider_crank(), t_end=2 * T, dt=T / n)
        phi = SC_PHI0 + SC_OMEGA * res.t
        # the drive row theta - theta0 - omega t is linear, and theta'' = 0 is integrated
        # exactly by the Newmark formulas: the crank angle is exact to round-off
        np.testing.assert_allclose(res.dof("crank.theta"), phi, rtol=0, atol=1e-12)
        x_exact = SC_R * np.cos(phi) + np.sqrt(SC_L**2 - (SC_R * np.sin(phi)) ** 2)
        err.append(np.max(np.abs(res.dof("slider.x") - x_exact)))
        viol.append(res.constraint_violation.max())
        # With the crank angle exact, the slider error comes from the joint gaps alone:
        # linearising the loop closure, x - x_exact = Phi_O.x - Phi_B.x - Phi_C.x
        # + tan(psi) (sum of four y rows), so |x - x_exact| <= (3 + 4 max|tan psi|) max|Phi|,
        # max|tan psi| = r/sqrt(l² - r²). Observed ratio 2.3; 5 % for the O(Phi²) remainder.
        kappa = 3.0 + 4.0 * SC_R / np.sqrt(SC_L**2 - SC_R**2)
        assert err[-1] <= 1.05 * kappa * viol[-1]
    # Observed (rho_inf 0.8, stabilization 0.5, "paper"): err = 2.9e-3, 3.7e-4 mm, max |Phi| =
    # 1.3e-3, 1.6e-4 mm at 100, 200 steps per revolution ("endpoint": 5.8e-3, 7.3e-4 mm; no
    # stabilization: 3.8e-2, 2.7e-2 mm "paper" and 1.9, 0.96 mm "endpoint" - the first-order
    # drift described in test_convergence_dt). Requirement: slider within 1e-4 r at 200 steps
    # per revolution, and the error falls at least at second order (observed 2.98).
    assert err[1] < 1e-4 * SC_R
    assert err[0] / err[1] > 2.0**2


# ---------------------------------------------------------------------------------------------
# cantilever free vibration after a force pulse

CL_L, CL_T, CL_B, CL_NE = 100.0, 2.0, 10.0, 4  # mm; 4 elements


def kicked_cantilever(t1):
    m = ml.Model(name="cantilever")
    nodes = straight_nodes(CL_NE, length=CL_L)
    # a single linear FFRF body clamped in its frame (the test reads its modal coordinate)
    beam = m.add_beam(nodes, E=E_AL, rho=RHO_AL, thickness=CL_T, width=CL_B, reference_node=0,
                      name="beam")
    m.add_fix(beam, at=(0.0, 0.0), dofs="xyr", name="clamp")
    m.add_force(beam, at=tuple(nodes[-1]), force=(0.0, 1.0), profile=pulse(t1), name="kick")
    return m


def flex_matrices(system):
    """Assembled M_ff, K_ff (n_f, n_f) of the only beam, from the element arrays."""
    El = system.arrays.elements
    nf = system.count("flex")
    M, K = np.zeros((nf, nf)), np.zeros((nf, nf))
    for e in range(El.fdof.shape[0]):
        fd = El.fdof[e]
        k = fd >= 0
        M[np.ix_(fd[k], fd[k])] += El.M[e][np.ix_(k, k)]
        K[np.ix_(fd[k], fd[k])] += El.K[e][np.ix_(k, k)]
    return M, K


def test_cantilever_free_vibration_at_first_eigenfrequency():
    EI = E_AL * CL_B * CL_T**3 / 12.0
    rhoA = RHO_AL * CL_B * CL_T
    beta1 = 1.8751040687  # root of cos(x) cosh(x) = -1
    w_exact = beta1**2 * np.sqrt(EI / (rhoA * CL_L**4))
    T1 = 2.0 * np.pi / w_exact  # 6.08 ms
    model = kicked_cantilever(t1=T1 / 4)
    system = ml.compile_model(model)
    M, K = flex_matrices(system)
    w2, V = eigh(K, M)
    w1, phi1 = np.sqrt(w2[0]), V[:, 0]  # phi1 M-orthonormal
    # FE model vs closed form: the Hermite element's error (beta1 h)^4/1440 = 3.35e-5 for
    # 4 elements (observed 3.27e-5); allow 1.5 times
    assert 0 < w1 / w_exact - 1.0 < 1.5 * (beta1 / CL_NE) ** 4 / 1440

    n = 100  # steps per period
    res = ml.simulate(system, t_end=6 * T1, dt=T1 / n, rho_inf=1.0)
    # modal coordinate eta_1 = phi1^T M q_f: the other modes are M-orthogonal to phi1, so eta_1
    # is a pure first-mode signal (the clamped beam's equations are linear: theta = const)
    fd = system.arrays.flex.dof
    eta, etad = res.q[:, fd] @ M @ phi1, res.v[:, fd] @ M @ phi1
    free = res.t > T1 / 2  # after the pulse
    c = zero_crossings(res.t[free], eta[free], etad[free])
    assert len(c) >= 10
    T_meas = 2.0 * np.polyfit(np.arange(len(c)), c, 1)[0]
    h = res.settings.h
    w_h = 2.0 / h * np.arctan(w1 * h / 2.0)  # exact discrete frequency of the trapezoidal rule
    # Observed T_meas * w_h/(2 pi) - 1 = -5e-8; max |Phi| = 1e-31 (clamp rows are linear).
    # What is left is the Hermite interpolation of the crossings: O((w h)⁴) ~ 1e-8 of T at 100
    # steps per period, plus the discrete velocities it uses, whose amplitude is w A, not
    # w_h A (a 3e-4 slope error at the crossing, second order in the root); bound 1e-6.
    assert abs(T_meas * w_h / (2 * np.pi) - 1.0) < 1e-6
    # and the familiar period elongation of the trapezoidal rule, (w h)²/12 (observed 3.29e-4)
    np.testing.assert_allclose(T_meas * w1 / (2 * np.pi) - 1.0, (w1 * h) ** 2 / 12, rtol=0.01)
    assert res.constraint_violation.max() < 1e-12 * CL_L


# ---------------------------------------------------------------------------------------------
# quadratic Newton convergence on the flexible four-bar


def newton_orders(res, floor=1e-15, start=1e-2):
    """``log(e_{k+1})/log(e_k)`` for consecutive Newton position corrections ``e`` (relative to
    the model size) with ``e_k < start`` (near the solution) and ``e_{k+1} > floor`` (above the
    round-off level, ~1e-17 here)."""
    out = []
    for hist in res.newton_history:
        e = np.array([c for _, c in hist])
        for k in range(len(e) - 1):
            if e[k] < start and e[k + 1] > floor:
                out.append(np.log(e[k + 1]) / np.log(e[k]))
    return np.array(out)


def test_newton_converges_quadratically_on_flexible_mechanism():
    # dt = 2 ms is large for this mechanism (4 iterations per step) and tol = 1e-14 lets
    # Newton run into the round-off floor, so that most steps give two or more corrections
    res = ml.simulate(flexible_mechanism(), t_end=0.1, dt=2e-3, tol=1e-14, max_iter=20)
    p = newton_orders(res)
    # The position correction is the dimensionless error measure (the residual norm mixes N,
    # N mm and scaled constraint rows, so its log-ratios depend on the units). Quadratic
    # convergence gives p = 2 + log(C)/log(e_k) -> 2; a Jacobian off by a relative 1e-2
    # gives e_{k+1} ~ 1e-2 e_k, i.e. p ~ 1 + 2/|log10 e_k| = 1.3 at e_k = 1e-6.
    # Observed: 67 values, median 1.99, min 1.53; max |Phi| 1.9e-4 mm (60 mm model).
    assert p.size >= 20
    assert np.median(p) > 1.8
    assert p.min() > 1.4


def test_newton_order_check_detects_an_inexact_jacobian(monkeypatch):
    """The same measure on a Newton matrix scaled by 1.01 (a 1 % Jacobian error): linear
    convergence at rate ~1e-2 must fail the test above. (The matrix is perturbed in
    ``StepProblem.fill``, which the compiled Newton loop bypasses, so the loop from Python is
    used.)"""
    from morphlab.solve.newton import StepProblem

    fill = StepProblem.fill

    def off_by_one_percent(self, z, data, W):
        fill(self, z, data, W)
        data *= 1.01

    monkeypatch.setattr(StepProblem, "fill", off_by_one_percent)
    res = ml.simulate(flexible_mechanism(), t_end=0.02, dt=2e-3, tol=1e-14, max_iter=40,
                      compiled_newton=False)
    p = newton_orders(res)
    assert np.median(p) < 1.5  # observed median 1.28 (7 iterations per step instead of 3-4)


# ---------------------------------------------------------------------------------------------
# slow load-controlled flexible mechanism ends at the static solution

LEVER_BETA = 3.5e-4  # s, stiffness-proportional damping of the skin


def lever_mechanism(t_ramp):
    """A clamped flexible 'skin' (4 elements) pushed at its tip by a link from a rigid crank
    that carries a torque ramped by SmoothStep(0, t_ramp); gravity on. A closed loop whose
    only stiffness is the skin's bending: first frequency ~591 rad/s."""
    m = ml.Model(gravity=(0.0, -9.81e3), name="lever")
    skin = m.add_beam(straight_nodes(4, length=100.0), E=E_AL, rho=RHO_AL, thickness=2.0,
                      width=10.0, damping=LEVER_BETA, name="skin")
    m.add_fix(skin, at=(0.0, 0.0), dofs="xyr", name="clamp")
    mass = 2e-6
    crank = m.add_rigid_body(mass=mass, inertia=mass * 20.0**2 / 12, position=(90.0, -30.0),
                             name="crank")
    link = m.add_rigid_body(mass=mass, inertia=mass * 30.0**2 / 12, position=(100.0, -15.0),
                            angle=np.pi / 2, name="link")
    m.add_revolute(m.ground, crank, at=(80.0, -30.0), name="A")
    m.add_revolute(crank, link, at=(100.0, -30.0), name="B")
    m.add_revolute(link, skin, at=(100.0, 0.0), name="C")
    m.add_torque(crank, 50.0, profile=ml.SmoothStep(0.0, t_ramp), name="Mt")
    return m


def test_slowly_loaded_mechanism_comes_to_rest_at_static_solution():
    t_ramp, t_end = 0.1, 0.2
    stat = ml.static(lever_mechanism(t_ramp), t=t_end, steps=2)
    dyn = ml.simulate(lever_mechanism(t_ramp), t_end=t_end, dt=1e-3)
    X_static = stat.node_positions("skin")[-1]
    deflection = np.max(np.abs(X_static - stat.node_positions("skin")[0]))  # 1.76 mm
    diff = np.max(np.abs(dyn.node_positions("skin")[-1] - X_static))
    # Reference error budget (first mode, omega ~ 591 rad/s, zeta = beta omega/2 = 0.10):
    # gravity, applied at t = 0 as a step, starts a vibration of ~0.036 mm that decays by
    # exp(-zeta omega t_end) = 5e-6; the quintic ramp leaves ~2 * 60/(omega t_ramp)³ = 6e-4 of
    # the deflection (1e-3 mm), decaying by exp(-zeta omega (t_end - t_ramp)) = 2e-3. Sum
    # ~2.4e-6 mm; bound 1e-5 mm. Observed 1.9e-7 mm; max |Phi| 1.8e-6 mm over the run.
    assert deflection > 1.0
    assert diff < 1e-5
    np.testing.assert_allclose(dyn.dof("crank.theta")[-1], stat.dof("crank.theta")[-1],
                               rtol=0, atol=1e-5 / 20.0)  # same 1e-5 mm at the 20 mm crank
    assert dyn.constraint_violation[-1] < 1e-9  # stabilised: Phi -> 0 at rest


# ---------------------------------------------------------------------------------------------
# constraint violation on a long run of the closed loop

FB_OMEGA, FB_TAU = 30.0, 0.05  # rad/s, s


def driven_four_bar():
    """flexible_mechanism with its crank driven at FB_OMEGA (spun up from rest with time
    constant FB_TAU); its torque and point force stay, the drive reacts the torque.

    Left free, the constant torque spins the crank up without bound: near 70 rad/s the
    coupler's axial force reaches 3 EI/L² = 389 N, where the linear FFRF beam in its tangent
    frame diverges (no geometric stiffness), and Newton fails at t ~ 0.49 s."""
    w, tau = FB_OMEGA, FB_TAU
    spin = ml.Custom(lambda t: w * (t - tau * (1.0 - np.exp(-t / tau))),
                     lambda t: w * (1.0 - np.exp(-t / tau)),
                     lambda t: w / tau * np.exp(-t / tau))
    m = flexible_mechanism(reference_node=0)  # the single linear tangent frame
    m.add_drive(m.body("crank"), angle=spin, name="motor")
    return m


def first_and_last_tenth(res):
    """max |Phi| over the first and over the last tenth of the run."""
    n = res.n_t // 10
    return res.constraint_violation[:n].max(), res.constraint_violation[-n:].max()


def test_constraint_violation_stays_bounded_over_ten_revolutions():
    t_end = 10 * 2 * np.pi / FB_OMEGA  # ~9.8 crank revolutions (spin-up included)
    system = ml.compile_model(driven_four_bar())
    L = system.length_scale  # 59.7 mm
    res = ml.simulate(system, t_end=t_end, dt=1e-3)
    first, last = first_and_last_tenth(res)
    # Observed at dt = 1 ms, 2094 steps: max |Phi| = 5.74e-4 mm = 9.6e-6 L ("endpoint":
    # 9.4e-4 mm); at dt = 2 ms 4.0e-3 mm ("endpoint" 6.4e-3 mm). Without stabilization the
    # gap grows linearly: 2.3 mm (paper) / 2.9 mm (endpoint) after 10 revolutions at 1 ms, and
    # "endpoint" diverges at 2 ms.
    # Requirement: joint gaps below 1e-4 of the model size (6 micrometre) and no growth from
    # the first to the last revolution beyond 50 %.
    assert res.constraint_violation.max() < 1e-4 * L
    assert last < 1.5 * first
    # the same check on the unstabilised run fails: the growth test can fail
    raw = ml.simulate(system, t_end=t_end, dt=2e-3, stabilization=0.0)
    first_raw, last_raw = first_and_last_tenth(raw)
    assert last_raw > 10 * first_raw  # observed 4.02 / 0.0989 = 41
