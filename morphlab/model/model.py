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

import cmath
import functools
from dataclasses import dataclass, field

import numpy as np

from ..errors import ModelError
from .frames import drive_node, frame_offsets
from .frames import resolve as resolve_frames
from .profiles import Constant, Profile, as_profile


def _real(x):
    return np.real(np.asarray(x))


def _show(value, limit=60) -> str:
    """Short ``repr`` of a user value for error messages."""
    text = repr(value)
    return text if len(text) <= limit else text[: limit - 3] + "..."


def _upcast(value):
    """NumPy values of less than double precision as float64/complex128 (the same numbers):
    joint geometry and the compiled system are computed in double precision, and a float32
    angle would put its round-off (~1e-7) into the initial constraint violation."""
    if isinstance(value, (np.ndarray, np.generic)):
        kind, size = value.dtype.kind, value.dtype.itemsize
        if kind == "f" and size < 8:
            return value.astype(np.float64)
        if kind == "c" and size < 16:
            return value.astype(np.complex128)
    return value


def _has_bool(value) -> bool:
    """True for a bool, or a list/tuple holding one (NumPy would silently turn it into 0/1)."""
    if isinstance(value, (bool, np.bool_)):
        return True
    return isinstance(value, (list, tuple)) and any(_has_bool(v) for v in value)


_PLAIN = (int, float, complex, np.float64, np.complex128, np.int64)


def _plain_numbers(value, shape) -> bool | None:
    """For a Python number (``shape == ()``) or a tuple of them of length ``shape[0]``: are
    they all finite? None for anything else (bool is not a number here)."""
    if shape == ():
        items = (value,)
    elif len(shape) == 1 and type(value) is tuple and len(value) == shape[0]:
        items = value
    else:
        return None
    if not all(type(x) in _PLAIN for x in items):
        return None
    return all(cmath.isfinite(x) for x in items)


def _numeric(value, what, owner, shape=(), expect="a finite number"):
    """``value`` as a numeric (integer, real or complex) array of ``shape``, all entries finite.

    Rejects what NumPy would otherwise let through or fail on later with an unrelated message:
    strings, ``None``, booleans, objects, ragged sequences, wrong shapes, NaN and Inf (real or
    imaginary part). Complex values are allowed (complex-step differentiation).
    """
    fast = _plain_numbers(value, shape)
    if fast is not None:  # Python numbers (the common case, without NumPy's reductions)
        if fast:
            return np.asarray(value)
        raise ModelError(f"{owner}: {what} must be {expect} (no NaN or Inf), got {_show(value)}")
    try:
        arr = None if _has_bool(value) else np.asarray(value)
    except (TypeError, ValueError, OverflowError):  # ragged or unconvertible sequences
        arr = None
    if arr is None or arr.dtype.kind not in "iufc" or arr.shape != shape:
        raise ModelError(f"{owner}: {what} must be {expect}, got {_show(value)}")
    if not np.all(np.isfinite(arr)):
        raise ModelError(f"{owner}: {what} must be {expect} (no NaN or Inf), got {_show(value)}")
    return _upcast(arr)


def _finite_positive(value, what, owner):
    v = _real(_numeric(value, what, owner, expect="a finite positive number"))
    if not v > 0:
        raise ModelError(f"{owner}: {what} must be a finite positive number, got {_show(value)}")
    return _upcast(value)


def _section_positive(value, what, owner, n_elem):
    """A positive section/material value: a scalar, or one value per element (n_elem,)."""
    if np.ndim(value) == 1 and not isinstance(value, (str, bytes)):
        arr = _numeric(value, what, owner, shape=(n_elem,),
                       expect=f"a finite positive number or an array of {n_elem} of them "
                              "(one per element)")
        if not np.all(_real(arr) > 0):
            k = int(np.flatnonzero(~(_real(arr) > 0))[0])
            raise ModelError(f"{owner}: {what} of element {k} must be positive, got "
                             f"{_show(arr[k])}")
        return arr
    return _finite_positive(value, what, owner)


