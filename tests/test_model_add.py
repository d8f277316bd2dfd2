"""``Model.add``: the one path by which items enter a model (morphlab.model.items).

Items validate themselves against the model (``Item.check``); ``add`` owns what every kind
shares: the item belongs to one model, names are unique per namespace (bodies; joints; loads
and force elements together), default names are the kind's prefix and the length of its list.
The references are the rules themselves and the ``add_*`` methods, whose models must compile to
the same arrays as the items added directly.
"""

from dataclasses import dataclass

import numpy as np
import pytest
from models import E_AL, RHO_AL, straight_nodes

import morphlab as ml
from morphlab.model import (
    Drive,
    Fix,
    Force,
    Item,
    LineLoad,
    Revolute,
    RotationalSpring,
    Spring,
    Torque,
)
from morphlab.model.items import COLLECTIONS


def _bodies(m):
    beam = m.add_beam(straight_nodes(4, length=80.0), E=E_AL, rho=RHO_AL, thickness=2.0,
                      width=10.0, name="beam")
    link = m.add_rigid_body(mass=1e-4, inertia=0.1, position=(80.0, 20.0), name="link")
    return beam, link


def _by_add_methods():
    m = ml.Model(name="m")
    beam, link = _bodies(m)
    m.add_revolute(m.ground, beam, at=(0.0, 0.0))
    m.add_revolute(beam, link, at=(80.0, 0.0), name="tip")
    m.add_drive(beam, angle=ml.SmoothStep(0.0, 0.1))
    m.add_force(link, at=(80.0, 40.0), force=(1.0, 0.0))
    m.add_torque(beam, 2.0, at=(40.0, 0.0))
    m.add_spring("s", link, m.ground, at_a=(80.0, 40.0), at_b=(100.0, 40.0), stiffness=1.0)
    m.add_rotational_spring("r", "tip", stiffness=3.0)
    m.add_line_load("q", beam, q=(0.0, -0.01), elements=[2, 1])
    return m


def _by_items():
    m = ml.Model(name="m")
    _bodies(m)
    # bodies by name, points as tuples: check() makes them the model's bodies and arrays
    m.add(Revolute(None, "ground", "beam", (0.0, 0.0)))
    m.add(Revolute("tip", "beam", "link", (80.0, 0.0)))
    m.add(Drive(None, "beam", ml.SmoothStep(0.0, 0.1)))
    m.add(Force("link", (80.0, 40.0), (1.0, 0.0)))
    m.add(Torque("beam", 2.0, at=(40.0, 0.0)))
    m.add(Spring("s", "link", "ground", (80.0, 40.0), (100.0, 40.0), 1.0))
    m.add(RotationalSpring("r", None, None, None, None, 3.0, joint="tip"))
    m.add(LineLoad("q", "beam", (0.0, -0.01), elements=[2, 1]))
    return m


def test_items_added_directly_compile_like_the_add_methods():
    """The same mechanism by ``add_*`` and by ``add(Item(...))``: equal names, equal
    normalized fields, and equal compiled arrays (every design and topology field, exactly)."""
    m1, m2 = _by_add_methods(), _by_items()
    for coll in COLLECTIONS:
        assert [x.name for x in getattr(m1, coll)] == [x.name for x in getattr(m2, coll)]
    assert [j.name for j in m2.joints] == ["revolute0", "tip", "drive2"]
    assert m2.forces[0].name == "force0" and m2.torques[0].name == "torque0"
    assert m2.joints[0].b is m2.body("beam") and m2.springs[1].a is m2.body("beam")
    np.testing.assert_array_equal(m2.line_loads[0].elements, [1, 2])
    s1, s2 = ml.compile_model(m1), ml.compile_model(m2)
    assert s1.dof_names == s2.dof_names and s1.con_names == s2.con_names
    np.testing.assert_array_equal(s1.design, s2.design)
    np.testing.assert_array_equal(s1.indices, s2.indices)


def test_add_refuses_what_is_not_an_item_and_items_of_another_model():
    m1, m2 = ml.Model(name="m1"), ml.Model(name="m2")
    b1 = m1.add_rigid_body(mass=1.0, inertia=1.0, position=(1.0, 0.0), name="b")
    j = m1.add_revolute(m1.ground, b1, at=(0.0, 0.0), name="pin")
    with pytest.raises(ml.ModelError, match=r"model 'm2': add expects a body, joint, load"):
        m2.add("pin")
    with pytest.raises(ml.ModelError, match=r"revolute 'pin' already belongs to model 'm1'"):
        m2.add(j)
    for ground in (ml.model.Ground(), m2.ground):  # every model has its own already
        with pytest.raises(ml.ModelError, match=r"a body named 'ground' already exists"):
            m2.add(ground)
    assert not m2.bodies and not m2.joints


