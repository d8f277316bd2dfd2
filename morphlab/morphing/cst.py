"""Class/shape transformation (CST) airfoils of Kulfan [1]_ and the high-speed section of the
morphing study (paper §4): :func:`cst_surface`, :class:`CSTAirfoil`, :func:`high_speed_airfoil`.

The wing section of the paper has a chord of 550 mm and a maximum thickness of 67.5 mm. All
lengths in mm; float64 geometry (no design variable of the sensitivity analysis lives here).

References
----------
.. [1] B. M. Kulfan, "Universal parametric geometry representation method", Journal of
   Aircraft 45(1), 142-158, 2008. doi:10.2514/1.29958
"""

from dataclasses import dataclass, replace
from math import comb

import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = ["CHORD_MM", "THICKNESS_MM", "cst_surface", "CSTAirfoil", "high_speed_airfoil"]

FloatArray = NDArray[np.float64]

#: Chord of the wing section of the paper [mm].
CHORD_MM = 550.0
#: Maximum thickness of the wing section of the paper [mm].
THICKNESS_MM = 67.5
# CST weights of the high-speed airfoil before scaling (chord 1, n = 5); see high_speed_airfoil.
_HS_UPPER = (0.14, 0.19, 0.23, 0.27, 0.24, 0.22)
_HS_LOWER = (-0.14, -0.07, -0.09, -0.09, -0.06, -0.07)


def cst_surface(
    psi: ArrayLike,
    weights: ArrayLike,
    n1: float = 0.5,
    n2: float = 1.0,
    te: float = 0.0,
) -> FloatArray:
    r"""Evaluate one CST surface (Kulfan 2008) in chord-normalised coordinates.

    Parameters
    ----------
    psi : array_like, any shape
        Normalised chordwise position ``x / c`` in [0, 1] (values within 1e-12 outside the
        interval are clipped to it).
    weights : array_like, shape (n + 1,)
        Bernstein weights ``A_0 ... A_n`` of the shape function (dimensionless). ``n`` is the
        order of the Bernstein polynomial.
    n1, n2 : float, optional
        Exponents of the class function. ``n1 = 0.5, n2 = 1`` (default) gives a round nose and
        a sharp trailing edge.
    te : float, optional
        Trailing-edge offset ``y_TE / c`` (dimensionless), added linearly in ``psi``.

    Returns
    -------
    ndarray of float64, same shape as `psi`
        Normalised ordinate ``y / c``.

    Notes
    -----
    .. math::

        \frac{y}{c} = \psi^{n_1}(1-\psi)^{n_2}
        \sum_{i=0}^{n} A_i \binom{n}{i}\psi^i(1-\psi)^{n-i} + \psi\,\frac{y_{TE}}{c}

    The Bernstein polynomials sum to one, so equal weights ``A_i = 1`` return the class
    function itself. Near the nose ``y/c ~ A_0 sqrt(psi)`` for ``n1 = 0.5``, i.e. a nose
    radius of ``A_0**2 / 2`` chords.
    """
    psi_arr = np.asarray(psi, dtype=float)
    w = np.asarray(weights, dtype=float)
    if w.ndim != 1 or w.size == 0:
        raise ValueError("weights must be a non-empty 1-D sequence")
    tol = 1e-12
    if np.any(psi_arr < -tol) or np.any(psi_arr > 1.0 + tol):
        raise ValueError("psi must lie in [0, 1]")
    psi_arr = np.clip(psi_arr, 0.0, 1.0)
    n = w.size - 1
    one_minus = 1.0 - psi_arr
    shape = np.zeros_like(psi_arr)
    for i, a_i in enumerate(w):
        shape += a_i * comb(n, i) * psi_arr**i * one_minus ** (n - i)
    class_fn = psi_arr**n1 * one_minus**n2
    return class_fn * shape + psi_arr * te


def _golden_max(fun, a: float, b: float, tol: float = 1e-13) -> float:
    """Abscissa of the maximum of a unimodal function on [a, b] by golden-section search."""
    inv_phi = (np.sqrt(5.0) - 1.0) / 2.0
    c = b - inv_phi * (b - a)
    d = a + inv_phi * (b - a)
    fc, fd = fun(c), fun(d)
    while b - a > tol:
        if fc > fd:
            b, d, fd = d, c, fc
            c = b - inv_phi * (b - a)
            fc = fun(c)
        else:
            a, c, fc = c, d, fd
            d = a + inv_phi * (b - a)
            fd = fun(d)
    return 0.5 * (a + b)