def _point(at, what, owner):
    return _numeric(at, what, owner, shape=(2,), expect="a finite pair (x, y) of numbers")


def _check_name(name, kind):
    """A user-given name must be a non-empty string."""
    if not isinstance(name, str) or not name:
        raise ModelError(f"{kind} names must be non-empty strings, got {_show(name)}")
    return name


def _profile(obj, owner):
    """``obj`` as a :class:`Profile` whose value at ``t = 0`` is a finite number."""
    if isinstance(obj, (bool, np.bool_)):
        raise ModelError(f"{owner}: profile must be a Profile, a number or a callable f(t), "
                         f"got {obj!r}")
    prof = as_profile(obj, owner)
    try:
        f0 = prof.value(0.0)
    except Exception as exc:  # a user callable: report which one failed, keep the cause
        raise ModelError(f"{owner}: evaluating the profile at t=0 failed: "
                         f"{type(exc).__name__}: {exc}") from exc
    _numeric(f0, "the profile value at t=0", owner)
    return prof


class Body:
    """Base of all bodies. ``name`` is unique within a model."""

    name: str
    _model: Model | None = None

    def __repr__(self) -> str:
        return f"{type(self).__name__}({self.name!r})"


class Ground(Body):
    """The fixed inertial frame (no DOFs). Every model has exactly one: ``model.ground``."""

    def __init__(self):
        self.name = "ground"


class RigidBody(Body):
    """A rigid body with its reference point at the centre of mass.

    Parameters
    ----------
    mass : float
        Mass [t in the morphing model].
    inertia : float
        Moment of inertia about the centre of mass [t·mm²].
    position : (2,)
        Initial position of the centre of mass, global [mm].
    angle : float
        Initial angle of the body frame [rad].
    velocity, angular_velocity :
        Initial velocity of the centre of mass and angular velocity (must satisfy the
        velocity-level constraints).
    """

    def __init__(self, mass, inertia, position, angle=0.0, *, velocity=(0.0, 0.0),
                 angular_velocity=0.0, name):
        self.name = _check_name(name, "body")
        owner = f"rigid body {name!r}"
        self.mass = _finite_positive(mass, "mass", owner)
        self.inertia = _finite_positive(inertia, "inertia", owner)
        self.position = _point(position, "position", owner)
        _numeric(angle, "angle [rad]", owner)
        self.angle = _upcast(angle)
        self.velocity = _point(velocity, "velocity", owner)
        _numeric(angular_velocity, "angular_velocity [rad/s]", owner)
        self.angular_velocity = _upcast(angular_velocity)


