"""Declarative model description: bodies, joints, loads and profiles.

A :class:`Model` only *describes* a mechanism; :func:`morphlab.compile.compile_model` turns it into
flat arrays. Points are given in global coordinates of the initial (undeformed) configuration;
on a beam, joints and loads sit at nodes. Values may be complex (complex-step differentiation
through a parametric ``build(p)``); validation looks at the real parts.

Items enter a model by :meth:`Model.add`, which checks that the item belongs to no other model
and that its name is free, and lets the item validate itself against the model
(:meth:`~morphlab.model.items.Item.check`) before anything changes; the ``add_*`` methods build
the item from their arguments and add it. Bad input is refused with a
:class:`~morphlab.errors.ModelError` that names the body, joint, load or parameter and says what
would be valid: numbers must be finite numbers of the right shape (no strings, ``None``,
booleans, NaN or Inf), physical parameters positive, names unique non-empty strings, points on
a beam at one of its nodes. What needs the whole model (redundant or conflicting constraints,
an inconsistent initial configuration) is checked by ``compile_model``.
"""

from __future__ import annotations

import numpy as np

from ..errors import ModelError
from .bodies import Beam, Body, Ground, RigidBody
from .forces import LineLoad, RotationalSpring, Spring
from .items import COLLECTIONS, NAMESPACES, Item
from .joints import Drive, Fix, Gear, Joint, Prismatic, Revolute, Weld
from .loads import Force, Torque
from .pressure import FollowerForce, Pressure
from .values import _check_name, _point, _show


