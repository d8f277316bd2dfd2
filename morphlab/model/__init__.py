"""Stage 1, describe: a :class:`Model` of bodies, joints, loads and drives, and time profiles.

A model is a description only; :mod:`morphlab.compile` turns it into arrays. Every kind of item
is a class derived from :class:`Item` that validates itself (:meth:`Item.check`) when
:meth:`Model.add` adds it.
"""

from .bodies import Beam, Body, Ground, RigidBody
from .forces import LineLoad, RotationalSpring, Spring
from .items import Item
from .joints import Drive, Fix, Gear, Joint, Prismatic, Revolute, Weld
from .loads import Force, Load, Torque
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
    "Beam", "Body", "Constant", "Custom", "Drive", "Fix", "FollowerForce", "Force", "Gear",
    "Ground", "Integral", "Item", "Joint", "LineLoad", "Linear", "Load", "Model", "Polynomial",
    "Pressure", "Prismatic", "Product", "Profile", "Ramp", "Revolute", "RigidBody",
    "RotationalSpring", "Scaled", "Sine", "SmoothStep", "Spring", "Sum", "Torque", "Weld",
    "as_profile",
]
