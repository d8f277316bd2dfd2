"""Model validation: geometry, parameters, topology and the initial configuration.

Every bad model must be refused with a :class:`ModelError` whose message names the offending
body/joint/node/parameter; the references are the bad value itself and independent
computations (distances by hand, the rank of the constraint Jacobian by NumPy's own rank test).
"""

import re

import numpy as np
import pytest
from models import E_AL, RHO_AL, flexible_mechanism, straight_nodes

import morphlab as ml
from morphlab.compile import constraint_rank

BEAM = dict(E=E_AL, rho=RHO_AL, thickness=2.0, width=10.0)


def beam_model(n_elem=4, length=100.0):
    m = ml.Model(name="strip")
    b = m.add_beam(straight_nodes(n_elem, length=length), name="strip", **BEAM)
    return m, b


def rigid_model():
    m = ml.Model(name="one")
    b = m.add_rigid_body(mass=1e-3, inertia=1.0, position=(10.0, 0.0), name="link")
    return m, b


# ---------------------------------------------------------------------------------- geometry
def test_beam_needs_two_nodes():
    with pytest.raises(ml.ModelError, match=r"beam 'b'.*at least two nodes, got 1"):
        ml.Model().add_beam([[0.0, 0.0]], name="b", **BEAM)


@pytest.mark.parametrize("nodes", [np.zeros(4), np.zeros((3, 3)), "nodes", None,
                                   [[0.0, 0.0], [1.0]]])
def test_beam_nodes_must_be_n_by_2_numbers(nodes):
    with pytest.raises(ml.ModelError, match=r"beam 'b': nodes must be an \(n, 2\) array"):
        ml.Model().add_beam(nodes, name="b", **BEAM)


def test_coincident_consecutive_nodes_are_named():
    X = straight_nodes(4)
    X[3] = X[2]
    with pytest.raises(ml.ModelError, match=r"beam 'b': nodes 2 and 3 coincide"):
        ml.Model().add_beam(X, name="b", **BEAM)


@pytest.mark.parametrize("bad", [np.nan, np.inf, -np.inf, complex(1.0, np.nan)])
def test_non_finite_node_is_named(bad):
    X = straight_nodes(4).astype(complex)
    X[3, 1] = bad
    with pytest.raises(ml.ModelError, match=r"beam 'b': node 3 has a non-finite coordinate"):
        ml.Model().add_beam(X, name="b", **BEAM)


@pytest.mark.parametrize("adder", ["revolute", "weld", "fix", "drive", "force", "torque"])
def test_point_off_the_beam_names_nearest_node_and_distance(adder):
    m, b = beam_model()  # nodes at x = 0, 25, 50, 75, 100
    at = (52.0, 1.5)
    expected = np.hypot(52.0 - 50.0, 1.5)  # node 2 at (50, 0)
    calls = {
        "revolute": lambda: m.add_revolute(m.ground, b, at=at),
        "weld": lambda: m.add_weld(b, m.ground, at=at),
        "fix": lambda: m.add_fix(b, at=at),
        "drive": lambda: m.add_drive(b, angle=ml.SmoothStep(0.0, 1.0), at=at),
        "force": lambda: m.add_force(b, at=at, force=(0.0, 1.0)),
        "torque": lambda: m.add_torque(b, 1.0, at=at),
    }
    with pytest.raises(ml.ModelError) as err:
        calls[adder]()
    msg = str(err.value)
    assert "beam 'strip'" in msg and "nearest is node 2" in msg
    dist = float(re.search(r"distance ([0-9.e+-]+)", msg).group(1))
    assert dist == pytest.approx(expected, rel=1e-6)  # printed with 6 significant digits
    assert not m.joints and not m.forces and not m.torques  # nothing half-added


def test_point_within_tolerance_of_a_node_is_accepted_and_rigid_points_are_anywhere():
    m, b = beam_model()
    # 1e-9 mm from node 4: well inside the add-time tolerance 1e-6 of the beam size
    m.add_fix(b, at=(100.0, 1e-9), dofs="xy")
    link = m.add_rigid_body(mass=1e-3, inertia=1.0, position=(30.0, 40.0), name="link")
    m.add_revolute(link, m.ground, at=(-500.0, 250.0))  # far outside the body: still material
    assert len(m.joints) == 2


