"""Force elements of a model: translational and rotational spring-dampers and line loads on
beams (descriptions that validate themselves, :meth:`~morphlab.model.items.Item.check`;
compiled by :mod:`morphlab.compile.forces`, formulation ``docs/theory.md`` §4.6). They share
one set of names with the loads.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from ..errors import ModelError
from .bodies import Beam, Body, Ground, body_of, material_point
from .joints import Revolute
from .loads import Load, _BeamLoad
from .profiles import Constant, Profile
from .values import _numeric, _point, _profile, _real, _show, _upcast

if TYPE_CHECKING:
    from .model import Model


def _nonnegative(value, what, owner):
    """A finite number whose real part is >= 0 (complex values pass: a complex step)."""
    v = _numeric(value, what, owner, expect="a finite number >= 0")
    if not _real(v) >= 0:
        raise ModelError(f"{owner}: {what} must be a finite number >= 0, got {_show(value)}")
    return _upcast(value)


class _SpringDamper(Load, collection="springs"):
    """Stiffness and damping (>= 0) and a preload of any sign."""

    def _check_parameters(self) -> None:
        _numeric(self.preload, "preload", self.owner)
        self.stiffness = _nonnegative(self.stiffness, "stiffness", self.owner)
        self.damping = _nonnegative(self.damping, "damping", self.owner)
        self.preload = _upcast(self.preload)


@dataclass(eq=False)
class Spring(_SpringDamper, label="spring"):
    """Translational spring-damper between the material point of ``a`` at ``at_a`` and that
    of ``b`` at ``at_b`` (global points of the initial configuration). Its tension is
    ``f = stiffness (l - rest_length) + damping dl/dt + preload`` along the line between the
    points; ``rest_length`` None means the initial distance. Either body may be the ground;
    points on a beam are nodes."""

    name: str | None
    a: Body | str
    b: Body | str
    at_a: np.ndarray
    at_b: np.ndarray
    stiffness: object
    damping: object = 0.0
    rest_length: object = None
    preload: object = 0.0

    def check(self, model: Model) -> None:
        owner = self.owner
        self.a, self.b = a, b = body_of(model, self.a, owner), body_of(model, self.b, owner)
        if a is model.ground and b is model.ground:
            raise ModelError(f"{owner}: both ends are on the ground; attach at least one to a "
                             "body")
        self.at_a = pa = material_point(a, self.at_a, owner, "at_a")
        self.at_b = pb = material_point(b, self.at_b, owner, "at_b")
        self._check_parameters()
        if self.rest_length is not None:
            self.rest_length = _nonnegative(self.rest_length, "rest_length", owner)
        d = _real(pa) - _real(pb)
        if not np.hypot(d[0], d[1]) > 0:
            raise ModelError(f"{owner}: its two points coincide at {tuple(_real(pa).tolist())} "
                             "in the initial configuration, where the direction of its force "
                             "is undefined; attach the ends at distinct points")


@dataclass(eq=False)
class RotationalSpring(_SpringDamper, label="rotational spring"):
    """Torsion spring-damper on the relative rotation ``psi`` of ``a`` against ``b`` (each the
    body's angle, plus the nodal rotation of the beam node at ``at_a`` / ``at_b``). Its moment is
    ``M = stiffness (psi - rest_angle) + damping dpsi/dt + preload``, with ``psi`` counted from
    the initial configuration (``rest_angle`` None: 0).

    Across a revolute joint: ``joint`` (the joint or its name) instead of ``a``, ``b``,
    ``at_a``, ``at_b``, which :meth:`check` then takes from the joint. A side that is a beam
    needs its node (``at_a`` / ``at_b``); two different nodes of one beam may be joined."""

    name: str | None
    a: Body | str | None
    b: Body | str | None
    at_a: np.ndarray | None
    at_b: np.ndarray | None
    stiffness: object
    damping: object = 0.0
    rest_angle: object = 0.0
    preload: object = 0.0
    joint: Revolute | str | None = None

    def _across(self, model: Model) -> None:
        """Sides and points from :attr:`joint`, a revolute joint of ``model``."""
        given = self.joint
        if not isinstance(given, (str, Revolute)):
            raise ModelError(f"{self.owner}: expected a revolute joint (or its name) or a pair "
                             f"(body_a, body_b), got {_show(given)}")
        joint = next((j for j in model.joints if j is given or j.name == given), None)
        if not isinstance(joint, Revolute):
            known = ", ".join(repr(j.name) for j in model.joints if isinstance(j, Revolute))
            raise ModelError(f"{self.owner}: {_show(given)} is not a revolute joint of model "
                             f"{model.name!r} (revolute joints: {known or 'none'}); give a "
                             "revolute joint or a pair of bodies")
        if any(x is not None for x in (self.a, self.b, self.at_a, self.at_b)):
            raise ModelError(f"{self.owner}: across a revolute joint the bodies and points are "
                             "the joint's; give a, b, at_a / at_b only with a pair of bodies")
        self.joint = joint
        self.a, self.b, self.at_a, self.at_b = joint.a, joint.b, joint.at, joint.at

    def check(self, model: Model) -> None:
        owner = self.owner
        if self.joint is not None:
            self._across(model)
        else:
            self.a, self.b = body_of(model, self.a, owner), body_of(model, self.b, owner)
        points = []
        for body, at, key in ((self.a, self.at_a, "at_a"), (self.b, self.at_b, "at_b")):
            if isinstance(body, Beam):
                if at is None:
                    raise ModelError(f"{owner}: {key} (a node of beam {body.name!r}) is "
                                     "needed: the spring acts on that node's rotation")
                at = material_point(body, at, owner, key)
            elif at is not None and not isinstance(body, Ground):
                at = _point(at, key, owner)
            points.append(at)
        a = self.a
        if a is self.b and not (isinstance(a, Beam)
                                and np.any(_real(points[0]) != _real(points[1]))):
            raise ModelError(f"{owner}: connects body {a.name!r} to itself (two different nodes "
                             "of one beam are allowed)")
        self.at_a, self.at_b = points
        self._check_parameters()
        if self.rest_angle is None:
            self.rest_angle = 0.0
        _numeric(self.rest_angle, "rest_angle", owner)
        self.rest_angle = _upcast(self.rest_angle)


@dataclass(eq=False)
class LineLoad(_BeamLoad, collection="line_loads", label="line load"):
    """A distributed load ``q * profile(t)`` [force per length of the undeformed beam] of fixed
    global direction on the elements ``elements`` of ``beam`` (element indices, 0 to
    ``n_elements - 1``; None: all; :meth:`check` makes them a sorted int64 array)."""

    q: np.ndarray
    profile: Profile = field(default_factory=Constant)
    elements: np.ndarray | None = None

    def check(self, model: Model) -> None:
        self._check_span(model)
        self.q = _point(self.q, "q", self.owner)
        self.profile = _profile(self.profile, self.owner)