class Beam(Body):
    """A flexible body of planar Euler–Bernoulli elements along a polyline of nodes (FFRF).

    Parameters
    ----------
    nodes : (n_node, 2)
        Initial global node positions [mm]; element ``e`` joins nodes ``e`` and ``e + 1``.
    E, rho : float or (n_elem,)
        Young's modulus [MPa] and density [t/mm³].
    thickness, width : float or (n_elem,), optional
        Rectangular section (in-plane thickness ``t`` and out-of-plane width ``b``) [mm]:
        ``A = b t``, ``I = b t³/12``, fibre distance ``t/2``.
    area, second_moment, fibre : float or (n_elem,), optional
        General section instead of a rectangle [mm², mm⁴, mm].

    Every material and section value is a scalar or one value per element.
    damping : float
        Stiffness-proportional damping coefficient ``beta_d`` [s]: ``D = beta_d K``.
    frames : int or "element", optional
        Number of floating frames (1 to the number of elements), or ``"element"`` (the
        default) for one per element: consecutive groups of elements as equal as possible,
        the longer groups first (:attr:`frame_offsets`), joined rigidly at their shared nodes.
    reference : {"chord", "first", "middle"}, optional
        Where each frame sits: ``"chord"`` (default) through the group's two end nodes (u, v
        of the first node and v of the last removed), ``"first"`` / ``"middle"`` the tangent
        frame at the group's first / middle node (its u, v, phi removed).
    reference_node : int, optional
        The single tangent frame at this node (its deformation DOFs are zero), x axis along
        the element that starts there (the one that ends there for the last node); excludes
        ``frames`` other than 1 and ``reference``.

    Notes
    -----
    Accuracy against cost of the frame choices: ``docs/frames.md``.
    """

    def __init__(self, nodes, *, E, rho, thickness=None, width=None, area=None,
                 second_moment=None, fibre=None, damping=0.0, frames=None, reference=None,
                 reference_node=None, name):
        self.name = _check_name(name, "body")
        owner = f"beam {name!r}"
        try:
            X = np.asarray(None if _has_bool(nodes) else nodes)
        except (TypeError, ValueError, OverflowError):  # ragged sequences
            X = np.asarray(None)
        if X.dtype.kind not in "iufc" or X.ndim != 2 or X.shape[1] != 2:
            raise ModelError(f"{owner}: nodes must be an (n, 2) array of numbers (x, y per row), "
                             f"got {_show(nodes)} (shape {X.shape}, dtype {X.dtype})")
        if X.shape[0] < 2:
            raise ModelError(f"{owner}: needs at least two nodes, got {X.shape[0]}")
        if not np.all(np.isfinite(X)):
            bad = int(np.argwhere(~np.isfinite(X))[0, 0])
            raise ModelError(f"{owner}: node {bad} has a non-finite coordinate {X[bad]!r}; "
                             "node coordinates must be finite numbers")
        seg = np.hypot(*np.diff(_real(X), axis=0).T)
        scale = max(float(np.ptp(_real(X), axis=0).max()), 1e-300)
        short = np.flatnonzero(seg <= 1e-12 * scale)
        if short.size:
            e = int(short[0])
            raise ModelError(
                f"{owner}: nodes {e} and {e + 1} coincide (element {e} has length {seg[e]:.3g});"
                " consecutive nodes must be distinct"
            )
        self.nodes = _upcast(X)
        n_el = X.shape[0] - 1

        def positive(value, what):
            return _section_positive(value, what, owner, n_el)

        self.E = positive(E, "E")
        self.rho = positive(rho, "rho")
        if thickness is not None or width is not None:
            if thickness is None or width is None:
                raise ModelError(f"{owner}: a rectangular section needs both thickness and width")
            if area is not None or second_moment is not None:
                raise ModelError(f"{owner}: give thickness/width or area/second_moment, not both")
            thickness = positive(thickness, "thickness")
            width = positive(width, "width")
            area = width * thickness
            # a product, not thickness**3: Python floats raise OverflowError on a huge power
            second_moment = width * thickness * thickness * thickness / 12.0
            fibre = thickness / 2.0 if fibre is None else fibre
            derived = " (= width thickness^3 / 12 from the rectangular section)"
        elif area is None or second_moment is None:
            raise ModelError(
                f"{owner}: section missing: give thickness and width, or area and second_moment"
            )
        else:
            derived = ""
        self.thickness = thickness
        self.width = width
        self.area = positive(area, "area")
        self.second_moment = positive(second_moment, f"second_moment{derived}")
        self.fibre = positive(fibre, "fibre") if fibre is not None else 0.0 * area
        d = _real(_numeric(damping, "damping [s]", owner, expect="a finite number >= 0"))
        if d < 0:
            raise ModelError(f"{owner}: damping [s] must be a finite number >= 0, got {damping!r}")
        self.damping = _upcast(damping)
        self.frames, self.reference, self.reference_node = resolve_frames(
            frames, reference, reference_node, n_el, owner)

    @property
    def frame_offsets(self) -> np.ndarray:
        """First element of each frame, then the number of elements, (frames + 1,) int64."""
        return frame_offsets(self.n_elements, self.frames)

    @property
    def n_nodes(self) -> int:
        return self.nodes.shape[0]

    @functools.cached_property
    def size(self) -> float:
        """Largest extent of the undeformed beam along x or y [length] (real parts)."""
        return float(np.ptp(_real(self.nodes), axis=0).max())

    @property
    def n_elements(self) -> int:
        return self.nodes.shape[0] - 1

    def nearest_node(self, at) -> tuple[int, float]:
        """Index of the node nearest to ``at`` (real parts) and its distance."""
        d = np.hypot(*(_real(self.nodes) - _real(np.asarray(at))).T)
        k = int(np.argmin(d))
        return k, float(d[k])


