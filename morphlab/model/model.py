"""Declarative model description: bodies, joints, loads and profiles.

A :class:`Model` only *describes* a mechanism; :func:`morphlab.compile.compile_model` turns it into
flat arrays. Points are given in global coordinates of the initial (undeformed) configuration;
on a beam, joints and loads sit at nodes. Values may be complex (complex-step differentiation
through a parametric ``build(p)``); validation looks at the real parts.

Every ``add_*`` call validates its arguments before it changes the model, and refuses bad input
with a :class:`~morphlab.errors.ModelError` that names the body, joint, load or parameter and
says what would be valid: numbers must be finite numbers of the right shape (no strings,
``None``, booleans, NaN or Inf), physical parameters positive, names unique non-empty strings,
points on a beam at one of its nodes. What needs the whole model (redundant or conflicting
constraints, an inconsistent initial configuration) is checked by ``compile_model``.
"""

from __future__ import annotations

import numpy as np

from ..errors import ModelError
from .bodies import Beam, Body, Ground, RigidBody
from .forces import (
    LineLoad,
    RotationalSpring,
    Spring,
    make_line_load,
    make_rotational_spring,
    make_spring,
)
from .frames import drive_node
from .joints import Drive, Fix, Joint, Prismatic, Revolute, Weld
from .loads import Force, Torque
from .pressure import FollowerForce, Pressure, make_pressure
from .values import _check_name, _numeric, _point, _profile, _real, _show, _upcast


