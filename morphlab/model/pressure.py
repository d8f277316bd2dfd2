"""Follower loads of a model: a pressure on beams and point forces that turn with the body
(descriptions and their validation; compiled by :mod:`morphlab.compile.loads`, formulation
``docs/theory.md`` §4.7)."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..errors import ModelError
from .bodies import Beam
from .forces import _body
from .loads import Force
from .profiles import Constant, Profile
from .values import _numeric, _profile, _real, _show, _upcast


@dataclass(eq=False)
class Pressure:
    """A pressure ``p(s) * profile(t)`` [force/area] normal to the deformed centre line of
    ``beam`` over ``elements``, on the beam's out-of-plane ``width`` [length]. Positive ``p``
    pushes along the left normal of the direction from node 0 to the last node (on a ring
    numbered counter-clockwise: inwards, an external pressure).

    ``p`` holds one value per node of the beam (linear along each element); ``width`` one per
    element."""

    name: str
    beam: Beam
    p: np.ndarray
    width: np.ndarray
    profile: Profile = field(default_factory=Constant)
    elements: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))


@dataclass(eq=False)
class FollowerForce(Force):
    """A point force that turns with the material point: ``F(t) = A(psi - psi_0) force
    profile(t)``, ``force`` in the axes of the initial configuration and ``psi`` the point's
    rotation (the body angle, plus the nodal rotation at a beam node)."""


def _elements(elements, beam: Beam, owner: str) -> np.ndarray:
    """Distinct element indices of ``beam`` (all for None), sorted."""
    n_el = beam.n_elements
    if elements is None:
        return np.arange(n_el, dtype=np.int64)
    try:
        idx = np.asarray(elements)
        ok = idx.ndim == 1 and idx.size > 0 and idx.dtype.kind in "iu"
    except (TypeError, ValueError):
        ok = False
    if not ok or np.any(idx < 0) or np.any(idx >= n_el) or np.unique(idx).size != idx.size:
        raise ModelError(f"{owner}: elements must be distinct element indices of beam "
                         f"{beam.name!r} (0 to {n_el - 1}), or None for all, got "
                         f"{_show(elements)}")
    return np.sort(idx.astype(np.int64))


def _nodal(p, beam: Beam, owner: str) -> np.ndarray:
    """The pressure at each node of ``beam``: a number, ``n_nodes`` values, or a callable
    ``p(xy)`` of the undeformed nodes (n_nodes, 2) returning ``n_nodes`` values."""
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
    arr = np.asarray(values) if not np.isscalar(values) else values
    if np.ndim(arr) == 0:
        v = _numeric(arr, what, owner)
        return np.full(n, v, dtype=np.result_type(v, float))
    return _upcast(_numeric(arr, what, owner, shape=(n,),
                            expect=f"a number or one finite value per node ({n})"))


def make_pressure(model, name, beam, p, profile, elements, width) -> Pressure:
    """A validated :class:`Pressure` of ``model`` (not yet added)."""
    owner = f"pressure {name!r}"
    beam = _body(model, beam, owner)
    if not isinstance(beam, Beam):
        raise ModelError(f"{owner}: a pressure acts on a beam, got {type(beam).__name__} "
                         f"{beam.name!r}")
    idx = _elements(elements, beam, owner)
    values = _nodal(p, beam, owner)
    if width is None:
        width = beam.width
        if width is None:
            raise ModelError(f"{owner}: beam {beam.name!r} has no width (its section was given "
                             "as area and second_moment); give width= [length]")
    w = np.broadcast_to(_upcast(np.asarray(width)), (beam.n_elements,))
    _numeric(w, "width", owner, shape=(beam.n_elements,))
    if not np.all(_real(w) > 0):
        raise ModelError(f"{owner}: width must be > 0, got {_show(width)}")
    return Pressure(name, beam, values, np.array(w), _profile(profile, owner), idx)

