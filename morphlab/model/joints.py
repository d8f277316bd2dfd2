"""The joints and drives of a model: descriptions that validate themselves
(:meth:`~morphlab.model.items.Item.check`); compiled by :mod:`morphlab.compile.joints`.

Bodies may be given by name and points as any pair of numbers: :meth:`check` turns them into
the model's bodies and NumPy points (a beam's exact node). A name left ``None`` is given by
:meth:`Model.add <morphlab.model.Model.add>` (the kind's prefix and the number of joints).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from ..errors import ModelError
from .bodies import Beam, Body, Ground, body_of, material_point
from .frames import drive_node
from .items import Item
from .profiles import Profile
from .values import _numeric, _point, _profile, _real, _show, _upcast

if TYPE_CHECKING:
    from .model import Model


@dataclass(eq=False)
class Joint(Item, collection="joints", namespace="joints", label="joint"):
    """Base of joints; ``name`` is unique among the joints of a model."""

    name: str | None


@dataclass(eq=False)
class _PointJoint(Joint):
    """A joint between the material points of ``a`` and ``b`` at the global point ``at``
    (a node where a side is a beam)."""

    a: Body | str
    b: Body | str
    at: np.ndarray

    def check(self, model: Model) -> None:
        self.a = body_of(model, self.a, self.owner)
        self.b = body_of(model, self.b, self.owner)
        if self.a is self.b:
            raise ModelError(f"{self.owner}: connects body {self.a.name!r} to itself")
        at = self.at
        for body in (self.a, self.b):  # b sees a's node, so both sides share one point
            at = material_point(body, at, self.owner)
        self.at = at


@dataclass(eq=False)
class Revolute(_PointJoint, label="revolute"):
    """Pin joint: the material points of ``a`` and ``b`` at ``at`` coincide (2 rows)."""


@dataclass(eq=False)
class Weld(_PointJoint, label="weld"):
    """Rigid joint: revolute plus the relative rotation at ``at`` kept at its initial value."""


@dataclass(eq=False)
class Prismatic(_PointJoint, label="prismatic"):
    """Slider: the material point of ``b`` at ``at`` moves along the line through ``at`` with
    direction ``axis`` fixed in ``a`` (in the frame of the beam node at ``at`` when ``a`` is a
    beam), and the relative rotation of ``a`` and ``b`` is held at its initial value (2 rows).
    ``axis``: any nonzero length, global, initial configuration."""

    axis: np.ndarray

    def check(self, model: Model) -> None:
        super().check(model)
        axis = _point(self.axis, "axis", self.owner)
        if not np.hypot(*_real(axis)) > 0:
            raise ModelError(f"{self.owner}: axis must be a nonzero direction (x, y), got "
                             f"{_show(axis)}")
        self.axis = axis


@dataclass(eq=False)
class Fix(Joint, label="fix"):
    """Ground constraint on a subset ``dofs`` of ``"x"``, ``"y"`` and ``"r"`` (rotation) of
    the point ``at`` of ``body`` (held at their initial values; stored in the order x, y, r)."""

    body: Body | str
    at: np.ndarray
    dofs: str = "xyr"

    def check(self, model: Model) -> None:
        self.body = body_of(model, self.body, self.owner)
        if self.body is model.ground:
            raise ModelError(f"{self.owner}: the ground is fixed already")
        dofs = self.dofs
        if (not isinstance(dofs, str) or not dofs or set(dofs) - set("xyr")
                or len(set(dofs)) != len(dofs)):
            raise ModelError(f"{self.owner}: dofs must be a non-empty string of distinct "
                             f"letters from 'x', 'y', 'r', got {dofs!r}")
        self.at = material_point(self.body, self.at, self.owner)
        self.dofs = "".join(sorted(dofs, key="xyr".index))


@dataclass(eq=False)
class Drive(Joint, label="drive"):
    """Prescribed rotation: ``angle(t) = angle_0 + f(t)`` of the body (or of a beam node at
    ``at``; default the beam's reference node, else node 0), with ``f = profile``, or ``f`` the
    exact integral of ``speed`` (:meth:`Profile.integral`; ``profile`` is then set to it).
    Exactly one of ``profile`` and ``speed`` is given; ``f(0)`` must be 0 so that the initial
    configuration is consistent."""

    body: Body | str
    profile: Profile | None = None
    at: np.ndarray | None = None
    speed: Profile | None = None

    def check(self, model: Model) -> None:
        owner = self.owner
        self.body = body = body_of(model, self.body, owner)
        if body is model.ground:
            raise ModelError(f"{owner}: cannot drive the ground")
        if (self.profile is None) == (self.speed is None):
            raise ModelError(f"{owner}: give exactly one of angle= (a profile of the angle, 0 "
                             "at t=0) and speed= (a profile of the angular speed)")
        if self.speed is not None:
            self.speed = _profile(self.speed, f"{owner} speed")
            try:
                prof = self.speed.integral(0.0)
            except ModelError as exc:
                raise ModelError(f"{owner}: speed= needs a profile with a closed-form "
                                 f"integral: {exc}") from None
        else:
            prof = _profile(self.profile, owner)
        f0 = _real(prof.value(0.0))
        if abs(f0) > 1e-12:
            raise ModelError(f"{owner}: angle(0) must be 0 (the drive is relative to the "
                             f"initial angle), got {f0:.6g}")
        if self.at is not None:
            self.at = material_point(body, self.at, owner)
        elif isinstance(body, Beam):
            self.at = body.nodes[drive_node(body)]
        self.profile = prof


@dataclass(eq=False)
class Gear(Joint, label="gear"):
    """Gear pair or coupler between two rotations (1 angle row, ``docs/theory.md`` §4.2):

    ``(theta_a + phi_a) - ratio (theta_b + phi_b) = c``,

    ``theta`` the angle of a body (of a beam's floating frame), ``phi`` the elastic rotation of
    the beam node at ``at_a`` / ``at_b`` (a beam side needs its node; on a rigid body every
    point turns alike, so the point is optional there), ``c`` the value in the initial
    configuration. ``b`` turns by ``1 / ratio`` of ``a``'s turn: ``ratio`` = teeth of ``b`` /
    teeth of ``a``, negative for an external pair (the senses are opposite), positive for an
    internal pair or a belt. Either side may be the ground, which then holds the other side's
    rotation. Its reaction (:meth:`Result.reaction`) is the moment on ``b`` (on ``a`` when
    ``b`` is the ground); ``a`` receives ``-1 / ratio`` of it.
    """

    a: Body | str
    b: Body | str
    ratio: object
    at_a: np.ndarray | None = None
    at_b: np.ndarray | None = None

    @property
    def at(self) -> np.ndarray:
        """The point of the side whose reaction :meth:`Result.reaction` gives (``b``, or ``a``
        when ``b`` is the ground): its ``at_b`` / ``at_a``, else its centre of mass (a rigid
        body turns alike at every point)."""
        body, at = (self.a, self.at_a) if isinstance(self.b, Ground) else (self.b, self.at_b)
        return at if at is not None else body.position

    def check(self, model: Model) -> None:
        owner = self.owner
        self.a, self.b = body_of(model, self.a, owner), body_of(model, self.b, owner)
        if self.a is self.b:
            raise ModelError(f"{owner}: connects body {self.a.name!r} to itself")
        r = _numeric(self.ratio, "ratio", owner, expect="a finite nonzero number")
        if not _real(r) != 0:
            raise ModelError(f"{owner}: ratio must be a finite nonzero number (the turn of a "
                             f"per turn of b), got {_show(self.ratio)}")
        self.ratio = _upcast(self.ratio)
        for side, key in (("a", "at_a"), ("b", "at_b")):
            body, at = getattr(self, side), getattr(self, key)
            if isinstance(body, Beam) and at is None:
                raise ModelError(f"{owner}: {key} (a node of beam {body.name!r}) is needed: the "
                                 "gear acts on that node's rotation")
            if at is not None:
                setattr(self, key, material_point(body, at, owner, key))