class Model:
    """A planar flexible multibody model.

    Parameters
    ----------
    gravity : (2,)
        Gravitational acceleration [mm/s² in the morphing units], default none.
    name : str
        Used in messages and saved files.

    Examples
    --------
    >>> import morphlab as ml
    >>> m = ml.Model(gravity=(0.0, -9.81e3))
    >>> link = m.add_rigid_body(mass=1e-3, inertia=1.0, position=(50.0, 0.0), name="link")
    >>> j = m.add_revolute(m.ground, link, at=(0.0, 0.0))
    """

    def __init__(self, gravity=(0.0, 0.0), name: str = "model"):
        self.name = _check_name(name, "model")
        self.gravity = _point(gravity, "gravity", f"model {name!r}")
        self.ground = Ground()
        self.ground._model = self
        self.bodies: list[Body] = []
        self.joints: list[Joint] = []
        self.forces: list[Force] = []
        self.torques: list[Torque] = []
        self.springs: list[Spring | RotationalSpring] = []
        self.line_loads: list[LineLoad] = []
        self.pressures: list[Pressure] = []

    # ---- bodies
    def _register(self, body: Body) -> Body:
        if not isinstance(body.name, str) or not body.name:
            raise ModelError(f"bodies need a non-empty string name, got {body.name!r}")
        if body._model is not None and body._model is not self:
            raise ModelError(f"body {body.name!r} already belongs to model {body._model.name!r};"
                             " a body can be part of one model only: create a new one")
        if body.name == "ground" or any(b.name == body.name for b in self.bodies):
            raise ModelError(f"model {self.name!r}: a body named {body.name!r} already exists "
                             "('ground' is reserved); body names must be unique")
        body._model = self
        self.bodies.append(body)
        return body

    def add_body(self, body: Body) -> Body:
        """Add a ready-made :class:`RigidBody` or :class:`Beam`."""
        if not isinstance(body, (RigidBody, Beam)):
            raise ModelError(f"add_body expects a RigidBody or Beam, got {type(body).__name__}")
        return self._register(body)

    def add_beam(self, nodes, *, E, rho, thickness=None, width=None, area=None,
                 second_moment=None, fibre=None, damping=0.0, frames=None, reference=None,
                 reference_node=None, name=None) -> Beam:
        """Add a flexible :class:`Beam` (see there for the parameters and units)."""
        name = f"beam{len(self.bodies)}" if name is None else name
        return self._register(Beam(nodes, E=E, rho=rho, thickness=thickness, width=width,
                                   area=area, second_moment=second_moment, fibre=fibre,
                                   damping=damping, frames=frames, reference=reference,
                                   reference_node=reference_node, name=name))

    def add_rigid_body(self, *, mass, inertia, position, angle=0.0, velocity=(0.0, 0.0),
                       angular_velocity=0.0, name=None) -> RigidBody:
        """Add a :class:`RigidBody` (reference point = centre of mass)."""
        name = f"body{len(self.bodies)}" if name is None else name
        return self._register(RigidBody(mass, inertia, position, angle, velocity=velocity,
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

    # ---- joints
    def _own(self, body, what):
        if isinstance(body, str):
            body = self.body(body)
        if not isinstance(body, Body):
            raise ModelError(f"{what}: expected a body of this model or its name, "
                             f"got {_show(body)}")
        if body is not self.ground and not any(body is b for b in self.bodies):
            other = body._model.name if body._model is not None else None
            where = f" (it belongs to model {other!r})" if other is not None else ""
            raise ModelError(f"{what}: body {body.name!r} is not part of model "
                             f"{self.name!r}{where}; add it to this model first")
        return body

    def _joint_name(self, name, prefix):
        name = f"{prefix}{len(self.joints)}" if name is None else _check_name(name, "joint")
        if any(j.name == name for j in self.joints):
            raise ModelError(f"model {self.name!r}: a joint named {name!r} already exists")
        return name

    def _load_name(self, name, prefix, count):
        """A unique name among the loads and force elements (``prefix<count>`` by default)."""
        name = f"{prefix}{count}" if name is None else _check_name(name, "load")
        if any(ld.name == name for ld in self.forces + self.torques + self.springs
               + self.line_loads):
            raise ModelError(f"model {self.name!r}: a load named {name!r} already exists "
                             "(loads and force elements share one set of names)")
        return name

    def _check_point_on(self, body, at, what):
        """``at`` as a point; on a beam it must be a node (to 1e-6 of the beam's size, at least
        1e-6 length units) and the node's exact coordinates are returned, so every side of a
        joint sees one point. Any point of the plane is a material point of a rigid body."""
        at = _point(at, "at", what)
        if isinstance(body, Beam):
            k, dist = body.nearest_node(at)
            tol = 1e-6 * max(body.size, 1.0)
            if dist > tol:
                node = tuple(float(x) for x in np.round(_real(body.nodes[k]), 6))
                raise ModelError(
                    f"{what}: point {tuple(float(x) for x in np.round(_real(at), 6))} is not at "
                    f"a node of beam {body.name!r}; nearest is node {k} at {node}, distance "
                    f"{dist:.6g} (tolerance {tol:.3g}). Joints and loads act at beam nodes: use "
                    "that node's coordinates or add a node there"
                )
            return body.nodes[k].copy()
        return at

    def add_revolute(self, a, b, *, at, name=None) -> Revolute:
        """Pin ``a`` and ``b`` together at the global point ``at`` (a node if on a beam)."""
        name = self._joint_name(name, "revolute")
        a, b = self._own(a, f"revolute {name!r}"), self._own(b, f"revolute {name!r}")
        if a is b:
            raise ModelError(f"revolute {name!r}: connects body {a.name!r} to itself")
        for body in (a, b):
            at = self._check_point_on(body, at, f"revolute {name!r}")
        j = Revolute(name, a, b, at)
        self.joints.append(j)
        return j

    def add_weld(self, a, b, *, at, name=None) -> Weld:
        """Rigidly connect ``a`` and ``b`` at ``at`` (position and relative angle held)."""
        name = self._joint_name(name, "weld")
        a, b = self._own(a, f"weld {name!r}"), self._own(b, f"weld {name!r}")
        if a is b:
            raise ModelError(f"weld {name!r}: connects body {a.name!r} to itself")
        for body in (a, b):
            at = self._check_point_on(body, at, f"weld {name!r}")
        j = Weld(name, a, b, at)
        self.joints.append(j)
        return j

    def add_prismatic(self, a, b, *, at, axis, name=None) -> Prismatic:
        """Let ``b`` slide along ``a``: the point of ``b`` at ``at`` (a node if on a beam)
        stays on the line through ``at`` with direction ``axis`` (global, initial
        configuration; any length) fixed in ``a`` (or the ground), and the relative rotation of
        ``a`` and ``b`` is locked. Its reaction (:meth:`Result.reaction`) is the guide's
        action on ``b``: the normal force and the locking moment."""
        name = self._joint_name(name, "prismatic")
        what = f"prismatic {name!r}"
        a, b = self._own(a, what), self._own(b, what)
        if a is b:
            raise ModelError(f"{what}: connects body {a.name!r} to itself")
        for body in (a, b):
            at = self._check_point_on(body, at, what)
        axis = _point(axis, "axis", what)
        if not np.hypot(*_real(axis)) > 0:
            raise ModelError(f"{what}: axis must be a nonzero direction (x, y), got "
                             f"{_show(axis)}")
        j = Prismatic(name, a, b, at, axis)
        self.joints.append(j)
        return j

    def add_fix(self, body, *, at, dofs="xyr", name=None) -> Fix:
        """Fix any of ``x``, ``y``, ``r`` (rotation) of the point ``at`` of ``body`` to ground."""
        name = self._joint_name(name, "fix")
        body = self._own(body, f"fix {name!r}")
        if body is self.ground:
            raise ModelError(f"fix {name!r}: the ground is fixed already")
        if not isinstance(dofs, str) or not dofs or set(dofs) - set("xyr") or len(set(dofs)) != len(
            dofs
        ):
            raise ModelError(
                f"fix {name!r}: dofs must be a non-empty string of distinct letters from 'x', "
                f"'y', 'r', got {dofs!r}"
            )
        at = self._check_point_on(body, at, f"fix {name!r}")
        j = Fix(name, body, at, "".join(sorted(dofs, key="xyr".index)))
        self.joints.append(j)
        return j

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
        name = self._joint_name(name, "drive")
        body = self._own(body, f"drive {name!r}")
        if body is self.ground:
            raise ModelError(f"drive {name!r}: cannot drive the ground")
        if (angle is None) == (speed is None):
            raise ModelError(f"drive {name!r}: give exactly one of angle= (a profile of the "
                             "angle, 0 at t=0) and speed= (a profile of the angular speed)")
        if speed is not None:
            spd = _profile(speed, f"drive {name!r} speed")
            try:
                prof = spd.integral(0.0)
            except ModelError as exc:
                raise ModelError(f"drive {name!r}: speed= needs a profile with a closed-form "
                                 f"integral: {exc}") from None
        else:
            prof = _profile(angle, f"drive {name!r}")
        f0 = _real(prof.value(0.0))
        if abs(f0) > 1e-12:
            raise ModelError(
                f"drive {name!r}: angle(0) must be 0 (the drive is relative to the initial angle),"
                f" got {f0:.6g}"
            )
        if at is not None:
            at = self._check_point_on(body, at, f"drive {name!r}")
        elif isinstance(body, Beam):
            at = body.nodes[drive_node(body)]
        j = Drive(name, body, prof, at)
        self.joints.append(j)
        return j

    # ---- loads
    def add_force(self, body, *, at, force, profile=None, name=None,
                  follower: bool = False) -> Force:
        """Apply ``force * profile(t)`` [N] at the point ``at`` of ``body``: of fixed global
        direction, or with ``follower`` a force that turns with the material point's rotation
        (:class:`~morphlab.model.pressure.FollowerForce`; ``force`` then gives its components
        in the initial configuration)."""
        name = self._load_name(name, "force", len(self.forces))
        body = self._own(body, f"force {name!r}")
        if body is self.ground:
            raise ModelError(f"force {name!r}: cannot load the ground")
        at = self._check_point_on(body, at, f"force {name!r}")
        f = _point(force, "force", f"force {name!r}")
        if not isinstance(follower, (bool, np.bool_)):
            raise ModelError(f"force {name!r}: follower must be True or False, got "
                             f"{_show(follower)}")
        cls = FollowerForce if follower else Force
        ld = cls(body, at, f, _profile(profile, f"force {name!r}"), name)
        self.forces.append(ld)
        return ld

    def add_torque(self, body, magnitude, *, profile=None, at=None, name=None) -> Torque:
        """Apply a torque ``magnitude * profile(t)`` [N·mm] to ``body`` (at the beam node ``at``
        when given: the torque then also works on that node's rotation)."""
        name = self._load_name(name, "torque", len(self.torques))
        body = self._own(body, f"torque {name!r}")
        if body is self.ground:
            raise ModelError(f"torque {name!r}: cannot load the ground")
        _numeric(magnitude, "magnitude", f"torque {name!r}")
        magnitude = _upcast(magnitude)
        if at is not None:
            at = self._check_point_on(body, at, f"torque {name!r}")
        tq = Torque(body, magnitude, _profile(profile, f"torque {name!r}"), at, name)
        self.torques.append(tq)
        return tq

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
        name = self._load_name(name, "spring", len(self.springs))
        sp = make_spring(self, name, body_a, body_b, at_a, at_b, stiffness, damping,
                         rest_length, preload)
        self.springs.append(sp)
        return sp

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
        name = self._load_name(name, "rotational_spring", len(self.springs))
        sp = make_rotational_spring(self, name, joint_or_bodies, at_a, at_b, stiffness,
                                    damping, rest_angle, preload)
        self.springs.append(sp)
        return sp

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
        name = self._load_name(name, "line_load", len(self.line_loads))
        ld = make_line_load(self, name, beam, q, profile, elements)
        self.line_loads.append(ld)
        return ld

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
        name = self._load_name(name, "pressure", len(self.pressures))
        pr = make_pressure(self, name, beam, p, profile, elements, width)
        self.pressures.append(pr)
        return pr

    def __repr__(self) -> str:
        return (f"Model({self.name!r}: {len(self.bodies)} bodies, {len(self.joints)} joints, "
                f"{len(self.forces)} forces, {len(self.torques)} torques, "
                f"{len(self.springs)} springs, {len(self.line_loads)} line loads, "
                f"{len(self.pressures)} pressures)")
