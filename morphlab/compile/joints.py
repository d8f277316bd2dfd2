"""Compile functions of the joints: each becomes scalar constraint rows
(:data:`~morphlab.kernels.joints.ROW_X`, ``ROW_Y``, ``ROW_ANGLE``, ``ROW_GEAR`` of the ``rows``
table, the slide row of the ``slides`` table) between two material points.
Formulation: ``docs/theory.md`` §4."""

from __future__ import annotations

import numpy as np

from ..kernels.joints import ROW_ANGLE, ROW_GEAR, ROW_X, ROW_Y
from ..model import Drive, Fix, Gear, Ground, Prismatic, Revolute, RigidBody, Weld
from .builder import Builder, compiles


@compiles(Revolute)
@compiles(Weld)
def compile_pin(j: Revolute | Weld, b: Builder) -> None:
    """``r_P - r_Q = c`` (x and y rows); a weld adds the relative angle held at its initial
    value. A ground side contributes its fixed coordinate to ``c``."""
    pa, pb = b.point(j.a, j.at), b.point(j.b, j.at)
    ca = np.asarray(j.at) if isinstance(j.a, Ground) else np.zeros(2)
    cb = np.asarray(j.at) if isinstance(j.b, Ground) else np.zeros(2)
    b.add_row("rows", ROW_X, j, "x", pa, pb, -ca[0] + cb[0])
    b.add_row("rows", ROW_Y, j, "y", pa, pb, -ca[1] + cb[1])
    if isinstance(j, Weld):
        b.add_row("rows", ROW_ANGLE, j, "r", pa, pb, pa[2] - pb[2])


@compiles(Fix)
def compile_fix(j: Fix, b: Builder) -> None:
    """Any subset of x, y and the rotation of a point held at its initial value."""
    pa = b.point(j.body, j.at)
    ground = b.point(b.model.ground, j.at)
    for label in j.dofs:
        kind = {"x": ROW_X, "y": ROW_Y, "r": ROW_ANGLE}[label]
        c0 = pa[2] if kind == ROW_ANGLE else np.asarray(j.at)[kind]
        b.add_row("rows", kind, j, label, pa, ground, c0)


@compiles(Drive)
def compile_drive(j: Drive, b: Builder) -> None:
    """The angle of a body (or beam node) prescribed: ``angle_0 + f(t)``."""
    at = j.at if j.at is not None else (
        j.body.position if isinstance(j.body, RigidBody) else None)
    pa = b.point(j.body, at)
    b.add_row("rows", ROW_ANGLE, j, "r", pa, b.point(b.model.ground, at), pa[2],
              profile=j.profile)


@compiles(Gear)
def compile_gear(j: Gear, b: Builder) -> None:
    """One gear row ``(theta_a + phi_a) - r (theta_b + phi_b) = c``, the ratio ``r`` as the
    coefficient of side b, ``c`` its value in the initial configuration (the nodal rotations
    are zero there). A rigid side's point is its centre of mass unless given (every point of
    it turns alike), which is where the reaction is read."""
    pa, pb = (b.point(body, at if at is not None else getattr(body, "position", None))
              for body, at in ((j.a, j.at_a), (j.b, j.at_b)))
    b.add_row("rows", ROW_GEAR, j, "r", pa, pb, pa[2] - j.ratio * pb[2], coef=j.ratio)


def _angle(vec):
    """Angle of the direction ``vec`` (2,); for a complex ``vec`` (a complex step through
    ``build``) its analytic continuation, so the angle follows the perturbation."""
    d = np.real(vec)
    th = float(np.arctan2(d[1], d[0]))
    if np.iscomplexobj(vec):
        th = th + np.arctan((d[0] * vec[1] - d[1] * vec[0]) / (d[0] * vec[0] + d[1] * vec[1]))
    return th


@compiles(Prismatic)
def compile_prismatic(j: Prismatic, b: Builder) -> None:
    """A slide row ``n . (r_P - r_Q) = 0`` (P the point of ``b``, Q that of ``a``, ``n`` the
    guide's normal fixed in ``a``: its angle in ``a``'s frame is ``beta``) and an angle row
    holding ``b``'s rotation relative to ``a``; ``b`` is side 0 of both rows."""
    pa, pb = b.point(j.a, j.at), b.point(j.b, j.at)
    if isinstance(j.a, Ground):  # the guide's point in the ground frame is ``at`` itself
        pa = (pa[0], np.asarray(j.at, dtype=b.dtype), 0.0)
    beta = _angle(np.asarray(j.axis)) + np.pi / 2 - pa[2]
    b.add_row("slides", None, j, "n", pb, pa, 0.0, coef=beta)
    b.add_row("rows", ROW_ANGLE, j, "r", pb, pa, pb[2] - pa[2])
