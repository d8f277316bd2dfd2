"""Prismatic joint: the slide row's exact Newton matrix (against complex-step columns of the
step residual) and closed-form motions (slider-crank kinematics, a block on an inclined guide,
a bead on a rotating rod)."""

import numpy as np
import pytest
from models import E_AL, RHO_AL, check_step_matrix_by_complex_step, straight_nodes

import morphlab as ml


def _guide_models():
    """A flexible guide (beam pinned to ground) carrying a rigid slider at a node, and a rigid
    guide (pinned rigid body) carrying a flexible beam at one of its nodes: both sides of the
    slide row on a beam node (with its rotation) and on a rigid body."""
    m1 = ml.Model(gravity=(0.0, -9.81e3), name="beam guide")
    nodes = straight_nodes(4, length=80.0, angle=0.3)
    guide = m1.add_beam(nodes, E=E_AL, rho=RHO_AL, thickness=2.0, width=10.0, name="guide")
    m1.add_revolute(m1.ground, guide, at=(0.0, 0.0))
    block = m1.add_rigid_body(mass=1e-4, inertia=0.1, position=tuple(nodes[2]), angle=0.2,
                              name="block")
    m1.add_prismatic(guide, block, at=tuple(nodes[2]), axis=(np.cos(0.3), np.sin(0.3)),
                     name="slide")
    m2 = ml.Model(gravity=(0.0, -9.81e3), name="rigid guide")
    rod = m2.add_rigid_body(mass=2e-4, inertia=0.3, position=(20.0, 10.0), angle=0.5,
                            name="rod")
    m2.add_revolute(m2.ground, rod, at=(0.0, 0.0))
    nodes = straight_nodes(3, length=40.0, origin=(10.0, 10.0), angle=-0.4)
    beam = m2.add_beam(nodes, E=E_AL, rho=RHO_AL, thickness=2.0, width=10.0, name="beam")
    m2.add_prismatic(rod, beam, at=tuple(nodes[1]), axis=(1.0, 2.0), name="slide")
    return [m1, m2]


@pytest.mark.parametrize("model", _guide_models(), ids=lambda m: m.name)
def test_newton_matrix_is_the_complex_step_of_the_residual(model):
    """Every column of the step matrix equals the complex-step derivative of the step
    residual (step h = 1e-30: no truncation or cancellation error, so agreement to round-off,
    1e-9 of the column's largest entry) at a random state far from any solution (nonzero
    velocities, accelerations and multipliers, so every term of the slide row's Hessian and of
    its velocity terms shows)."""
    check_step_matrix_by_complex_step(model, seed=4)


def _slider_crank(r=20.0, l=50.0, th0=np.pi / 6, omega=40.0):
    """Rigid crank (radius r, driven from rest: theta = th0 + omega (t - sin(k t)/k)),
    rigid rod (length l), slider on a ground guide along x through the crank's pivot."""
    m = ml.Model(gravity=(0.0, 0.0), name="slider-crank")
    pin = np.array([r * np.cos(th0), r * np.sin(th0)])
    x0 = r * np.cos(th0) + np.sqrt(l**2 - (r * np.sin(th0))**2)
    crank = m.add_rigid_body(mass=1e-4, inertia=5.0, position=tuple(pin / 2), angle=th0,
                             name="crank")
    phi = np.arctan2(-pin[1], x0 - pin[0])
    rod = m.add_rigid_body(mass=2e-4, inertia=40.0, position=tuple((pin + [x0, 0.0]) / 2),
                           angle=phi, name="rod")
    slider = m.add_rigid_body(mass=3e-4, inertia=1.0, position=(x0, 0.0), name="slider")
    m.add_revolute(m.ground, crank, at=(0.0, 0.0), name="O")
    m.add_revolute(crank, rod, at=tuple(pin), name="A")
    m.add_revolute(rod, slider, at=(x0, 0.0), name="B")
    m.add_prismatic(m.ground, slider, at=(x0, 0.0), axis=(1.0, 0.0), name="P")
    k = 2 * np.pi / 0.05
    m.add_drive(crank, angle=ml.Custom(lambda t: omega * (t - np.sin(k * t) / k),
                                       lambda t: omega * (1 - np.cos(k * t)),
                                       lambda t: omega * k * np.sin(k * t)), name="motor")
    return m


