"""The gear / coupler joint ``(theta_a + phi_a) - r (theta_b + phi_b) = c`` (docs/theory.md
§4.2; ``Model.add_gear``, ``morphlab.model.Gear``, the kernel's ``ROW_GEAR``).

References, each independent of the code under test: the kinematic closed form of a driven
pair; the closed-form angular acceleration and transmitted moment of a pair under a torque
(``alpha_a = T / (J_a + J_b / r^2)``); conservation of energy (computed here from the states,
not by the library) for a free pair exchanging kinetic and gravitational energy; complex-step
columns of the step residual for the Newton matrix of a pair with beam nodes; the whole-run
complex step for the sensitivities with respect to the ratio.
"""

import numpy as np
import pytest
from models import E_AL, RHO_AL, straight_nodes

import morphlab as ml
from morphlab.compile.system import time_table
from morphlab.kernels import assemble
from morphlab.kernels.ffrf import scratch
from morphlab.kernels.types import Level, Weights

J_A, J_B = 2.0, 5.0  # [t mm^2]


def disks(ratio, *, angle_a=0.3, angle_b=-0.2, omega_a=0.0, offset=0.0, gravity=0.0):
    """Two rigid disks pinned to the ground, coupled by a gear of ``ratio``: ``a`` at the
    origin (balanced), ``b`` pivoting at (70, 0) with its centre of mass ``offset`` from the
    pivot along its initial angle (``J_B`` about the centre of mass); initial speeds
    consistent with the gear (``omega_b = omega_a / ratio``)."""
    m = ml.Model(gravity=(0.0, -gravity), name="disks")
    a = m.add_rigid_body(mass=1e-3, inertia=J_A, position=(0.0, 0.0), angle=angle_a,
                         angular_velocity=omega_a, name="a")
    pivot = np.array([70.0, 0.0])
    e = offset * np.array([np.cos(angle_b), np.sin(angle_b)])
    omega_b = omega_a / ratio
    b = m.add_rigid_body(mass=2e-3, inertia=J_B, position=tuple(pivot + e), angle=angle_b,
                         velocity=(-omega_b * e[1], omega_b * e[0]),
                         angular_velocity=omega_b, name="b")
    m.add_revolute(m.ground, a, at=(0.0, 0.0), name="pin_a")
    m.add_revolute(m.ground, b, at=tuple(pivot), name="pin_b")
    m.add_gear(a, b, ratio=ratio, name="mesh")
    return m


@pytest.mark.parametrize("ratio", [-2.5, 0.4])
def test_driven_pair_follows_the_ratio(ratio):
    """A drive turns ``a`` by 1.2 rad: ``b`` turns by 1.2 / r at every step. The gear row,
    between two coordinates with a constant target, holds to round-off (measured 2e-16 rad
    at r = -2.5, 6e-16 at 0.4; asserted 1e-12 of the turn), also its velocity level; the
    drive's own row lags its moving target by the stabilization's drift (measured 3.9e-6 rad
    at the end; asserted 1e-5 relative: the turn is there)."""
    m = disks(ratio)
    m.add_drive("a", angle=1.2 * ml.SmoothStep(0.0, 0.05), name="motor")
    res = ml.simulate(m, t_end=0.06, dt=1e-3)
    turn_a = res.dof("a.theta") - 0.3
    turn_b = res.dof("b.theta") + 0.2
    assert turn_a[-1] == pytest.approx(1.2, rel=1e-5)
    assert np.abs(turn_b - turn_a / ratio).max() <= 1e-12 * 1.2
    np.testing.assert_allclose(res.v[:, 5], res.v[:, 2] / ratio, rtol=0, atol=1e-10 * 1.2 / 0.05)


