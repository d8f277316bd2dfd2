"""Time profiles: scalar functions of time with their first two derivatives.

A profile scales a load or prescribes a driven coordinate. Every profile has ``value(t)``,
``d1(t)`` and ``d2(t)``; the time ``t`` is always a real float (time is not a design variable),
while the profile's own parameters may be complex during complex-step differentiation.

Profiles combine with operators: ``f + g``, ``f - g``, ``k * f``, ``f / k`` (``k`` a number)
and ``f * g`` (derivatives by the product rule), each again a profile. ``f.integral(c0)`` is
the exact antiderivative ``c0 + int_0^t f`` for the profiles with a closed-form primitive
(:class:`Constant`, :class:`Linear`, :class:`Polynomial`, :class:`Ramp`, :class:`SmoothStep`,
:class:`Sine`, and sums and multiples of them); a speed drive integrates its speed this way.
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

    # ---- algebra: every result is again a profile with exact derivatives
    def __add__(self, other):
        return Sum(self, _operand(other, "+"))

    __radd__ = __add__

    def __sub__(self, other):
        return Sum(self, Scaled(-1.0, _operand(other, "-")))

    def __rsub__(self, other):
        return Sum(_operand(other, "-"), Scaled(-1.0, self))

    def __neg__(self):
        return Scaled(-1.0, self)

    def __mul__(self, other):
        if isinstance(other, Profile):
            return Product(self, other)
        return Scaled(_number(other, "*"), self)

    __rmul__ = __mul__

    def __truediv__(self, other):
        k = _number(other, "/")
        if k == 0:
            raise ModelError("profile / 0: division by zero")
        return Scaled(1.0 / k, self)

    # ---- exact integration
    def primitive(self, t):
        """An antiderivative ``F`` (``F' = f``) at ``t`` (a float or an array of times), in
        closed form; profiles without one raise :class:`~morphlab.errors.ModelError`."""
        raise ModelError(
            f"{type(self).__name__} has no closed-form integral; integrable profiles: Constant, "
            "Linear, Polynomial, Ramp, SmoothStep, Sine and sums and multiples of them (for a "
            "function of your own give the angle itself, e.g. Custom(f, df, ddf))")

    def integral(self, c0: float = 0.0) -> Integral:
        """The exact integral ``F(t) = c0 + int_0^t f(s) ds`` as a profile (``F' = f``,
        ``F'' = f'``).

        Raises
        ------
        ModelError
            The profile has no closed-form primitive (e.g. :class:`Custom`, a product).
        """
        self.primitive(0.0)  # fail now, not in a run
        return Integral(self, c0)

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

    def primitive(self, t):
        return self.level * np.asarray(t, dtype=float)[()]


def _number(k, op):
    if isinstance(k, (bool, np.bool_)) or not isinstance(k, (int, float, complex, np.number)):
        raise ModelError(f"profile {op} {type(k).__name__}: a profile combines with numbers and "
                         "other profiles only")
    return k


def _operand(other, op) -> Profile:
    return other if isinstance(other, Profile) else Constant(_number(other, op))


def _scalar(x, t):
    """``x`` as a scalar when ``t`` was one (primitives are written for arrays of times)."""
    return x[()] if np.ndim(t) == 0 else x


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

    def primitive(self, t):
        """``(t - t0)² / 2T`` on the rise (``T = t1 - t0``), ``T/2 + t - t1`` after it."""
        s = np.asarray(t, dtype=float)
        T = self.t1 - self.t0
        x = np.clip(s, self.t0, self.t1) - self.t0
        return _scalar(x * x / (2.0 * T) + np.maximum(s - self.t1, 0.0), t)


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

    def primitive(self, t):
        """``T (5/2 x⁴ - 3 x⁵ + x⁶)`` on the step, ``T/2 + t - t1`` after it."""
        s = np.asarray(t, dtype=float)
        T = self.t1 - self.t0
        x = np.clip((s - self.t0) / T, 0.0, 1.0)
        return _scalar(T * x**4 * (2.5 - 3.0 * x + x * x) + np.maximum(s - self.t1, 0.0), t)


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

    def primitive(self, t):
        if self.omega == 0:
            return np.sin(self.phase) * np.asarray(t, dtype=float)[()]
        return -np.cos(self.omega * np.asarray(t, dtype=float) + self.phase)[()] / self.omega


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

    def primitive(self, t):
        return 0.5 * self.rate * np.asarray(t, dtype=float)[()] ** 2


@dataclass(frozen=True)
class Polynomial(Profile):
    """``f(t) = c[0] + c[1] t + c[2] t² + ...`` (``coefficients`` a tuple of numbers)."""

    coefficients: tuple

    def __post_init__(self):
        c = tuple(self.coefficients) if np.ndim(self.coefficients) else (self.coefficients,)
        for k in c:
            _number(k, "Polynomial coefficient")
        object.__setattr__(self, "coefficients", c or (0.0,))

    def _eval(self, c, t):
        out = 0.0 * np.asarray(t, dtype=float)
        for k in reversed(c):  # Horner
            out = out * t + k
        return out

    def _deriv(self, c):
        return tuple(k * c[k] for k in range(1, len(c))) or (0.0 * c[0],)

    def value(self, t):
        return self._eval(self.coefficients, t)[()]

    def d1(self, t):
        return self._eval(self._deriv(self.coefficients), t)[()]

    def d2(self, t):
        return self._eval(self._deriv(self._deriv(self.coefficients)), t)[()]

    def table(self, times):
        t = np.asarray(times, dtype=float)
        c1 = self._deriv(self.coefficients)
        return (self._eval(self.coefficients, t), self._eval(c1, t),
                self._eval(self._deriv(c1), t))

    def primitive(self, t):
        c = (0.0,) + tuple(k / (i + 1) for i, k in enumerate(self.coefficients))
        return self._eval(c, np.asarray(t, dtype=float))[()]


@dataclass(frozen=True)
class Sum(Profile):
    """``f = a + b`` (made by ``a + b``)."""

    a: Profile
    b: Profile

    def value(self, t):
        return self.a.value(t) + self.b.value(t)

    def d1(self, t):
        return self.a.d1(t) + self.b.d1(t)

    def d2(self, t):
        return self.a.d2(t) + self.b.d2(t)

    def table(self, times):
        return tuple(x + y for x, y in zip(self.a.table(times), self.b.table(times)))

    def primitive(self, t):
        return self.a.primitive(t) + self.b.primitive(t)


@dataclass(frozen=True)
class Scaled(Profile):
    """``f = factor * profile`` (made by ``factor * profile``; ``factor`` a number)."""

    factor: float
    profile: Profile

    def value(self, t):
        return self.factor * self.profile.value(t)

    def d1(self, t):
        return self.factor * self.profile.d1(t)

    def d2(self, t):
        return self.factor * self.profile.d2(t)

    def table(self, times):
        return tuple(self.factor * np.asarray(x) for x in self.profile.table(times))

    def primitive(self, t):
        return self.factor * self.profile.primitive(t)


@dataclass(frozen=True)
class Product(Profile):
    """``f = a b`` (made by ``a * b``): ``f' = a' b + a b'``, ``f'' = a'' b + 2 a' b' + a b''``.
    No closed-form integral in general."""

    a: Profile
    b: Profile

    def value(self, t):
        return self.a.value(t) * self.b.value(t)

    def d1(self, t):
        return self.a.d1(t) * self.b.value(t) + self.a.value(t) * self.b.d1(t)

    def d2(self, t):
        a, a1, a2 = self.a.value(t), self.a.d1(t), self.a.d2(t)
        b, b1, b2 = self.b.value(t), self.b.d1(t), self.b.d2(t)
        return a2 * b + 2.0 * a1 * b1 + a * b2

    def table(self, times):
        (a, a1, a2), (b, b1, b2) = self.a.table(times), self.b.table(times)
        return a * b, a1 * b + a * b1, a2 * b + 2.0 * a1 * b1 + a * b2


@dataclass(frozen=True)
class Integral(Profile):
    """``F(t) = c0 + int_0^t f(s) ds`` of a profile ``f`` with a closed-form primitive (made by
    ``f.integral(c0)``): ``F' = f``, ``F'' = f'``; ``F(0) = c0`` exactly."""

    profile: Profile
    c0: float = 0.0

    def value(self, t):
        p = self.profile
        return self.c0 + (p.primitive(t) - p.primitive(0.0))

    def d1(self, t):
        return self.profile.value(t)

    def d2(self, t):
        return self.profile.d1(t)

    def table(self, times):
        t = np.asarray(times, dtype=float)
        f, f1, _ = self.profile.table(t)
        F = self.c0 + (np.asarray(self.profile.primitive(t)) - self.profile.primitive(0.0))
        return F + 0.0 * t, np.asarray(f) + 0.0 * t, np.asarray(f1) + 0.0 * t


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
