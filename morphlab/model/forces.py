"""Force elements of a model: translational and rotational spring-dampers and line loads on
beams (descriptions and their validation; compiled by :mod:`morphlab.compile.forces`,
formulation ``docs/theory.md`` §4.6).

The ``make_*`` functions check every argument before anything is added and refuse bad input
with a :class:`~morphlab.errors.ModelError` naming the element; :class:`~morphlab.model.Model`
calls them from ``add_spring``, ``add_rotational_spring`` and ``add_line_load``.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..errors import ModelError
from .bodies import Beam, Body, Ground
from .joints import Revolute
from .profiles import Constant, Profile
from .values import _numeric, _point, _profile, _real, _show, _upcast


@dataclass(eq=False)
class Spring:
    """Translational spring-damper between the material point of ``a`` at ``at_a`` and that
    of ``b`` at ``at_b`` (global points of the initial configuration). Its tension is
    ``f = stiffness (l - rest_length) + damping dl/dt + preload`` along the line between the
    points; ``rest_length`` None means the initial distance."""

    name: str
    a: Body
    b: Body
    at_a: np.ndarray
    at_b: np.ndarray
    stiffness: object
    damping: object = 0.0
    rest_length: object = None
    preload: object = 0.0


@dataclass(eq=False)
class RotationalSpring:
    """Torsion spring-damper on the relative rotation ``psi`` of ``a`` against ``b`` (each the
    body's angle, plus the nodal rotation of the beam node at ``at_a`` / ``at_b``). Its moment is
    ``M = stiffness (psi - rest_angle) + damping dpsi/dt + preload``, with ``psi`` counted from
    the initial configuration."""

    name: str
    a: Body
    b: Body
    at_a: np.ndarray | None
    at_b: np.ndarray | None
    stiffness: object
    damping: object = 0.0
    rest_angle: object = 0.0
    preload: object = 0.0


@dataclass(eq=False)
class LineLoad:
    """A distributed load ``q * profile(t)`` [force per length of the undeformed beam] of fixed
    global direction on the elements ``elements`` of ``beam``."""

    name: str
    beam: Beam
    q: np.ndarray
    profile: Profile = field(default_factory=Constant)
    elements: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))


def _body(model, body, owner):
    """``model._own(body)``, an unknown name reported with ``owner``."""
    if isinstance(body, str):
        try:
            return model.body(body)
        except ModelError as exc:
            raise ModelError(f"{owner}: {exc}") from None
    return model._own(body, owner)


def _nonnegative(value, what, owner):
    """A finite number whose real part is >= 0 (complex values pass: a complex step)."""
    v = _numeric(value, what, owner, expect="a finite number >= 0")
    if not _real(v) >= 0:
        raise ModelError(f"{owner}: {what} must be a finite number >= 0, got {_show(value)}")
    return _upcast(value)


def _parameters(owner, stiffness, damping, preload):
    """Stiffness and damping (>= 0) and a preload of any sign, validated."""
    _numeric(preload, "preload", owner)
    return (_nonnegative(stiffness, "stiffness", owner), _nonnegative(damping, "damping", owner),
            _upcast(preload))


def make_spring(model, name, body_a, body_b, at_a, at_b, stiffness, damping, rest_length,
                preload) -> Spring:
    """A validated :class:`Spring` of ``model`` (not yet added)."""
    owner = f"spring {name!r}"
    a, b = _body(model, body_a, owner), _body(model, body_b, owner)
    if a is model.ground and b is model.ground:
        raise ModelError(f"{owner}: both ends are on the ground; attach at least one to a body")
    pa = model._check_point_on(a, at_a, owner)
    pb = model._check_point_on(b, at_b, owner)
    k, c, f0 = _parameters(owner, stiffness, damping, preload)
    if rest_length is not None:
        rest_length = _nonnegative(rest_length, "rest_length", owner)
    d = _real(pa) - _real(pb)
    if not np.hypot(d[0], d[1]) > 0:
        raise ModelError(f"{owner}: its two points coincide at {tuple(_real(pa).tolist())} in "
                         "the initial configuration, where the direction of its force is "
                         "undefined; attach the ends at distinct points")
    return Spring(name, a, b, pa, pb, k, c, rest_length, f0)


def make_rotational_spring(model, name, joint_or_bodies, at_a, at_b, stiffness, damping,
                           rest_angle, preload) -> RotationalSpring:
    """A validated :class:`RotationalSpring` of ``model``: across the revolute joint
    ``joint_or_bodies`` (the joint or its name), or between the two bodies of a pair (a beam's
    node given by ``at_a`` / ``at_b``)."""
    owner = f"rotational spring {name!r}"
    if isinstance(joint_or_bodies, (str, Revolute)):
        joint = next((j for j in model.joints if j is joint_or_bodies
                      or j.name == joint_or_bodies), None)
        if not isinstance(joint, Revolute):
            known = ", ".join(repr(j.name) for j in model.joints if isinstance(j, Revolute))
            raise ModelError(f"{owner}: {_show(joint_or_bodies)} is not a revolute joint of "
                             f"model {model.name!r} (revolute joints: {known or 'none'}); give "
                             "a revolute joint or a pair of bodies")
        if at_a is not None or at_b is not None:
            raise ModelError(f"{owner}: across a revolute joint the points are the joint's; "
                             "give at_a / at_b only with a pair of bodies")
        a, b, at_a, at_b = joint.a, joint.b, joint.at, joint.at
    elif isinstance(joint_or_bodies, (tuple, list)) and len(joint_or_bodies) == 2:
        a, b = (_body(model, x, owner) for x in joint_or_bodies)
    else:
        raise ModelError(f"{owner}: expected a revolute joint (or its name) or a pair "
                         f"(body_a, body_b), got {_show(joint_or_bodies)}")
    points = []
    for body, at, key in ((a, at_a, "at_a"), (b, at_b, "at_b")):
        if isinstance(body, Beam):
            if at is None:
                raise ModelError(f"{owner}: {key} (a node of beam {body.name!r}) is needed: "
                                 "the spring acts on that node's rotation")
            at = model._check_point_on(body, at, owner)
        elif at is not None and not isinstance(body, Ground):
            at = _point(at, key, owner)
        points.append(at)
    if a is b and not (isinstance(a, Beam) and np.any(_real(points[0]) != _real(points[1]))):
        raise ModelError(f"{owner}: connects body {a.name!r} to itself (two different nodes "
                         "of one beam are allowed)")
    k, c, f0 = _parameters(owner, stiffness, damping, preload)
    if rest_angle is not None:
        _numeric(rest_angle, "rest_angle", owner)
    rest = 0.0 if rest_angle is None else _upcast(rest_angle)
    return RotationalSpring(name, a, b, points[0], points[1], k, c, rest, f0)


def make_line_load(model, name, beam, q, profile, elements) -> LineLoad:
    """A validated :class:`LineLoad` of ``model``."""
    owner = f"line load {name!r}"
    beam = _body(model, beam, owner)
    if not isinstance(beam, Beam):
        raise ModelError(f"{owner}: a line load acts on a beam, got {type(beam).__name__} "
                         f"{beam.name!r}")
    qv = _point(q, "q", owner)
    n_el = beam.n_elements
    if elements is None:
        idx = np.arange(n_el, dtype=np.int64)
    else:
        try:
            idx = np.asarray(elements)
            ok = idx.ndim == 1 and idx.size > 0 and idx.dtype.kind in "iu"
        except (TypeError, ValueError):
            ok = False
        if not ok or np.any(idx < 0) or np.any(idx >= n_el) or np.unique(idx).size != idx.size:
            raise ModelError(f"{owner}: elements must be distinct element indices of beam "
                             f"{beam.name!r} (0 to {n_el - 1}), or None for all, got "
                             f"{_show(elements)}")
        idx = np.sort(idx.astype(np.int64))
    return LineLoad(name, beam, qv, _profile(profile, owner), idx)