@pytest.mark.parametrize("ratio", [-2.5, 3.0])
def test_torque_on_one_side_accelerates_both_by_the_reflected_inertia(ratio):
    """Torque T on ``a`` only: ``J_a alpha_a = T - M/r`` and ``J_b alpha_b = M`` with
    ``alpha_b = alpha_a / r`` give ``alpha_a = T / (J_a + J_b / r^2)`` and the moment the gear
    applies to ``b``, ``M = J_b alpha_a / r`` (its reaction). The accelerations are constant,
    which generalized-alpha integrates exactly: measured 1.3e-13 relative (accelerations) and
    4.9e-13 (moment); asserted 1e-9 (the Newton tolerance)."""
    T = 100.0  # [N mm]
    m = disks(ratio)
    m.add_torque("a", T, name="T")
    res = ml.simulate(m, t_end=0.02, dt=1e-3)
    alpha_a = T / (J_A + J_B / ratio**2)
    np.testing.assert_allclose(res.a[:, 2], alpha_a, rtol=1e-9)
    np.testing.assert_allclose(res.a[:, 5], alpha_a / ratio, rtol=1e-9)
    moment = res.reaction("mesh")
    np.testing.assert_allclose(moment[:, 2], J_B * alpha_a / ratio, rtol=1e-9)
    assert np.all(moment[:, :2] == 0.0)  # a gear row transmits no force
    # the pin of ``a`` holds its centre: no force, and the gear's moment on ``a`` is -M/r
    np.testing.assert_allclose(J_A * res.a[:, 2], T - moment[:, 2] / ratio, rtol=1e-9)


def test_free_pair_conserves_energy():
    """No torque; ``b`` unbalanced (centre of mass 15 mm off its pivot) under gravity, both
    turning initially: the pair swings, trading kinetic for potential energy (both vary by
    more than the total). Energy from the states (``m |v|^2 / 2 + J omega^2 / 2 + m g y``) is
    constant to the integrator's error, second order at rho_inf = 1: measured drift 4.4e-6 and
    1.1e-6 of the total at dt = 1e-3 and 5e-4 s (ratio 4.0); asserted 1e-5 and order 2 +- 0.2."""
    g, ratio = 9.81e3, -1.5

    def total_energy(res):
        s = res.system
        out = np.zeros(res.n_t)
        for name in ("a", "b"):
            body = s.model.body(name)
            x, y, th = s.body(name).ref
            v2 = res.v[:, x] ** 2 + res.v[:, y] ** 2
            out += 0.5 * body.mass * v2 + 0.5 * body.inertia * res.v[:, th] ** 2
            out += body.mass * g * res.q[:, y]
        return out

    drift = []
    for dt in (1e-3, 5e-4):
        res = ml.simulate(disks(ratio, omega_a=-12.0, offset=15.0, gravity=g), t_end=0.4,
                          dt=dt, rho_inf=1.0)
        e = total_energy(res)
        kinetic = e - 2e-3 * g * res.dof("b.y")
        assert np.ptp(kinetic) > 0.5 * abs(e[0])  # the swing is not trivial (measured 1.22)
        drift.append(np.abs(e - e[0]).max() / abs(e[0]))
    assert drift[1] < 1e-5
    assert np.log2(drift[0] / drift[1]) == pytest.approx(2.0, abs=0.2)


# ---------------------------------------------------------------- beam nodes on a side
def geared_arm(ratio=-3.0, torque=40.0):
    """A motor disk (``a``) geared to the root node of a flexible arm (``b``; two frames,
    pinned at its root, the gear on the node's frame angle plus its elastic rotation), and a
    second gear from an interior node of the arm to a rigid follower: beam nodes on both sides
    of a gear row."""
    m = ml.Model(gravity=(0.0, -9.81e3), name="geared arm")
    nodes = straight_nodes(4, length=60.0, angle=0.2)
    arm = m.add_beam(nodes, E=E_AL, rho=RHO_AL, thickness=1.0, width=10.0, frames=2,
                     name="arm")
    motor = m.add_rigid_body(mass=1e-4, inertia=0.5, position=(0.0, -30.0), angle=0.1,
                             name="motor")
    follower = m.add_rigid_body(mass=1e-4, inertia=0.2, position=(40.0, -30.0), name="follower")
    m.add_revolute(m.ground, arm, at=(0.0, 0.0), name="root")
    m.add_revolute(m.ground, motor, at=(0.0, -30.0), name="bearing")
    m.add_revolute(m.ground, follower, at=(40.0, -30.0), name="follower_bearing")
    m.add_gear(motor, arm, ratio=ratio, at_b=(0.0, 0.0), name="mesh")
    m.add_gear(arm, follower, ratio=0.7, at_a=tuple(nodes[2]), name="belt")
    m.add_torque(motor, torque, profile=ml.SmoothStep(0.0, 0.01), name="T")
    return m, nodes


