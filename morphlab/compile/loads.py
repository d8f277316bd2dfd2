"""Compile functions of the loads: point forces and torques."""

from __future__ import annotations

import numpy as np

from ..model import Beam, Force, Torque
from ..model.frames import drive_node
from .builder import Builder, compiles


@compiles(Force)
def compile_force(f: Force, b: Builder) -> None:
    """A force of fixed global direction at a material point."""
    dofs, u0, _ = b.point(f.body, f.at)
    b.table("loads").add(f.name, base=np.asarray(f.force), profile=f.profile, u0=u0, dofs=dofs)


@compiles(Torque)
def compile_torque(t: Torque, b: Builder) -> None:
    """A torque on a body's angle (and on the nodal rotation of the beam node at ``at``)."""
    info = b.bodies[t.body.name]
    dofs = np.array([info.ref[2], -1], dtype=np.int64)
    if isinstance(t.body, Beam):  # without ``at``: the drive node (docs/frames.md)
        k = t.body.nearest_node(t.at)[0] if t.at is not None else drive_node(t.body)
        dofs[:] = info.node_ref[k, 2], info.node_dofs[k, 2]
    b.table("torques").add(t.name, base=t.magnitude, profile=t.profile, dofs=dofs)
