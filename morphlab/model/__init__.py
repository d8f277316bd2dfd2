"""Stage 1, describe: a :class:`Model` of bodies, joints, loads and drives, and time profiles.

A model is a description only; :mod:`morphlab.compile` turns it into arrays.
"""

from .bodies import Beam, Body, Ground, RigidBody
from .forces import LineLoad, RotationalSpring, Spring
from .joints import Drive, Fix, Joint, Prismatic, Revolute, Weld
from .loads import Force, Torque
from .model import Model
from .pressure import FollowerForce, Pressure
from .profiles import (
    Constant,
    Custom,
    Integral,
    Linear,
    Polynomial,
    Product,
    Profile,
    Ramp,
    Scaled,
    Sine,
    SmoothStep,
    Sum,
    as_profile,
)

__all__ = [
    "Beam", "Body", "Constant", "Custom", "Drive", "Fix", "FollowerForce", "Force", "Ground", "Integral", "Joint",
    "LineLoad", "Linear", "Model", "Polynomial", "Pressure", "Prismatic", "Product", "Profile", "Ramp",
    "Revolute", "RigidBody", "RotationalSpring", "Scaled", "Sine", "SmoothStep", "Spring", "Sum",
    "Torque", "Weld", "as_profile",
]