# -------------------------------------------------------------------------------- parameters
@pytest.mark.parametrize("param", ["E", "rho", "thickness", "width"])
# (1.0, 2.0, 3.0): one value per element is allowed, but this beam has 2 elements
@pytest.mark.parametrize("bad", [0.0, -1.0, np.nan, np.inf, "7e4", None, True, (1.0, 2.0, 3.0),
                                 (1.0, -2.0)])
def test_beam_parameters_must_be_finite_positive(param, bad):
    kw = dict(BEAM)
    kw[param] = bad
    m = ml.Model()
    with pytest.raises(ml.ModelError) as err:
        m.add_beam(straight_nodes(2), name="skin", **kw)
    msg = str(err.value)
    assert "beam 'skin'" in msg and param in msg
    if bad is not None:  # None means "not given": the message asks for the pair instead
        assert "finite positive number" in msg or "must be positive" in msg
    assert not m.bodies


@pytest.mark.parametrize("param", ["E", "rho", "thickness", "width"])
def test_beam_parameters_may_be_given_per_element(param):
    kw = dict(BEAM)
    kw[param] = (kw[param], 1.5 * kw[param])
    b = ml.Model().add_beam(straight_nodes(2), name="skin", **kw)
    assert np.shape(getattr(b, param)) == (2,)


@pytest.mark.parametrize("param", ["mass", "inertia"])
@pytest.mark.parametrize("bad", [0.0, -2.0, np.nan, -np.inf, "1", None, [1.0]])
def test_rigid_body_parameters_must_be_finite_positive(param, bad):
    kw = dict(mass=1.0, inertia=1.0, position=(0.0, 0.0))
    kw[param] = bad
    with pytest.raises(ml.ModelError, match=rf"rigid body 'crank': {param}.*finite positive"):
        ml.Model().add_rigid_body(name="crank", **kw)


@pytest.mark.parametrize("param,bad", [("angle", np.nan), ("angular_velocity", np.inf),
                                       ("angular_velocity", "1"), ("position", (0.0, np.nan)),
                                       ("velocity", (1.0,)), ("position", None)])
def test_rigid_body_state_must_be_finite(param, bad):
    kw = dict(mass=1.0, inertia=1.0, position=(0.0, 0.0))
    kw[param] = bad
    with pytest.raises(ml.ModelError, match=rf"rigid body 'crank': {param}"):
        ml.Model().add_rigid_body(name="crank", **kw)


def test_damping_and_reference_node():
    m = ml.Model()
    with pytest.raises(ml.ModelError, match=r"damping \[s\] must be a finite number >= 0"):
        m.add_beam(straight_nodes(2), damping=-1e-4, name="b", **BEAM)
    for ref in (3, -4, 1.0, True):
        with pytest.raises(ml.ModelError, match=r"reference_node must be a node index in \[0, 2\]"):
            m.add_beam(straight_nodes(2), reference_node=ref, name="b", **BEAM)


def test_section_must_be_complete_and_unambiguous():
    m = ml.Model()
    with pytest.raises(ml.ModelError, match="needs both thickness and width"):
        m.add_beam(straight_nodes(2), E=1.0, rho=1.0, thickness=1.0, name="b")
    with pytest.raises(ml.ModelError, match="not both"):
        m.add_beam(straight_nodes(2), E=1.0, rho=1.0, thickness=1.0, width=1.0, area=1.0,
                   name="b")
    with pytest.raises(ml.ModelError, match="section missing"):
        m.add_beam(straight_nodes(2), E=1.0, rho=1.0, area=1.0, name="b")
    # a huge thickness overflows the second moment: refused with the reason, not OverflowError
    with pytest.raises(ml.ModelError, match=r"second_moment.*from the rectangular section"):
        m.add_beam(straight_nodes(2), E=1.0, rho=1.0, thickness=1e200, width=1.0, name="b")


