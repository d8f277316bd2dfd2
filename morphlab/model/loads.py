"""The loads of a model: point forces and torques with time profiles (descriptions that
validate themselves, :meth:`~morphlab.model.items.Item.check`; compiled by
:mod:`morphlab.compile.loads`)."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from ..errors import ModelError
from .bodies import Beam, Body, body_of, element_indices, material_point
from .items import Item
from .profiles import Constant, Profile
from .values import _numeric, _point, _profile, _upcast

if TYPE_CHECKING:
    from .model import Model


class Load(Item, namespace="loads"):
    """Base of loads and force elements: they share one set of names (the ``"loads"``
    namespace). A new kind of load derives from it, names its list and label in the class
    statement (``class Torque(Load, collection="torques", label="torque")``) and writes its
    :meth:`check`."""

    def _loaded_body(self, model: Model, body) -> Body:
        """``body`` (or its name) as a body of ``model`` other than the ground."""
        body = body_of(model, body, self.owner)
        if body is model.ground:
            raise ModelError(f"{self.owner}: cannot load the ground")
        return body


@dataclass(eq=False)
class _BeamLoad(Load):
    """Base of the loads distributed over elements of one beam (line loads, pressures): their
    first two fields, ``name`` and ``beam``, and the resolution of ``beam`` and of the kind's
    ``elements`` field (element indices of that beam, None for all)."""

    name: str | None
    beam: Beam | str

    def _check_span(self, model: Model) -> Beam:
        """Bring ``beam`` to a beam of ``model`` and ``elements`` to a sorted int64 array of
        its element indices; return the beam.

        Raises
        ------
        ModelError
            Naming the load: ``beam`` is not a beam of ``model`` (or its name), or
            ``elements`` are not distinct element indices of it.
        """
        self.beam = beam = body_of(model, self.beam, self.owner)
        if not isinstance(beam, Beam):
            raise ModelError(f"{self.owner}: a {self.label} acts on a beam, got "
                             f"{type(beam).__name__} {beam.name!r}")
        self.elements = element_indices(self.elements, beam, self.owner)
        return beam


@dataclass(eq=False)
class Force(Load, collection="forces", label="force"):
    """A force of fixed global direction at a material point: ``F(t) = force * profile(t)``
    [N] (``at`` a node when ``body`` is a beam; ``profile`` a :class:`Profile`, a number or
    a callable ``f(t)``)."""

    body: Body | str
    at: np.ndarray
    force: np.ndarray
    profile: Profile = field(default_factory=Constant)
    name: str | None = None

    def check(self, model: Model) -> None:
        self.body = self._loaded_body(model, self.body)
        self.at = material_point(self.body, self.at, self.owner)
        self.force = _point(self.force, "force", self.owner)
        self.profile = _profile(self.profile, self.owner)


@dataclass(eq=False)
class Torque(Load, collection="torques", label="torque"):
    """A torque ``T(t) = magnitude * profile(t)`` [N·mm] on a body (and on the nodal rotation
    of the beam node at ``at``, when given)."""

    body: Body | str
    magnitude: object
    profile: Profile = field(default_factory=Constant)
    at: np.ndarray | None = None
    name: str | None = None

    def check(self, model: Model) -> None:
        self.body = self._loaded_body(model, self.body)
        _numeric(self.magnitude, "magnitude", self.owner)
        self.magnitude = _upcast(self.magnitude)
        if self.at is not None:
            self.at = material_point(self.body, self.at, self.owner)
        self.profile = _profile(self.profile, self.owner)