class Model:
    """A planar flexible multibody model.

    Parameters
    ----------
    gravity : (2,)
        Gravitational acceleration [mm/s² in the morphing units], default none.
    name : str
        Used in messages and saved files.

    Attributes
    ----------
    ground : Ground
    bodies, joints, forces, torques, springs, line_loads : list
        The items of each kind, in the order they were added (one list per
        :attr:`~morphlab.model.items.Item.collection`; a kind of item defined elsewhere brings
        its own list).

    Examples
    --------
    >>> import morphlab as ml
    >>> m = ml.Model(gravity=(0.0, -9.81e3))
    >>> link = m.add_rigid_body(mass=1e-3, inertia=1.0, position=(50.0, 0.0), name="link")
    >>> j = m.add_revolute(m.ground, link, at=(0.0, 0.0))
    """

    bodies: list[Body]
    joints: list[Joint]
    forces: list[Force]
    torques: list[Torque]
    springs: list[Spring | RotationalSpring]
    line_loads: list[LineLoad]

    def __init__(self, gravity=(0.0, 0.0), name: str = "model"):
        self.name = _check_name(name, "model")
        self.gravity = _point(gravity, "gravity", f"model {name!r}")
        self.ground = Ground()
        self.ground._model = self
        for collection in COLLECTIONS:
            setattr(self, collection, [])

    def add(self, item: Item) -> Item:
        """Add ``item`` (a body, joint, load or force element) and return it.

        A name left ``None`` becomes the kind's prefix followed by the length of its list
        (``"revolute3"``). The item then validates itself against the model
        (:meth:`~morphlab.model.items.Item.check`), which may bring its fields to canonical
        form (bodies given by name become the model's bodies, points on a beam its node).

        Raises
        ------
        ModelError
            Not an item; an item of another model; a name that is not a non-empty string, or
            taken in the item's namespace (bodies; joints; loads and force elements together);
            whatever the item's own check refuses. The model is unchanged then.
        """
        if not isinstance(item, Item) or not item.collection:
            raise ModelError(f"model {self.name!r}: add expects a body, joint, load or force "
                             f"element (a morphlab.model item), got {_show(item)}")
        if item._model is not None and item._model is not self:
            raise ModelError(f"{item.owner} already belongs to model {item._model.name!r}; an "
                             "item can be part of one model only: create a new one")
        items = getattr(self, item.collection)
        word, note = NAMESPACES[item.namespace]
        if item.name is None:
            item.name = f"{item.prefix}{len(items)}"
        _check_name(item.name, word)
        if any(other.name == item.name for other in self._namespace(item.namespace)):
            raise ModelError(f"model {self.name!r}: a {word} named {item.name!r} already "
                             f"exists{note}")
        item.check(self)
        item._model = self
        items.append(item)
        return item

    def _namespace(self, namespace: str):
        """Every item whose name is in ``namespace`` (the ground among the bodies)."""
        if namespace == "bodies":
            yield self.ground
        for collection, ns in COLLECTIONS.items():
            if ns == namespace:
                yield from getattr(self, collection)

    # ---- bodies
    def add_body(self, body: Body) -> Body:
        """Add a ready-made :class:`RigidBody` or :class:`Beam`."""
        if not isinstance(body, (RigidBody, Beam)):
            raise ModelError(f"add_body expects a RigidBody or Beam, got {type(body).__name__}")
        return self.add(body)

    def add_beam(self, nodes, *, E, rho, thickness=None, width=None, area=None,
                 second_moment=None, fibre=None, damping=0.0, frames=None, reference=None,
                 reference_node=None, name=None) -> Beam:
        """Add a flexible :class:`Beam` (see there for the parameters and units)."""
        name = f"{Beam.prefix}{len(self.bodies)}" if name is None else name
        return self.add(Beam(nodes, E=E, rho=rho, thickness=thickness, width=width, area=area,
                             second_moment=second_moment, fibre=fibre, damping=damping,
                             frames=frames, reference=reference, reference_node=reference_node,
                             name=name))

    def add_rigid_body(self, *, mass, inertia, position, angle=0.0, velocity=(0.0, 0.0),
                       angular_velocity=0.0, name=None) -> RigidBody:
        """Add a :class:`RigidBody` (reference point = centre of mass)."""
        name = f"{RigidBody.prefix}{len(self.bodies)}" if name is None else name
        return self.add(RigidBody(mass, inertia, position, angle, velocity=velocity,
                                  angular_velocity=angular_velocity, name=name))

    def body(self, name: str) -> Body:
        """The body called ``name`` (``"ground"`` for the ground)."""
        if not isinstance(name, str):
            raise ModelError(f"model {self.name!r}: body names are strings, got {_show(name)}")
        if name == "ground":
            return self.ground
        for b in self.bodies:
            if b.name == name:
                return b
        known = ", ".join(repr(b.name) for b in self.bodies) or "none"
        raise ModelError(f"model {self.name!r} has no body {name!r} (bodies: {known})")

    # ---- joints (morphlab.model.joints; bodies by object or name, points global)
    def add_revolute(self, a, b, *, at, name=None) -> Revolute:
        """Pin ``a`` and ``b`` together at the global point ``at`` (a node if on a beam)."""
        return self.add(Revolute(name, a, b, at))

    def add_weld(self, a, b, *, at, name=None) -> Weld:
        """Rigidly connect ``a`` and ``b`` at ``at`` (position and relative angle held)."""
        return self.add(Weld(name, a, b, at))

    def add_prismatic(self, a, b, *, at, axis, name=None) -> Prismatic:
        """Let ``b`` slide along ``a``: the point of ``b`` at ``at`` (a node if on a beam)
        stays on the line through ``at`` with direction ``axis`` (global, initial
        configuration; any length) fixed in ``a`` (or the ground), and the relative rotation of
        ``a`` and ``b`` is locked. Its reaction (:meth:`Result.reaction`) is the guide's
        action on ``b``: the normal force and the locking moment."""
        return self.add(Prismatic(name, a, b, at, axis))

    def add_fix(self, body, *, at, dofs="xyr", name=None) -> Fix:
        """Fix any of ``x``, ``y``, ``r`` (rotation) of the point ``at`` of ``body`` to ground."""
        return self.add(Fix(name, body, at, dofs))

    def add_drive(self, body, *, angle=None, speed=None, at=None, name=None) -> Drive:
        """Prescribe the rotation of ``body`` (or of the beam node at ``at``) by its angle or
        by its angular speed; exactly one of ``angle`` and ``speed`` is given.

        Parameters
        ----------
        angle : Profile, number or callable, optional
            ``angle_0 + angle(t)`` [rad]; ``angle(0)`` must be 0.
        speed : Profile or number, optional
            Angular speed [rad per time unit]: the drive angle is ``angle_0 + int_0^t speed``,
            integrated exactly (:meth:`Profile.integral`), so ``speed`` must be a profile with
            a closed-form integral (Constant, Linear, Polynomial, Ramp, SmoothStep, Sine, and
            sums and multiples of them). A speed that is not 0 at ``t = 0`` starts the
            mechanism moving: when no body has an initial velocity, consistent ones are
            computed at compile time (``morphlab.compile.initial``).

        Raises
        ------
        ModelError
            Neither or both of ``angle`` and ``speed``; a speed profile without a closed-form
            integral; ``angle(0) != 0``.
        """
        return self.add(Drive(name, body, angle, at, speed))

    def add_gear(self, a, b, *, ratio, at_a=None, at_b=None, name=None) -> Gear:
        """Couple the rotations of ``a`` and ``b``: ``(theta_a + phi_a) - ratio (theta_b +
        phi_b)`` stays at its initial value (a gear pair, a belt, a coupler; :class:`Gear`).

        Parameters
        ----------
        a, b : Body or str
            The bodies (or their names; either may be the ground).
        ratio : float
            Turn of ``a`` per turn of ``b`` (teeth of ``b`` / teeth of ``a``), nonzero;
            negative when the senses are opposite (an external gear pair).
        at_a, at_b : (2,), optional
            The beam node whose rotation counts, needed where a side is a beam (global
            coordinates of the initial configuration).

        Raises
        ------
        ModelError
            A ratio that is zero or not a finite number, unknown bodies or bodies of another
            model, a body coupled to itself, a missing or off-node point on a beam.
        """
        return self.add(Gear(name, a, b, ratio, at_a, at_b))

    # ---- loads (morphlab.model.loads)
    def add_force(self, body, *, at, force, profile=None, name=None,
                  follower: bool = False) -> Force:
        """Apply ``force * profile(t)`` [N] at the point ``at`` of ``body``: of fixed global
        direction, or with ``follower`` a force that turns with the material point's rotation
        (:class:`~morphlab.model.pressure.FollowerForce`; ``force`` then gives its components
        in the initial configuration)."""
        if not isinstance(follower, (bool, np.bool_)):
            raise ModelError(f"force {name!r}: follower must be True or False, got "
                             f"{_show(follower)}")
        return self.add((FollowerForce if follower else Force)(body, at, force, profile, name))

    def add_torque(self, body, magnitude, *, profile=None, at=None, name=None) -> Torque:
        """Apply a torque ``magnitude * profile(t)`` [N·mm] to ``body`` (at the beam node ``at``
        when given: the torque then also works on that node's rotation)."""
        return self.add(Torque(body, magnitude, profile, at, name))

    # ---- force elements (morphlab.model.forces; docs/theory.md §4.6)
    def add_spring(self, name, body_a, body_b, *, at_a, at_b, stiffness, damping=0.0,
                   rest_length=None, preload=0.0) -> Spring:
        """Add a translational spring-damper between the point ``at_a`` of ``body_a`` and the
        point ``at_b`` of ``body_b`` (global points of the initial configuration, nodes on a
        beam; either body may be the ground).

        Its tension ``f = stiffness (l - rest_length) + damping dl/dt + preload`` [N] acts along
        the line between the points (positive pulls them together); ``l`` is their distance.

        Parameters
        ----------
        stiffness : float >= 0
            [N/mm].
        damping : float >= 0
            [N·s/mm].
        rest_length : float >= 0, optional
            [mm]; default the initial distance of the points.
        preload : float
            Constant tension [N] (negative: compression).

        Raises
        ------
        ModelError
            Unknown bodies, a point that is not a node of a beam, negative stiffness, damping
            or rest length, coinciding points (the direction of the force is undefined), a name
            already used.
        """
        return self.add(Spring(name, body_a, body_b, at_a, at_b, stiffness, damping,
                               rest_length, preload))

    def add_rotational_spring(self, name, joint_or_bodies, *, at_a=None, at_b=None, stiffness,
                              damping=0.0, rest_angle=None, preload=0.0) -> RotationalSpring:
        """Add a torsion spring-damper on the relative rotation ``psi`` of two bodies: across a
        revolute joint (the joint or its name), or between a pair ``(body_a, body_b)`` (``at_a``
        / ``at_b``: the node of a beam side, whose nodal rotation then counts; either body may
        be the ground).

        Its moment ``M = stiffness (psi - rest_angle) + damping dpsi/dt + preload`` [N·mm]
        turns ``body_b`` forward and ``body_a`` back (``psi``: the rotation of ``a`` relative to
        ``b``, counter-clockwise positive, counted from the initial configuration).

        Parameters
        ----------
        stiffness : float >= 0
            [N·mm/rad].
        damping : float >= 0
            [N·mm·s/rad].
        rest_angle : float, optional
            Relative rotation from the initial configuration at which the spring is relaxed
            [rad]; default 0 (relaxed initially).
        preload : float
            Constant moment [N·mm].
        """
        pair = isinstance(joint_or_bodies, (tuple, list)) and len(joint_or_bodies) == 2
        a, b = joint_or_bodies if pair else (None, None)
        return self.add(RotationalSpring(name, a, b, at_a, at_b, stiffness, damping, rest_angle,
                                         preload, joint=None if pair else joint_or_bodies))

    def add_line_load(self, name, beam, *, q, profile=None, elements=None) -> LineLoad:
        """Add a distributed load ``q * profile(t)`` of fixed global direction on a beam.

        Parameters
        ----------
        q : (2,)
            Force per unit length of the undeformed beam, global frame [N/mm].
        profile : Profile, number or callable, optional
            Time factor (default 1).
        elements : sequence of int, optional
            Element indices of the beam (0 to n_elements - 1) the load acts on; default all.

        The load is applied consistently with the beam's shape functions (work-equivalent),
        on every floating frame that holds a loaded element.
        """
        return self.add(LineLoad(name, beam, q, profile, elements))

    def add_pressure(self, name, beam, p, *, profile=None, elements=None,
                     width=None) -> Pressure:
        """Add a follower pressure on a beam: normal to the deformed centre line
        (:mod:`morphlab.kernels.pressure`, ``docs/theory.md`` §4.7).

        Parameters
        ----------
        p : float, (n_nodes,) or callable
            Pressure [MPa = N/mm²]: one value, one per node of the beam (linear along each
            element), or ``p(xy)`` of the undeformed nodes (n_nodes, 2) [mm] returning one
            per node. Positive ``p`` pushes along the left normal of the direction from the
            first node to the last (on a ring numbered counter-clockwise: inwards).
        profile : Profile, number or callable, optional
            Time factor (default 1).
        elements : sequence of int, optional
            Element indices of the beam the pressure acts on; default all.
        width : float or (n_elements,), optional
            Out-of-plane width [mm] the pressure acts on; default the beam's section width.
        """
        return self.add(Pressure(name, beam, p, width, profile, elements))

    def __repr__(self) -> str:
        counts = ", ".join(f"{len(getattr(self, c))} {c.replace('_', ' ')}" for c in COLLECTIONS)
        return f"Model({self.name!r}: {counts})"
