"""Follower loads of a model: a pressure on beams and point forces that turn with the body
(descriptions that validate themselves, :meth:`~morphlab.model.items.Item.check`; compiled by
:mod:`morphlab.compile.loads`, formulation ``docs/theory.md`` §4.7)."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from ..errors import ModelError
from .bodies import Beam
from .loads import Force, _BeamLoad
from .profiles import Constant, Profile
from .values import _numeric, _profile, _real, _show, _upcast

if TYPE_CHECKING:
    from .model import Model


@dataclass(eq=False)
class Pressure(_BeamLoad, collection="pressures", label="pressure"):
    """A pressure ``p(s) * profile(t)`` [force/area] normal to the deformed centre line of
    ``beam`` over ``elements``, on the beam's out-of-plane ``width`` [length]. Positive ``p``
    pushes along the left normal of the direction from the first node to the last (on a ring
    numbered counter-clockwise: inwards, an external pressure).

    ``p``: a number, one value per node of the beam (linear along each element) or a callable
    ``p(xy)`` of the undeformed nodes (n_nodes, 2) returning one per node; ``width``: a number
    or one per element (None: the beam's section width); ``elements``: element indices (None:
    all). :meth:`check` makes ``p`` (n_nodes,), ``width`` (n_elements,) and ``elements`` a
    sorted int64 array."""

    p: object
    width: object = None
    profile: Profile = field(default_factory=Constant)
    elements: np.ndarray | None = None

    def check(self, model: Model) -> None:
        owner = self.owner
        beam = self._check_span(model)
        self.p = _nodal(self.p, beam, owner)
        width = beam.width if self.width is None else self.width
        if width is None:
            raise ModelError(f"{owner}: beam {beam.name!r} has no width (its section was given "
                             "as area and second_moment); give width= [length]")
        w = _numeric(np.broadcast_to(_upcast(np.asarray(width)), (beam.n_elements,)), "width",
                     owner, shape=(beam.n_elements,))
        if not np.all(_real(w) > 0):
            raise ModelError(f"{owner}: width must be > 0, got {_show(width)}")
        self.width = np.array(w)
        self.profile = _profile(self.profile, owner)


@dataclass(eq=False)
class FollowerForce(Force, label="follower force", prefix="force"):
    """A point force that turns with the material point: ``F(t) = A(psi - psi_0) force
    profile(t)``, ``force`` in the axes of the initial configuration and ``psi`` the point's
    rotation (the body angle, plus the nodal rotation at a beam node)."""


def _nodal(p, beam: Beam, owner: str) -> np.ndarray:
    """The pressure at each node of ``beam`` (:class:`Pressure`'s ``p``)."""
    n = beam.n_nodes
    if callable(p) and not isinstance(p, Profile):
        try:
            values = p(np.array(beam.nodes))
        except Exception as exc:
            raise ModelError(f"{owner}: the pressure function raised {type(exc).__name__}: "
                             f"{exc}") from exc
        what = "the values of the pressure function"
    else:
        values, what = p, "p"
    if np.ndim(values) == 0:
        v = _numeric(values, what, owner)
        return np.full(n, v, dtype=np.result_type(v, float))
    return _upcast(_numeric(values, what, owner, shape=(n,),
                            expect=f"a number or one finite value per node ({n})"))
