"""Compile functions of the loads: point forces and torques."""

from __future__ import annotations

import numpy as np

from ..model.model import Beam, Force, Torque
from .builder import Builder, compiles


@compiles(Force)
def compile_force(f: Force, b: Builder) -> None:
    """A force of fixed global direction at a material point."""
    b.add_load(b.point(f.body, f.at), f.force, f.profile, f.name)


@compiles(Torque)
def compile_torque(t: Torque, b: Builder) -> None:
    """A torque on a body's angle (and on the nodal rotation of the beam node at ``at``)."""
    info = b.bodies[t.body.name]
    dofs = np.array([info.ref[2], -1], dtype=np.int64)
    if t.at is not None and isinstance(t.body, Beam):
        k, _ = t.body.nearest_node(t.at)
        dofs[1] = info.node_dofs[k, 2]
    b.add_torque(dofs, t.magnitude, t.profile, t.name)
