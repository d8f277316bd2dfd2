"""Stage 1, describe: a :class:`Model` of bodies, joints, loads and drives, and time profiles.

A model is a description only; :mod:`morphlab.compile` turns it into arrays.
"""

from .model import (
    Beam,
    Body,
    Drive,
    Fix,
    Force,
    Ground,
    Joint,
    Model,
    Prismatic,
    Revolute,
    RigidBody,
    Torque,
    Weld,
)
from .profiles import Constant, Custom, Linear, Profile, Ramp, Sine, SmoothStep, as_profile

__all__ = [
    "Beam", "Body", "Constant", "Custom", "Drive", "Fix", "Force", "Ground", "Joint", "Linear",
    "Model", "Prismatic", "Profile", "Ramp", "Revolute", "RigidBody", "Sine", "SmoothStep",
    "Torque", "Weld", "as_profile",
]
