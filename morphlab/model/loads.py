"""The loads of a model: point forces and torques with time profiles (descriptions that
validate themselves, :meth:`~morphlab.model.items.Item.check`; compiled by
:mod:`morphlab.compile.loads`)."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from ..errors import ModelError
from .bodies import Body, body_of, material_point
from .items import Item
from .profiles import Constant, Profile
from .values import _numeric, _point, _profile, _upcast

if TYPE_CHECKING:
    from .model import Model


class Load(Item):
    """Base of loads and force elements: they share one set of names (the ``"loads"``
    namespace). A new kind of load derives from it and sets ``collection``, ``label`` and
    ``prefix`` and its :meth:`check`."""

    namespace = "loads"

    def _loaded_body(self, model: Model, body) -> Body:
        """``body`` (or its name) as a body of ``model`` other than the ground."""
        body = body_of(model, body, self.owner)
        if body is model.ground:
            raise ModelError(f"{self.owner}: cannot load the ground")
        return body


@dataclass(eq=False)
class Force(Load):
    """A force of fixed global direction at a material point: ``F(t) = force * profile(t)``
    [N] (``at`` a node when ``body`` is a beam; ``profile`` a :class:`Profile`, a number or
    a callable ``f(t)``)."""

    body: Body | str
    at: np.ndarray
    force: np.ndarray
    profile: Profile = field(default_factory=Constant)
    name: str | None = None

    collection = "forces"
    label = "force"
    prefix = "force"

    def check(self, model: Model) -> None:
        self.body = self._loaded_body(model, self.body)
        self.at = material_point(self.body, self.at, self.owner)
        self.force = _point(self.force, "force", self.owner)
        self.profile = _profile(self.profile, self.owner)


@dataclass(eq=False)
class Torque(Load):
    """A torque ``T(t) = magnitude * profile(t)`` [N·mm] on a body (and on the nodal rotation
    of the beam node at ``at``, when given)."""

    body: Body | str
    magnitude: object
    profile: Profile = field(default_factory=Constant)
    at: np.ndarray | None = None
    name: str | None = None

    collection = "torques"
    label = "torque"
    prefix = "torque"

    def check(self, model: Model) -> None:
        self.body = self._loaded_body(model, self.body)
        _numeric(self.magnitude, "magnitude", self.owner)
        self.magnitude = _upcast(self.magnitude)
        if self.at is not None:
            self.at = material_point(self.body, self.at, self.owner)
        self.profile = _profile(self.profile, self.owner)