def test_slider_crank_follows_the_closed_form_kinematics():
    """Slider position x = r cos(theta) + sqrt(l² - r² sin²(theta)) over more than a crank
    revolution: the rigid mechanism has one DOF, prescribed by the drive, so the slider
    follows from the constraints alone, wrong only by their drift (acceleration-level rows
    with Baumgarte stabilization: positions drift as dt³ here). Measured: error 8.8e-4 /
    1.1e-4 mm at dt = 5e-4 / 2.5e-4 s, twice the run's reported violation, order 3.0;
    asserted: below 2.5 x the reported violation, and at least second order."""
    r, l = 20.0, 50.0
    errs = []
    for dt in (5e-4, 2.5e-4):
        res = ml.simulate(_slider_crank(r, l), t_end=0.2, dt=dt)
        th = res.dof("crank.theta")
        assert th[-1] - th[0] > 2 * np.pi
        x = r * np.cos(th) + np.sqrt(l**2 - (r * np.sin(th))**2)
        errs.append(np.abs(res.dof("slider.x") - x).max())
        assert errs[-1] < 2.5 * res.constraint_violation.max()
        assert np.abs(res.dof("slider.y")).max() < 1e-12  # on the guide (a linear row)
        assert np.abs(res.dof("slider.theta")).max() < 1e-12  # rotation locked
    assert np.log2(errs[0] / errs[1]) > 2.0


def test_block_slides_down_an_inclined_guide():
    """A block on a frictionless guide at 30° under gravity: s = -g sin(alpha) t² / 2 along the
    guide. The acceleration is constant, which the Newmark update integrates exactly, so the
    run matches to round-off (1e-9 relative); the guide's normal force is m g cos(alpha)."""
    g, al, mass = 9.81e3, np.deg2rad(30.0), 1e-3
    m = ml.Model(gravity=(0.0, -g))
    blk = m.add_rigid_body(mass=mass, inertia=1.0, position=(5.0, 2.0), name="block")
    m.add_prismatic(m.ground, blk, at=(5.0, 2.0), axis=(2 * np.cos(al), 2 * np.sin(al)),
                    name="guide")
    res = ml.simulate(m, t_end=0.1, dt=1e-3)
    R, th = res.reference("block")
    s = (R[:, 0] - 5.0) * np.cos(al) + (R[:, 1] - 2.0) * np.sin(al)
    np.testing.assert_allclose(s, -0.5 * g * np.sin(al) * res.t**2, rtol=1e-9, atol=1e-12)
    off = -(R[:, 0] - 5.0) * np.sin(al) + (R[:, 1] - 2.0) * np.cos(al)
    assert np.abs(off).max() < 1e-12 and np.abs(th).max() < 1e-12
    np.testing.assert_allclose(np.abs(res.lam[1:, 0]), mass * g * np.cos(al), rtol=1e-9)


def bead_on_rotating_rod(omega=30.0, r0=10.0):
    """A rod spinning about the origin at a constant rate ``omega`` (driven), a bead free to
    slide on it (no gravity): r(t) = r0 cosh(omega t)."""
    m = ml.Model(name="bead")
    rod = m.add_rigid_body(mass=2e-4, inertia=20.0, position=(0.0, 0.0),
                           angular_velocity=omega, name="rod")
    m.add_revolute(m.ground, rod, at=(0.0, 0.0), name="pivot")
    m.add_drive(rod, angle=ml.Linear(omega), name="motor")
    bead = m.add_rigid_body(mass=1e-4, inertia=0.5, position=(r0, 0.0),
                            velocity=(0.0, omega * r0), angular_velocity=omega, name="bead")
    m.add_prismatic(rod, bead, at=(r0, 0.0), axis=(1.0, 0.0), name="slide")
    return m