def test_names_are_unique_per_namespace_and_checked_before_the_item():
    m = ml.Model(name="m")
    b = m.add_rigid_body(mass=1.0, inertia=1.0, position=(1.0, 0.0), name="b")
    m.add(Fix("b", b, (0.0, 0.0)))  # a joint may share a body's name
    m.add(Torque(b, 1.0, name="b"))  # and a load a joint's
    with pytest.raises(ml.ModelError, match=r"a load named 'b' already exists \(loads and force"):
        m.add(Spring("b", b, m.ground, (1.0, 0.0), (2.0, 0.0), 1.0))
    with pytest.raises(ml.ModelError, match=r"a joint named 'b' already exists"):
        m.add(Fix("b", "nobody", None))  # the name is refused before the bad body and point
    with pytest.raises(ml.ModelError, match=r"joint names must be non-empty strings, got 3"):
        m.add(Fix(3, b, (0.0, 0.0)))
    # a default name that a user's name took already is refused as well, not renamed
    m.add(Force(b, (0.0, 0.0), (1.0, 0.0), name="force1"))
    with pytest.raises(ml.ModelError, match=r"a load named 'force1' already exists"):
        m.add(Force(b, (0.0, 0.0), (1.0, 0.0)))  # one force so far: the default is "force1"
    assert [f.name for f in m.forces] == ["force1"]


def test_item_errors_name_the_item_for_a_body_given_by_a_bad_name():
    m = ml.Model(name="m")
    with pytest.raises(ml.ModelError, match=r"revolute 'A': model 'm' has no body 'x'"):
        m.add_revolute("x", m.ground, at=(0.0, 0.0), name="A")
    with pytest.raises(ml.ModelError, match=r"force 'F': expected a body of this model or its "
                                            r"name, got None"):
        m.add_force(None, at=(0.0, 0.0), force=(1.0, 0.0), name="F")


def test_a_new_kind_of_item_brings_its_own_list():
    """A kind defined outside the model module (as a new load kind would be) registers its
    list when its class is defined; every model made afterwards has it, ``add`` fills it and
    its names share the loads' namespace."""

    @dataclass(eq=False)
    class Marker(Item, collection="test_markers", namespace="loads", label="test marker"):
        name: str | None
        body: object

        def check(self, model):
            if self.body is model.ground:
                raise ml.ModelError(f"{self.owner}: not on the ground")

    try:
        m = ml.Model(name="m")
        b = m.add_rigid_body(mass=1.0, inertia=1.0, position=(1.0, 0.0), name="b")
        m.add_torque(b, 1.0, name="T")
        assert m.test_markers == []
        assert m.add(Marker(None, b)).name == "test_marker0"
        with pytest.raises(ml.ModelError, match=r"test marker 'test_marker1': not on the ground"):
            m.add(Marker(None, m.ground))
        with pytest.raises(ml.ModelError, match=r"a load named 'T' already exists"):
            m.add(Marker("T", b))
        assert [x.name for x in m.test_markers] == ["test_marker0"]
        with pytest.raises(TypeError, match="namespace must be one of"):
            type("Bad", (Item,), {"collection": "bad", "namespace": "other"})
    finally:
        COLLECTIONS.pop("test_markers")


def test_default_names_of_every_kind_are_its_label_with_a_count():
    """The class statement gives label and prefix; a rigid body is named like any body and a
    follower force like any force (they share the list and its count)."""
    from morphlab.model.bodies import Beam, RigidBody
    from morphlab.model.forces import LineLoad, RotationalSpring, Spring
    from morphlab.model.joints import Drive, Fix, Gear, Prismatic, Revolute, Weld
    from morphlab.model.loads import Force, Torque
    from morphlab.model.pressure import FollowerForce, Pressure

    prefixes = {cls.__name__: cls.prefix for cls in (
        Beam, RigidBody, LineLoad, RotationalSpring, Spring, Drive, Fix, Gear, Prismatic,
        Revolute, Weld, Force, Torque, FollowerForce, Pressure)}
    assert prefixes == {
        "Beam": "beam", "RigidBody": "body", "LineLoad": "line_load",
        "RotationalSpring": "rotational_spring", "Spring": "spring", "Drive": "drive",
        "Fix": "fix", "Gear": "gear", "Prismatic": "prismatic", "Revolute": "revolute",
        "Weld": "weld", "Force": "force", "Torque": "torque", "FollowerForce": "force",
        "Pressure": "pressure"}
    assert (FollowerForce.collection, FollowerForce.label) == ("forces", "follower force")
    assert (RotationalSpring.collection, RotationalSpring.namespace) == ("springs", "loads")