@pytest.mark.parametrize("dofs", ["", "xx", "q", "XY", "xyz", None, 3, ["x"]])
def test_fix_dofs_letters(dofs):
    m, b = rigid_model()
    with pytest.raises(ml.ModelError, match=r"fix 'F': dofs must be a non-empty string of "
                                            r"distinct letters from 'x', 'y', 'r'"):
        m.add_fix(b, at=(0.0, 0.0), dofs=dofs, name="F")


def test_fix_dofs_any_order_is_normalized():
    m, b = rigid_model()
    assert m.add_fix(b, at=(0.0, 0.0), dofs="rx").dofs == "xr"


def test_body_belongs_to_one_model():
    m1, m2 = ml.Model(name="m1"), ml.Model(name="m2")
    body = ml.RigidBody(1.0, 1.0, (0.0, 0.0), name="link")
    m1.add_body(body)
    with pytest.raises(ml.ModelError, match=r"body 'link' already belongs to model 'm1'"):
        m2.add_body(body)
    with pytest.raises(ml.ModelError, match=r"not part of model 'm2' \(it belongs to model 'm1'\)"):
        m2.add_revolute(m2.ground, body, at=(0.0, 0.0))
    assert m2.bodies == [] and m2.joints == []


def test_duplicate_names():
    m, b = rigid_model()
    with pytest.raises(ml.ModelError, match="a body named 'link' already exists"):
        m.add_rigid_body(mass=1.0, inertia=1.0, position=(0.0, 0.0), name="link")
    with pytest.raises(ml.ModelError, match="a body named 'ground' already exists"):
        m.add_rigid_body(mass=1.0, inertia=1.0, position=(0.0, 0.0), name="ground")
    m.add_revolute(m.ground, b, at=(0.0, 0.0), name="A")
    with pytest.raises(ml.ModelError, match="a joint named 'A' already exists"):
        m.add_drive(b, angle=ml.SmoothStep(0.0, 1.0), name="A")
    m.add_force(b, at=(0.0, 0.0), force=(1.0, 0.0), name="P")
    with pytest.raises(ml.ModelError, match="a load named 'P' already exists"):
        m.add_torque(b, 1.0, name="P")
    for bad in ("", 3, ("a",)):
        with pytest.raises(ml.ModelError, match="names must be non-empty strings"):
            m.add_rigid_body(mass=1.0, inertia=1.0, position=(0.0, 0.0), name=bad)
    assert [x.name for x in m.bodies] == ["link"] and len(m.joints) == 1


@pytest.mark.parametrize("bad", [(0.0, np.nan), (np.inf, 0.0), (0.0,), "down", None,
                                 [[0.0, 1.0]]])
def test_gravity_and_force_must_be_finite_pairs(bad):
    with pytest.raises(ml.ModelError, match=r"model 'm': gravity must be a finite pair"):
        ml.Model(gravity=bad, name="m")
    m, b = rigid_model()
    with pytest.raises(ml.ModelError, match=r"force 'P': force must be a finite pair"):
        m.add_force(b, at=(0.0, 0.0), force=bad, name="P")
    assert not m.forces


@pytest.mark.parametrize("bad", [np.nan, -np.inf, complex(0.0, np.inf), "5", None, (1.0, 2.0)])
def test_torque_magnitude_must_be_a_finite_number(bad):
    m, b = rigid_model()
    with pytest.raises(ml.ModelError, match=r"torque 'T': magnitude must be a finite"):
        m.add_torque(b, bad, name="T")
    assert not m.torques


def test_load_profiles_must_be_finite_at_start():
    m, b = rigid_model()
    with pytest.raises(ml.ModelError, match=r"force 'P': the profile value at t=0"):
        m.add_force(b, at=(0.0, 0.0), force=(1.0, 0.0), profile=np.nan, name="P")
    with pytest.raises(ml.ModelError, match=r"torque 'T': evaluating the profile at t=0 failed"):
        m.add_torque(b, 1.0, profile=lambda t: 1.0 / t, name="T")
    with pytest.raises(ml.ModelError, match=r"force 'P': expected a Profile"):
        m.add_force(b, at=(0.0, 0.0), force=(1.0, 0.0), profile="ramp", name="P")