@dataclass(eq=False)
class Joint:
    """Base of joints; ``name`` is unique within a model."""

    name: str


@dataclass(eq=False)
class Revolute(Joint):
    """Pin joint: the material points of ``a`` and ``b`` at ``at`` coincide (2 rows)."""

    a: Body
    b: Body
    at: np.ndarray


@dataclass(eq=False)
class Weld(Joint):
    """Rigid joint: revolute plus the relative rotation at ``at`` kept at its initial value."""

    a: Body
    b: Body
    at: np.ndarray


@dataclass(eq=False)
class Prismatic(Joint):
    """Slider: the material point of ``b`` at ``at`` moves along the line through ``at`` with
    direction ``axis`` fixed in ``a`` (in the frame of the beam node at ``at`` when ``a`` is a
    beam), and the relative rotation of ``a`` and ``b`` is held at its initial value (2 rows)."""

    a: Body
    b: Body
    at: np.ndarray
    axis: np.ndarray


@dataclass(eq=False)
class Fix(Joint):
    """Ground constraint on a subset of x, y and rotation of the point ``at`` of ``body``."""

    body: Body
    at: np.ndarray
    dofs: str


@dataclass(eq=False)
class Drive(Joint):
    """Prescribed rotation: ``angle(t) = angle_0 + f(t)`` of the body (or of a beam node at
    ``at``); ``f(0)`` must be 0 so that the initial configuration is consistent. A drive by
    speed holds ``f = speed.integral()``."""

    body: Body
    profile: Profile
    at: np.ndarray | None = None


@dataclass(eq=False)
class Force:
    """A force of fixed global direction at a material point: ``F(t) = force * profile(t)``."""

    body: Body
    at: np.ndarray
    force: np.ndarray
    profile: Profile = field(default_factory=Constant)
    name: str = ""


@dataclass(eq=False)
class Torque:
    """A torque ``T(t) = magnitude * profile(t)`` on a body (and on the nodal rotation of the
    beam node at ``at``, when given)."""

    body: Body
    magnitude: object
    profile: Profile = field(default_factory=Constant)
    at: np.ndarray | None = None
    name: str = ""


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
        name = f"{prefix}{count}" if name is None else _check_name(name, "load")
        if any(ld.name == name for ld in self.forces + self.torques):
            raise ModelError(f"model {self.name!r}: a load named {name!r} already exists")
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
    def add_force(self, body, *, at, force, profile=None, name=None) -> Force:
        """Apply ``force * profile(t)`` (global direction) at the point ``at`` of ``body``."""
        name = self._load_name(name, "force", len(self.forces))
        body = self._own(body, f"force {name!r}")
        if body is self.ground:
            raise ModelError(f"force {name!r}: cannot load the ground")
        at = self._check_point_on(body, at, f"force {name!r}")
        f = _point(force, "force", f"force {name!r}")
        ld = Force(body, at, f, _profile(profile, f"force {name!r}"), name)
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

    def __repr__(self) -> str:
        return (f"Model({self.name!r}: {len(self.bodies)} bodies, {len(self.joints)} joints, "
                f"{len(self.forces)} forces, {len(self.torques)} torques)")