@dataclass(frozen=True)
class CSTAirfoil:
    """Airfoil described by two CST surfaces with a sharp trailing edge.

    Parameters
    ----------
    upper : tuple of float, length n_u + 1
        CST weights of the upper surface (dimensionless, positive for a normal airfoil).
    lower : tuple of float, length n_l + 1
        CST weights of the lower surface (dimensionless, negative for a normal airfoil).
    chord : float, optional
        Chord length [mm]. Default 550 mm.
    n1, n2 : float, optional
        Class-function exponents (round nose, sharp trailing edge by default).

    Notes
    -----
    The leading edge is at (0, 0) and the trailing edge at (chord, 0). If
    ``upper[0] == -lower[0]`` both surfaces have the same nose radius and the contour's
    curvature is continuous through the leading edge.
    """

    upper: tuple[float, ...]
    lower: tuple[float, ...]
    chord: float = CHORD_MM
    n1: float = 0.5
    n2: float = 1.0

    def __post_init__(self) -> None:
        object.__setattr__(self, "upper", tuple(float(a) for a in self.upper))
        object.__setattr__(self, "lower", tuple(float(a) for a in self.lower))
        if not self.upper or not self.lower:
            raise ValueError("upper and lower weights must not be empty")
        if not self.chord > 0.0:
            raise ValueError("chord must be positive")

    def surfaces(self, x: ArrayLike) -> tuple[FloatArray, FloatArray]:
        """Ordinates of the upper and lower surface.

        Parameters
        ----------
        x : array_like, any shape
            Chordwise positions in [0, chord] [mm].

        Returns
        -------
        y_upper, y_lower : ndarray of float64, same shape as `x`
            Ordinates [mm].
        """
        psi = np.asarray(x, dtype=float) / self.chord
        y_u = self.chord * cst_surface(psi, self.upper, self.n1, self.n2)
        y_l = self.chord * cst_surface(psi, self.lower, self.n1, self.n2)
        return y_u, y_l

    def thickness(self, x: ArrayLike) -> FloatArray:
        """Local thickness ``y_upper - y_lower`` [mm] at chordwise positions `x` [mm]."""
        y_u, y_l = self.surfaces(x)
        return y_u - y_l

    def max_thickness_position(self) -> float:
        """Chordwise position of the maximum thickness [mm].

        A cosine-spaced sample of 2001 points brackets the maximum, and a golden-section
        search refines it to 1e-13 chords (the maximum value is then exact to round-off,
        because the thickness is stationary there).
        """
        psi = 0.5 * (1.0 - np.cos(np.linspace(0.0, np.pi, 2001)))
        t = self.thickness(psi * self.chord)
        k = int(np.argmax(t))
        lo, hi = psi[max(k - 1, 0)], psi[min(k + 1, psi.size - 1)]
        psi_max = _golden_max(lambda p: float(self.thickness(p * self.chord)), lo, hi)
        return psi_max * self.chord

    def max_thickness(self) -> float:
        """Maximum thickness [mm] (see :meth:`max_thickness_position` for the search)."""
        return float(self.thickness(self.max_thickness_position()))

    def scaled_to_thickness(self, t: float) -> "CSTAirfoil":
        """Copy with all weights scaled so that the maximum thickness is `t` [mm].

        Upper and lower weights are multiplied by the same factor, so thickness and camber
        keep their proportion (the camber line scales with the thickness). With a sharp
        trailing edge the thickness is linear in the weights and the scaling is exact.
        """
        if not t > 0.0:
            raise ValueError("thickness must be positive")
        k = t / self.max_thickness()
        return replace(
            self,
            upper=tuple(k * a for a in self.upper),
            lower=tuple(k * a for a in self.lower),
        )

    def contour(self, n: int = 201) -> FloatArray:
        """Closed contour from the trailing edge over the upper surface round the nose back.

        Parameters
        ----------
        n : int, optional
            Number of points (>= 3). Odd `n` includes the leading edge (0, 0) itself.

        Returns
        -------
        ndarray of float64, shape (n, 2)
            Points ``(x, y)`` [mm], trailing edge (upper) -> leading edge -> trailing edge
            (lower), with cosine spacing ``x = c (1 + cos beta) / 2``, beta in [0, 2 pi], which
            clusters points at the nose and the trailing edge.
        """
        if n < 3:
            raise ValueError("n must be at least 3")
        beta = np.linspace(0.0, 2.0 * np.pi, n)
        x = 0.5 * self.chord * (1.0 + np.cos(beta))
        y_u, y_l = self.surfaces(x)
        y = np.where(beta <= np.pi, y_u, y_l)
        return np.column_stack([x, y])


def high_speed_airfoil(chord: float = CHORD_MM, thickness: float = THICKNESS_MM) -> CSTAirfoil:
    """Cambered laminar-type sailplane airfoil, the undeformed (high-speed) skin shape.

    Parameters
    ----------
    chord : float, optional
        Chord [mm]. Default 550 mm.
    thickness : float, optional
        Maximum thickness [mm]. Default 67.5 mm (12.27 % of the chord).

    Returns
    -------
    CSTAirfoil
        Fifth-order CST airfoil (6 weights per surface) with the given chord and maximum
        thickness.

    Notes
    -----
    The paper's own airfoils come from an aerodynamic optimisation that is not published, so
    this is a stand-in with the features of a laminar sailplane section. The unscaled weights
    were set by hand as thickness weights ``T`` plus camber weights ``C`` (upper = T + C,
    lower = -T + C) and rounded to two decimals::

        upper = ( 0.14,  0.19,  0.23,  0.27,  0.24,  0.22)
        lower = (-0.14, -0.07, -0.09, -0.09, -0.06, -0.07)

    and then every weight is multiplied by one factor to reach the required thickness (this
    keeps the camber-to-thickness ratio). The choices, checked by evaluating the contour:

    * ``C_0 = 0`` (equal first weights): same nose radius on both sides, so the curvature is
      continuous round the nose, which the bent skin needs. After scaling the nose radius is
      ``A_0**2 / 2`` = 1.08 % of the chord (5.9 mm).
    * Thickness weights growing to the middle put the maximum thickness aft, at 39 % of the
      chord, as on laminar sections (long favourable pressure gradient).
    * Camber weights growing aft give a maximum camber of 2.8 % of the chord at 48 % and a
      lower surface that turns concave over the last 21 % (aft loading); the upper surface
      stays convex up to the trailing edge (the last two upper weights were set for that).
    """
    base = CSTAirfoil(upper=_HS_UPPER, lower=_HS_LOWER, chord=chord)
    return base.scaled_to_thickness(thickness)