def test_drive_must_start_at_zero():
    m, b = rigid_model()
    with pytest.raises(ml.ModelError, match=r"drive 'D': angle\(0\) must be 0"):
        m.add_drive(b, angle=lambda t: 1.0 + t, name="D")
    with pytest.raises(ml.ModelError, match=r"drive 'D': the profile value at t=0"):
        m.add_drive(b, angle=ml.Custom(lambda t: np.nan), name="D")
    with pytest.raises(ml.ModelError, match="cannot drive the ground"):
        m.add_drive(m.ground, angle=ml.SmoothStep(0.0, 1.0))


# ---------------------------------------------------------------------------------- topology
def redundant_rows(model):
    """(names in the error message, error) of a model that must be refused as redundant."""
    with pytest.raises(ml.ModelError, match="redundant or conflicting constraints") as err:
        ml.compile_model(model)
    listed = re.search(r"Linearly dependent rows: (.*?) \(joints", str(err.value)).group(1)
    return set(re.findall(r"'([^']+)'", listed)), str(err.value)


def test_drive_and_fix_on_the_same_beam_rotation_are_redundant():
    m, b = beam_model()
    m.add_fix(b, at=(0.0, 0.0), name="clamp")  # x, y, r of node 0 (the reference node)
    m.add_drive(b, angle=ml.SmoothStep(0.0, 0.1), name="motor")
    rows, msg = redundant_rows(m)
    # the two rotation rows are the dependent pair; the clamp's x and y rows are independent
    assert rows == {"clamp.r", "motor.r"}
    assert "rank 3 for 4 rows" in msg


def test_drive_and_fix_on_the_same_node_rotation_away_from_the_reference_node():
    m, b = beam_model()
    m.add_fix(b, at=(0.0, 0.0), dofs="xy", name="pin")
    m.add_fix(b, at=(50.0, 0.0), dofs="r", name="hold")
    m.add_drive(b, angle=ml.SmoothStep(0.0, 0.1), at=(50.0, 0.0), name="motor")
    assert redundant_rows(m)[0] == {"hold.r", "motor.r"}


def test_fix_plus_revolute_at_the_same_point_is_redundant():
    m, b = rigid_model()
    m.add_fix(b, at=(0.0, 0.0), name="F")
    m.add_revolute(m.ground, b, at=(0.0, 0.0), name="A")
    assert redundant_rows(m)[0] == {"F.x", "F.y", "A.x", "A.y"}


def toggle(bend):
    """Two rigid links pinned to ground at (0, 0) and (2, 0) and to each other at (1, bend):
    a structure, singular (an infinitesimal mechanism) when the links are collinear."""
    m = ml.Model(name="toggle")
    P = np.array([1.0, bend])
    links = []
    for k, (A, name) in enumerate([((0.0, 0.0), "left"), ((2.0, 0.0), "right")]):
        d = P - np.asarray(A)
        links.append(m.add_rigid_body(mass=1e-3, inertia=1e-4, position=tuple((P + A) / 2),
                                      angle=np.arctan2(d[1], d[0]), name=name))
        m.add_revolute(m.ground, links[k], at=A, name=f"G{k}")
    m.add_revolute(links[0], links[1], at=tuple(P), name="K")
    return m


def test_dead_point_is_reported_and_a_bent_toggle_is_not():
    rows, msg = redundant_rows(toggle(0.0))
    assert "rank 5 for 6 rows" in msg
    # the null space of J^T is the self-stress of the straight toggle: a tension along the
    # line, carried by the horizontal rows of the three pins (G0.x - K.x + G1.x has zero
    # gradient because every lever arm is horizontal); the vertical rows stay independent
    assert rows == {"G0.x", "G1.x", "K.x"}
    system = ml.compile_model(toggle(0.2))
    assert constraint_rank(system)[0] == 6


