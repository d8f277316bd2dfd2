"""The joints and drives of a model (descriptions only: compiled by
:mod:`morphlab.compile.joints`)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .bodies import Body
from .profiles import Profile


@dataclass(eq=False)
class Joint:
    """Base of joints; ``name`` is unique within a model."""

    name: str


@dataclass(eq=False)
class Revolute(Joint):
    """Pin joint: the material points of ``a`` and ``b`` at ``at`` coincide (2 rows)."""

    a: Body
    b: Body
    at: np.ndarray


@dataclass(eq=False)
class Weld(Joint):
    """Rigid joint: revolute plus the relative rotation at ``at`` kept at its initial value."""

    a: Body
    b: Body
    at: np.ndarray


@dataclass(eq=False)
class Prismatic(Joint):
    """Slider: the material point of ``b`` at ``at`` moves along the line through ``at`` with
    direction ``axis`` fixed in ``a`` (in the frame of the beam node at ``at`` when ``a`` is a
    beam), and the relative rotation of ``a`` and ``b`` is held at its initial value (2 rows)."""

    a: Body
    b: Body
    at: np.ndarray
    axis: np.ndarray


@dataclass(eq=False)
class Fix(Joint):
    """Ground constraint on a subset of x, y and rotation of the point ``at`` of ``body``."""

    body: Body
    at: np.ndarray
    dofs: str


@dataclass(eq=False)
class Drive(Joint):
    """Prescribed rotation: ``angle(t) = angle_0 + f(t)`` of the body (or of a beam node at
    ``at``); ``f(0)`` must be 0 so that the initial configuration is consistent. A drive by
    speed holds ``f = speed.integral()``."""

    body: Body
    profile: Profile
    at: np.ndarray | None = None