def test_bead_on_a_rotating_rod_moves_out_as_cosh():
    """The guide turns (the slide row's normal and its Hessian in the guide's angle work):
    r = r0 cosh(omega t). Second order in time: at dt = 1e-4 s (omega dt = 3e-3) the error
    over omega t = 3 is ~1e-5 of r; halving dt divides it by ~4 (observed order 2 +- 0.1)."""
    omega, r0, t_end = 30.0, 10.0, 0.1
    errs = []
    for dt in (2e-4, 1e-4):
        res = ml.simulate(bead_on_rotating_rod(omega, r0), t_end=t_end, dt=dt, rho_inf=1.0)
        R, _ = res.reference("bead")
        r = np.hypot(R[:, 0], R[:, 1])
        errs.append(np.abs(r / (r0 * np.cosh(omega * res.t)) - 1).max())
    assert errs[1] < 2e-5
    assert np.log2(errs[0] / errs[1]) == pytest.approx(2.0, abs=0.1)


def test_bad_prismatic_input_is_refused():
    m = ml.Model()
    b = m.add_rigid_body(mass=1.0, inertia=1.0, position=(0.0, 0.0), name="b")
    with pytest.raises(ml.ModelError, match="axis must be a nonzero direction"):
        m.add_prismatic(m.ground, b, at=(0.0, 0.0), axis=(0.0, 0.0))
    beam = m.add_beam(straight_nodes(2), E=E_AL, rho=RHO_AL, thickness=1.0, width=1.0,
                      name="beam")
    with pytest.raises(ml.ModelError, match="not at a node of beam 'beam'"):
        m.add_prismatic(beam, b, at=(10.0, 0.0), axis=(1.0, 0.0))
    with pytest.raises(ml.ModelError, match="connects body 'b' to itself"):
        m.add_prismatic(b, b, at=(0.0, 0.0), axis=(1.0, 0.0))


def test_prismatic_joints_are_drawn_as_a_block_on_a_guide(tmp_path):
    """Model plot: a slider block (a polygon centred on the joint, its long side along the
    axis) and a guide line along the axis, no ground triangle. Snapshots: a ground guide
    spanning the stroke, one block per snapshot at the slider's position; on a turning guide
    the guide follows the rod. The animation writes its frames."""
    import matplotlib

    matplotlib.use("Agg")
    from matplotlib.patches import Polygon

    import morphlab.plots as mp

    def gid(fig, name):
        return [a for a in fig.axes[0].get_children() if a.get_gid() == name]

    model = _slider_crank()
    fig = mp.model(model)
    (block,) = gid(fig, "joint:P")
    (guide,) = gid(fig, "joint:P:guide")
    assert isinstance(block, Polygon)
    corners = block.get_xy()[:4]
    x0 = model.body("slider").position
    np.testing.assert_allclose(corners.mean(axis=0), x0, atol=1e-9)
    assert np.ptp(guide.get_ydata()) == 0.0  # the guide runs along x
    triangles = [a for a in gid(fig, "ground") if isinstance(a, Polygon)]
    assert len(triangles) == 1  # the crank's pivot only, none under the slider
    np.testing.assert_allclose(triangles[0].get_xy()[0], [0.0, 0.0])
    res = ml.simulate(model, t_end=0.1, dt=1e-3)
    fig = mp.snapshots(res, n=5)
    blocks = [a for a in fig.axes[0].patches if a.get_gid().endswith(":P")]
    assert len(blocks) == 5
    xs = np.array([b.get_xy()[:4].mean(axis=0)[0] for b in blocks])
    idx = np.unique(np.round(np.linspace(0, res.n_t - 1, 5)).astype(int))
    np.testing.assert_allclose(xs, res.dof("slider.x")[idx], atol=1e-9)
    (line,) = gid(fig, "guide:P")
    stroke = res.dof("slider.x")
    assert line.get_xdata().min() < stroke.min() and line.get_xdata().max() > stroke.max()
    bead = ml.simulate(bead_on_rotating_rod(), t_end=0.05, dt=1e-3)
    fig = mp.snapshots(bead, n=3)
    guides = gid(fig, "guide:slide")
    assert len(guides) == 3  # a turning guide is drawn at every snapshot
    ends = np.array([[g.get_xdata(), g.get_ydata()] for g in guides])  # (3, 2, 2)
    angle = np.arctan2(np.diff(ends[:, 1]), np.diff(ends[:, 0]))[:, 0]
    th = bead.dof("rod.theta")[np.unique(np.round(np.linspace(0, bead.n_t - 1, 3)).astype(int))]
    np.testing.assert_allclose(angle, th, atol=1e-9)
    path = mp.animate(res, tmp_path / "slider.gif", n_frames=4)
    assert path.stat().st_size > 0
