"""Time profiles: scalar functions of time with their first two derivatives.

A profile scales a load or prescribes a driven coordinate. Every profile has ``value(t)``,
``d1(t)`` and ``d2(t)``; the time ``t`` is always a real float (time is not a design variable),
while the profile's own parameters may be complex during complex-step differentiation.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from ..errors import ModelError


class Profile:
    """Base class of time profiles (value and two derivatives)."""

    def value(self, t: float):  # pragma: no cover - interface
        raise NotImplementedError

    def d1(self, t: float):  # pragma: no cover - interface
        raise NotImplementedError

    def d2(self, t: float):  # pragma: no cover - interface
        raise NotImplementedError

    def __call__(self, t: float):
        return self.value(t)

    def table(self, times):
        """``(f, f', f'')`` at every time of ``times`` (arrays); profiles override this with
        a vectorized version, the default loops over the times."""
        n = len(times)
        out = [np.empty(n, dtype=complex) for _ in range(3)]
        for k, t in enumerate(times):
            t = float(t)
            out[0][k], out[1][k], out[2][k] = self.value(t), self.d1(t), self.d2(t)
        return tuple(o if np.any(o.imag) else o.real for o in out)


@dataclass(frozen=True)
class Constant(Profile):
    """``f(t) = level`` (default 1)."""

    level: float = 1.0

    def value(self, t):
        return self.level

    def d1(self, t):
        return 0.0 * self.level

    def d2(self, t):
        return 0.0 * self.level

    def table(self, times):
        one = np.ones(len(times))
        return one * self.level, one * 0.0 * self.level, one * 0.0 * self.level


def _check_interval(t0, t1, name):
    if not (math.isfinite(t0) and math.isfinite(t1)) or not t1 > t0:
        raise ModelError(f"{name}: need finite t0 < t1, got t0={t0!r}, t1={t1!r}")


@dataclass(frozen=True)
class Ramp(Profile):
    """Linear rise from 0 at ``t0`` to 1 at ``t1``, constant 1 afterwards.

    The second derivative is zero almost everywhere; the kinks at ``t0`` and ``t1`` excite the
    structure, so prefer :class:`SmoothStep` when the response should stay smooth.
    """

    t0: float
    t1: float

    def __post_init__(self):
        _check_interval(self.t0, self.t1, "Ramp")

    def value(self, t):
        if t <= self.t0:
            return 0.0
        if t >= self.t1:
            return 1.0
        return (t - self.t0) / (self.t1 - self.t0)

    def d1(self, t):
        return 1.0 / (self.t1 - self.t0) if self.t0 < t < self.t1 else 0.0

    def d2(self, t):
        return 0.0

    def table(self, times):
        t = np.asarray(times, dtype=float)
        inside = (t > self.t0) & (t < self.t1)
        return (np.clip((t - self.t0) / (self.t1 - self.t0), 0.0, 1.0),
                np.where(inside, 1.0 / (self.t1 - self.t0), 0.0), np.zeros_like(t))


@dataclass(frozen=True)
class SmoothStep(Profile):
    """Quintic step from 0 at ``t0`` to 1 at ``t1`` with zero first and second derivatives at
    both ends: ``f = 10 x³ - 15 x⁴ + 6 x⁵``, ``x = (t - t0)/(t1 - t0)``."""

    t0: float
    t1: float

    def __post_init__(self):
        _check_interval(self.t0, self.t1, "SmoothStep")

    def _x(self, t):
        return min(max((t - self.t0) / (self.t1 - self.t0), 0.0), 1.0)

    def table(self, times):
        x = np.clip((np.asarray(times, dtype=float) - self.t0) / (self.t1 - self.t0), 0.0, 1.0)
        T = self.t1 - self.t0
        return (x**3 * (10.0 - 15.0 * x + 6.0 * x * x), 30.0 * x * x * (1.0 - x) ** 2 / T,
                60.0 * x * (1.0 - x) * (1.0 - 2.0 * x) / T**2)

    def value(self, t):
        x = self._x(t)
        return x * x * x * (10.0 - 15.0 * x + 6.0 * x * x)

    def d1(self, t):
        x = self._x(t)
        return 30.0 * x * x * (1.0 - x) ** 2 / (self.t1 - self.t0)

    def d2(self, t):
        x = self._x(t)
        return 60.0 * x * (1.0 - x) * (1.0 - 2.0 * x) / (self.t1 - self.t0) ** 2


@dataclass(frozen=True)
class Sine(Profile):
    """``f(t) = sin(omega t + phase)``; ``omega`` in rad per time unit."""

    omega: float
    phase: float = 0.0

    def value(self, t):
        return math.sin(self.omega * t + self.phase)

    def d1(self, t):
        return self.omega * math.cos(self.omega * t + self.phase)

    def d2(self, t):
        return -self.omega**2 * math.sin(self.omega * t + self.phase)


@dataclass(frozen=True)
class Linear(Profile):
    """``f(t) = rate * t`` (e.g. a crank driven at constant speed)."""

    rate: float

    def value(self, t):
        return self.rate * t

    def d1(self, t):
        return self.rate

    def d2(self, t):
        return 0.0 * self.rate


@dataclass(frozen=True)
class Custom(Profile):
    """A user function with optional derivatives.

    Without ``d1``/``d2`` the derivatives are formed numerically: ``d1`` by complex step when
    ``f`` accepts complex arguments, otherwise by a central difference; ``d2`` by a central
    difference of ``d1`` (step ``1e-5 * (1 + |t|)``, error about 1e-10 relative for smooth f).
    """

    f: Callable[[float], float]
    df: Callable[[float], float] | None = None
    ddf: Callable[[float], float] | None = None

    def value(self, t):
        return self.f(t)

    def d1(self, t):
        if self.df is not None:
            return self.df(t)
        h = 1e-30
        try:
            return complex(self.f(complex(t, h))).imag / h
        except TypeError:
            e = 1e-6 * (1.0 + abs(t))
            return (self.f(t + e) - self.f(t - e)) / (2 * e)

    def d2(self, t):
        if self.ddf is not None:
            return self.ddf(t)
        e = 1e-5 * (1.0 + abs(t))
        return (self.d1(t + e) - self.d1(t - e)) / (2 * e)


def as_profile(obj, name: str = "profile") -> Profile:
    """Turn ``None`` (constant 1), a number (constant) or a callable into a :class:`Profile`."""
    if obj is None:
        return Constant(1.0)
    if isinstance(obj, Profile):
        return obj
    if isinstance(obj, (int, float, complex)):
        return Constant(obj)
    if callable(obj):
        return Custom(obj)
    raise ModelError(
        f"{name}: expected a Profile (Ramp, SmoothStep, Constant, ...), a number or a callable "
        f"f(t), got {type(obj).__name__}"
    )