def test_rank_agrees_with_numpy_on_the_unscaled_jacobian():
    # a model of unit size: the scaling changes nothing there, so NumPy's matrix_rank (default
    # tolerance sigma_max * max(m, n) * eps, on the unscaled J) is an independent reference.
    system = ml.compile_model(toggle(0.3))
    # the same links turned collinear along x (the constraint values are violated there, but
    # the Jacobian depends on q only): left centre at l/2, right centre at 3l/2 turned by pi
    half = np.hypot(1.0, 0.3) / 2
    q_line = np.array([half, 0.0, 0.0, 3 * half, 0.0, np.pi])
    for q, expected in ((system.q0, 6), (q_line, 5)):
        J = np.real(system.constraint_matrix(q))
        assert np.linalg.matrix_rank(J) == expected == constraint_rank(system, q)[0]


@pytest.mark.parametrize("scale", [1e-12, 1e-3, 1.0, 1e3, 1e12])
def test_rank_test_is_unit_independent(scale):
    # Fix 'x' at two points of different height fixes x and the rotation (full rank 2); a
    # third x-row at another height repeats them (rank 2 for 3 rows). Without scaling the
    # rotation column by the model size, at 1e-12 the first model would look singular and at
    # 1e12 the translational columns would be lost against the lever arms.
    def model(n_fix):
        m = ml.Model(name="u")
        b = m.add_rigid_body(mass=1.0, inertia=1.0, position=(0.0, 0.0), name="b")
        for k in range(n_fix):
            m.add_fix(b, at=(0.0, scale * (k - 0.7)), dofs="x", name=f"x{k}")
        return m

    assert constraint_rank(ml.compile_model(model(2)))[0] == 2
    assert redundant_rows(model(3))[0] == {"x0.x", "x1.x", "x2.x"}


def test_valid_closed_loop_has_full_rank():
    system = ml.compile_model(flexible_mechanism())
    rank, dep, _ = constraint_rank(system)
    assert rank == system.n_con == 8
    assert np.all(dep == 0.0)


# ---------------------------------------------------------------------- initial configuration
def test_joint_slightly_off_a_node_violates_the_initial_configuration():
    m = ml.Model(name="two strips")
    a = m.add_beam(straight_nodes(4), name="a", **BEAM)
    b = m.add_beam(straight_nodes(4, origin=(100.0, 5e-5)), name="b", **BEAM)
    m.add_fix(a, at=(0.0, 0.0))
    # within the add-time tolerance (1e-6 of 100 mm) of node 4 of 'a' and node 0 of 'b', but
    # the two nodes are 5e-5 mm apart: far above 1e-9 of the model size
    m.add_revolute(a, b, at=(100.0, 5e-5), name="hinge")
    with pytest.raises(ml.ModelError) as err:
        ml.compile_model(m)
    msg = str(err.value)
    assert "violates constraint 'hinge.y' of joint 'hinge' by 5e-05" in msg
    assert "from node 4 of beam 'a'" in msg


def test_drive_with_initial_speed_needs_consistent_initial_velocities():
    """Given velocities must match the drive's speed; none given: computed (the crank's centre
    at 10 mm moves at 10·2 mm/s)."""
    def model(omega0):
        m = ml.Model(name="crank")
        b = m.add_rigid_body(mass=1e-3, inertia=1.0, position=(10.0, 0.0),
                             velocity=(0.0, 10.0 * omega0), angular_velocity=omega0, name="c")
        m.add_revolute(m.ground, b, at=(0.0, 0.0), name="A")
        m.add_drive(b, angle=ml.Linear(2.0), name="motor")
        return m

    with pytest.raises(ml.ModelError, match="initial velocities violate constraint 'motor.r'"):
        ml.compile_model(model(1.0))
    assert ml.compile_model(model(2.0)).n_con == 3
    assert np.allclose(ml.compile_model(model(0.0)).v0, [0.0, 20.0, 2.0], rtol=1e-14, atol=1e-13)