def newton_columns_by_complex_step(model, seed: int) -> None:
    """Assert that the step-matrix parts ``D0 = dR/d(a, lam/scale)``, ``Dq = dR/dq`` and
    ``Dv = dR/dq'`` of the residual share of one level (``kernels.assemble.matrix`` with the
    identity as coefficients) are the complex-step derivatives (h = 1e-30: exact to round-off)
    of that residual (``kernels.assemble.residual``) column by column, at a random state far
    from any solution: nonzero velocities, accelerations and multipliers and weights of
    different sizes, so that every term shows. Asserted to 1e-9 of the column's largest
    entry."""
    s = ml.compile_model(model)
    n, n_dof = s.n, s.n_dof
    rng = np.random.default_rng(seed)
    q = s.q0 + 0.05 * rng.standard_normal(n_dof)
    v, a = 3.0 * rng.standard_normal(n_dof), rng.standard_normal(n_dof)
    lam = rng.standard_normal(s.n_con)
    w = Weights(wm=1.1, wl=0.9, wf=0.8, wcm=1.3, wcf=0.6, scale=2.0, b0=5.0, b1=3.0)
    n_flex = s.count("flex")
    D = np.zeros((3, s.nnz))
    assemble.matrix(s.arrays, Level(q, v, a, lam), w, time_table(s, np.zeros(1)), 0, 0,
                    np.eye(3), D, scratch(n_flex, q))
    Ac, Tc, parts = s.arrays_as(complex), time_table(s, np.zeros(1), complex), s.parts()
    h = 1e-30
    for which in range(3):  # 0: (a, lam / scale), 1: q, 2: q'
        dense = np.zeros((n, n))
        for col in range(n):
            sl = slice(s.indptr[col], s.indptr[col + 1])
            dense[s.indices[sl], col] = D[which, sl]
        for k in range(n):
            x = [z.astype(complex) for z in (q, v, a, lam)]
            if k < n_dof:
                x[(2, 0, 1)[which]][k] += 1j * h
            elif which == 0:
                x[3][k - n_dof] += 1j * h * w.scale
            R = np.zeros(n, dtype=complex)
            assemble.residual(Ac, Level(*x), w, Tc, 0, 0, parts, n_dof, R,
                              scratch(n_flex, x[0]))
            col = R.imag / h
            err = np.abs(dense[:, k] - col).max()
            assert err <= 1e-9 * max(np.abs(col).max(), 1.0), (which, s.unknown_names[k])


def test_gear_on_beam_nodes_runs_and_its_newton_matrix_is_exact():
    """The geared arm runs (the root node turns by the motor's turn / r, elastic rotation
    included, to 1e-12 rad; measured 4.5e-17), and every column of its step matrix equals the
    complex-step derivative of the residual."""
    model, nodes = geared_arm()
    res = ml.simulate(model, t_end=0.02, dt=1e-3)
    assert res.status == "ok"
    s = res.system
    root_phi = s.body("arm").node_dofs[0][2]
    root_turn = res.q[:, s.body("arm").ref[2]] - res.q[0, s.body("arm").ref[2]]
    root_turn = root_turn + (res.q[:, root_phi] if root_phi >= 0 else 0.0)
    motor_turn = res.dof("motor.theta") - 0.1
    assert np.abs(motor_turn).max() > 5e-3  # measured 9.1e-3 rad: the relation is not vacuous
    assert np.abs(root_turn - motor_turn / -3.0).max() <= 1e-12
    newton_columns_by_complex_step(model, seed=11)


def test_gear_reaction_point_and_drawing():
    """A gear's ``at`` is the point of the side its reaction is read on: ``b``'s node, or the
    centre of mass of a rigid ``b`` given without a point; the model drawing marks each gear
    there."""
    import matplotlib.pyplot as plt

    model, nodes = geared_arm()
    mesh, belt = model.joints[-2:]
    np.testing.assert_array_equal(mesh.at, nodes[0])
    np.testing.assert_array_equal(belt.at, [40.0, -30.0])
    fig = ml.plots.model(model)
    for j in (mesh, belt):
        (mark,) = [ln for ln in fig.axes[0].lines if ln.get_gid() == f"joint:{j.name}"]
        np.testing.assert_array_equal(mark.get_xydata()[0], np.real(j.at))
    plt.close(fig)


