"""Compile functions of the joints: each becomes scalar constraint rows
(:data:`~morphlab.kernels.joints.ROW_X`, ``ROW_Y``, ``ROW_ANGLE``) between two material points.
Formulation: ``docs/theory.md`` §4."""

from __future__ import annotations

import numpy as np

from ..kernels.joints import ROW_ANGLE, ROW_X, ROW_Y
from ..model.model import Drive, Fix, Ground, Revolute, RigidBody, Weld
from .builder import Builder, compiles


@compiles(Revolute)
@compiles(Weld)
def compile_pin(j: Revolute | Weld, b: Builder) -> None:
    """``r_P - r_Q = c`` (x and y rows); a weld adds the relative angle held at its initial
    value. A ground side contributes its fixed coordinate to ``c``."""
    pa, pb = b.point(j.a, j.at), b.point(j.b, j.at)
    ca = np.asarray(j.at) if isinstance(j.a, Ground) else np.zeros(2)
    cb = np.asarray(j.at) if isinstance(j.b, Ground) else np.zeros(2)
    b.add_row(ROW_X, j, "x", pa, pb, -ca[0] + cb[0])
    b.add_row(ROW_Y, j, "y", pa, pb, -ca[1] + cb[1])
    if isinstance(j, Weld):
        b.add_row(ROW_ANGLE, j, "r", pa, pb, pa[2] - pb[2])


@compiles(Fix)
def compile_fix(j: Fix, b: Builder) -> None:
    """Any subset of x, y and the rotation of a point held at its initial value."""
    pa = b.point(j.body, j.at)
    ground = b.point(b.model.ground, j.at)
    for label in j.dofs:
        kind = {"x": ROW_X, "y": ROW_Y, "r": ROW_ANGLE}[label]
        c0 = pa[2] if kind == ROW_ANGLE else np.asarray(j.at)[kind]
        b.add_row(kind, j, label, pa, ground, c0)


@compiles(Drive)
def compile_drive(j: Drive, b: Builder) -> None:
    """The angle of a body (or beam node) prescribed: ``angle_0 + f(t)``."""
    at = j.at if j.at is not None else (
        j.body.position if isinstance(j.body, RigidBody) else None)
    pa = b.point(j.body, at)
    b.add_row(ROW_ANGLE, j, "r", pa, b.point(b.model.ground, at), pa[2], profile=j.profile)
