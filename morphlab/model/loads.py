"""The loads of a model: point forces and torques with time profiles."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .bodies import Body
from .profiles import Constant, Profile


@dataclass(eq=False)
class Force:
    """A force of fixed global direction at a material point: ``F(t) = force * profile(t)``."""

    body: Body
    at: np.ndarray
    force: np.ndarray
    profile: Profile = field(default_factory=Constant)
    name: str = ""


@dataclass(eq=False)
class Torque:
    """A torque ``T(t) = magnitude * profile(t)`` on a body (and on the nodal rotation of the
    beam node at ``at``, when given)."""

    body: Body
    magnitude: object
    profile: Profile = field(default_factory=Constant)
    at: np.ndarray | None = None
    name: str = ""