P_GEAR = {"r": -3.0, "T": 40.0}
# Newton to 1e-13: the whole-run complex step differentiates the iterates as they are, so at
# the default 1e-10 it differs from the converged solution's derivative by ~1e-9 (measured
# 7.6e-10 and 1.5e-9 of the largest scaled gradient, for the ratio and the torque alike)
RUN = dict(t_end=0.02, dt=1e-3, tol=1e-13)


def test_sensitivities_with_respect_to_the_ratio():
    """d(response)/d(ratio, torque) of the arm's tip displacement and of the gear's reaction
    moment: the direct and adjoint methods against the whole-run complex step, to 1e-10 of
    each response's largest scaled gradient (p_i dpsi/dp_i; measured <= 2.7e-15, round-off,
    with Newton converged to 1e-13); the ratio moves each response by more than 1e-2 of the
    largest (measured 0.99: no vacuous comparison)."""
    nodes = geared_arm()[1]
    resp = {"tip_y": ml.responses.point_displacement("arm", tuple(nodes[-1]), 1),
            "mesh_M": ml.responses.reaction("mesh", 2)}

    def build(p):
        return geared_arm(ratio=p["r"], torque=p["T"])[0]

    cs = ml.sensitivities(build, P_GEAR, resp, method="complex-step", **RUN)
    for method in ("direct", "adjoint"):
        d = ml.sensitivities(build, P_GEAR, resp, method=method, **RUN)
        for r in resp:
            scaled = {v: abs(P_GEAR[v] * cs.gradients[r][v]) for v in P_GEAR}
            largest = max(scaled.values())
            assert scaled["r"] > 1e-2 * largest, r
            for v in P_GEAR:
                err = abs(P_GEAR[v] * (d.gradients[r][v] - cs.gradients[r][v]))
                assert err <= 1e-10 * largest, (method, r, v, err / largest)


# ---------------------------------------------------------------- bad input
def test_bad_input_is_refused_naming_the_gear():
    m, nodes = geared_arm()
    other = ml.Model(name="other")
    stranger = other.add_rigid_body(mass=1.0, inertia=1.0, position=(0.0, 0.0), name="x")
    n_joints = len(m.joints)
    cases = [
        (dict(ratio=0.0), r"gear 'g': ratio must be a finite nonzero number.*got 0.0"),
        (dict(ratio=np.nan), r"gear 'g': ratio must be a finite nonzero number \(no NaN"),
        (dict(ratio=np.inf), r"gear 'g': ratio must be a finite nonzero number \(no NaN"),
        (dict(ratio="2"), r"gear 'g': ratio must be a finite nonzero number, got '2'"),
        (dict(ratio=True), r"gear 'g': ratio must be a finite nonzero number, got True"),
        (dict(ratio=2.0, b=stranger),
         r"gear 'g': body 'x' is not part of model 'geared arm' \(it belongs to model 'other'"),
        (dict(ratio=2.0, b="nobody"), r"gear 'g': model 'geared arm' has no body 'nobody'"),
        (dict(ratio=2.0, b="motor"), r"gear 'g': connects body 'motor' to itself"),
        (dict(ratio=2.0, b="arm"), r"gear 'g': at_b \(a node of beam 'arm'\) is needed"),
        (dict(ratio=2.0, b="arm", at_b=(31.0, 6.0)),
         r"gear 'g': point \(31.0, 6.0\) is not at a node of beam 'arm'; nearest is node 2"),
        (dict(ratio=2.0, b="arm", at_b=(np.nan, 0.0)),
         r"gear 'g': at_b must be a finite pair"),
    ]
    for kw, pattern in cases:
        kw = dict(kw)
        b = kw.pop("b", "follower")
        with pytest.raises(ml.ModelError, match=pattern):
            m.add_gear("motor", b, name="g", **kw)
    assert len(m.joints) == n_joints  # nothing half-added
    # a rigid side takes any point (every point turns alike); the node is snapped exactly
    g = m.add_gear("motor", "arm", ratio=2.0, at_a=(5.0, 5.0),
                   at_b=tuple(nodes[1] + 1e-9), name="g")
    np.testing.assert_array_equal(g.at_b, nodes[1])
