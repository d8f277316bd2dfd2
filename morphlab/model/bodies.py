"""The bodies of a model: the ground, rigid bodies and flexible beams (FFRF, with their
floating frames: :mod:`morphlab.model.frames`)."""

from __future__ import annotations

import functools
from typing import TYPE_CHECKING

import numpy as np

from ..errors import ModelError
from .frames import frame_offsets
from .frames import resolve as resolve_frames
from .items import Item
from .values import (
    _check_name,
    _finite_positive,
    _has_bool,
    _numeric,
    _point,
    _real,
    _section_positive,
    _show,
    _upcast,
)

if TYPE_CHECKING:
    from .model import Model


class Body(Item, collection="bodies", namespace="bodies", label="body"):
    """Base of all bodies. ``name`` is unique within a model. A body validates its parameters
    when it is constructed; :meth:`Model.add <morphlab.model.Model.add>` checks its name."""

    name: str

    def __repr__(self) -> str:
        return f"{type(self).__name__}({self.name!r})"


class Ground(Body):
    """The fixed inertial frame (no DOFs). Every model has exactly one: ``model.ground``."""

    def __init__(self):
        self.name = "ground"


class RigidBody(Body, label="rigid body", prefix="body"):
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


class Beam(Body, label="beam"):
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


# ---- a body and a material point of it, as items refer to them
def body_of(model: Model, body, owner: str) -> Body:
    """``body`` (a body or its name) as a body of ``model`` (its ground included).

    Raises
    ------
    ModelError
        Naming ``owner``: not a body or a name, an unknown name, a body of another model.
    """
    if isinstance(body, str):
        try:
            return model.body(body)
        except ModelError as exc:
            raise ModelError(f"{owner}: {exc}") from None
    if not isinstance(body, Body):
        raise ModelError(f"{owner}: expected a body of this model or its name, got "
                         f"{_show(body)}")
    if body is not model.ground and not any(body is b for b in model.bodies):
        other = body._model.name if body._model is not None else None
        where = f" (it belongs to model {other!r})" if other is not None else ""
        raise ModelError(f"{owner}: body {body.name!r} is not part of model "
                         f"{model.name!r}{where}; add it to this model first")
    return body


def material_point(body: Body, at, owner: str, what: str = "at") -> np.ndarray:
    """``at`` (2,) as a material point of ``body``: any point of the plane for a rigid body
    or the ground; on a beam one of its nodes (to 1e-6 of the beam's size, at least 1e-6
    length units), whose exact coordinates are returned so that every side of a joint sees one
    point.

    Raises
    ------
    ModelError
        Naming ``owner`` and ``what``: not a finite pair of numbers, or on a beam not at a
        node (the nearest node and its distance are given).
    """
    at = _point(at, what, owner)
    if isinstance(body, Beam):
        k, dist = body.nearest_node(at)
        tol = 1e-6 * max(body.size, 1.0)
        if dist > tol:
            node = tuple(float(x) for x in np.round(_real(body.nodes[k]), 6))
            raise ModelError(
                f"{owner}: point {tuple(float(x) for x in np.round(_real(at), 6))} is not at "
                f"a node of beam {body.name!r}; nearest is node {k} at {node}, distance "
                f"{dist:.6g} (tolerance {tol:.3g}). Joints and loads act at beam nodes: use "
                "that node's coordinates or add a node there"
            )
        return body.nodes[k].copy()
    return at


def element_indices(elements, beam: Beam, owner: str) -> np.ndarray:
    """``elements`` as distinct element indices of ``beam`` (all for None), sorted int64;
    a :class:`ModelError` naming ``owner`` otherwise."""
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
