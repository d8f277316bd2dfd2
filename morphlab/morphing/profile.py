"""The whole wing section seen by the flow: the skin (F round the nose to G) joined to the fixed
rear part, a smooth spline through it, and its class/shape (CST) fit in NeuralFoil's form.

Everything here is a smooth function of the skin's node coordinates (splines, a Newton-refined
leading edge, a linear least-squares fit with a fixed design), so that aerodynamic responses
built on it can be differentiated by central differences. Lengths in mm (the model's units),
angles in rad unless named ``_deg``.
"""

from __future__ import annotations

from dataclasses import dataclass
from math import comb

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.interpolate import CubicSpline

from ..errors import ModelError
from .airfoil import X_SPAR_MM, leading_edge_curve
from .cst import CSTAirfoil, high_speed_airfoil

__all__ = ["skin_curve", "whole_airfoil", "Contour", "KulfanFit", "kulfan_fit", "N_KULFAN"]

FloatArray = NDArray[np.float64]

#: CST weights per surface of NeuralFoil's input (its networks take exactly 8).
N_KULFAN = 8


def _smoothstep(t: FloatArray) -> FloatArray:
    t = np.clip(t, 0.0, 1.0)
    return t * t * (3.0 - 2.0 * t)


def skin_curve(nodes: ArrayLike, airfoil: CSTAirfoil | None = None, *,
               n_dense: int = 2001) -> FloatArray:
    """Dense skin curve through displaced skin nodes: the exact undeformed curve plus the
    nodes' displacements interpolated along it.

    Parameters
    ----------
    nodes : array_like, shape (n_nodes, 2)
        Skin nodes F -> nose -> G [mm] (e.g. ``res.node_positions("skin")[-1]``, or
        :func:`~morphlab.morphing.geometry.target`), node k the image of undeformed node k,
        which lies at arc length ``k L / (n_nodes - 1)`` on the undeformed curve (the
        model's mesh, :func:`~morphlab.morphing.airfoil.target_nodes`).
    airfoil : CSTAirfoil, optional
        Undeformed section; default :func:`~morphlab.morphing.cst.high_speed_airfoil`.
    n_dense : int, optional
        Points of the undeformed curve (:func:`~morphlab.morphing.airfoil.leading_edge_curve`).

    Returns
    -------
    ndarray, shape (n_dense, 2)
        The deformed skin curve [mm].

    Notes
    -----
    The 30 elements of the model are ~10 mm long around a 5.9 mm nose radius: a spline
    through the node positions alone cuts the nose by 0.4 mm (and lifts the leading edge by
    0.9 mm), which shifts CL by 0.01. The displacement field, by contrast, is smooth along
    the skin (a droop of a few mm spread over its 300 mm), so a cubic spline of the nodal
    displacements in arc length, added to the exact undeformed curve, keeps the nose's
    shape: on the drooped target the curve so rebuilt from 31 nodes lies within 0.027 mm
    (RMS 0.006 mm) of the exact target curve, from 61 nodes within 0.003 mm.
    """
    af = high_speed_airfoil() if airfoil is None else airfoil
    q = np.real(np.asarray(nodes, dtype=complex)).astype(float)
    if q.ndim != 2 or q.shape[1] != 2 or q.shape[0] < 4:
        raise ModelError(f"nodes must have shape (n_nodes, 2) with n_nodes >= 4, got {q.shape}")
    dense = leading_edge_curve(af, x_spar=X_SPAR_MM, n=n_dense)
    seg = np.sqrt(np.sum(np.diff(dense, axis=0) ** 2, axis=1))
    s = np.concatenate([[0.0], np.cumsum(seg)])
    s_nodes = np.linspace(0.0, s[-1], q.shape[0])
    base = np.column_stack([np.interp(s_nodes, s, dense[:, 0]), np.interp(s_nodes, s, dense[:, 1])])
    return dense + CubicSpline(s_nodes, q - base, axis=0)(s)


def whole_airfoil(skin: ArrayLike | None = None, airfoil: CSTAirfoil | None = None, *,
                  n_rear: int = 121, fairing: float = 20.0) -> FloatArray:
    """Coordinates of the whole section: fixed rear upper surface, skin, fixed rear lower surface.

    Parameters
    ----------
    skin : array_like, shape (m, 2), optional
        Skin points from F (upper surface at the spar) round the nose to G (lower surface),
        e.g. ``res.node_positions("skin")[-1]`` [mm]. Default: the undeformed skin as a dense
        curve (401 points) of ``airfoil``.
    airfoil : CSTAirfoil, optional
        The fixed section; default :func:`~morphlab.morphing.cst.high_speed_airfoil`.
    n_rear : int, optional
        Points on each rear surface (cosine spacing, clustered at the spar and the trailing
        edge), F and G excluded.
    fairing : float, optional
        Length [mm] behind G over which the lower rear surface is blended into G's height.
        G slides aft in x (by ~4.6 mm when morphed) keeping its height, so it ends slightly
        off the fixed lower surface (a step of ~0.1 mm); the fairing removes the step with a
        smooth blend instead of a kink, which a panel method would turn into a spike.

    Returns
    -------
    ndarray, shape (2 n_rear + m, 2)
        Points [mm], trailing edge (upper) -> F -> nose -> G -> trailing edge (lower), i.e.
        counter-clockwise (Selig order). The trailing edge appears first and last.

    Raises
    ------
    ModelError
        If the skin does not start on the upper and end on the lower surface behind its
        nose, or lies outside the chord.
    """
    af = high_speed_airfoil() if airfoil is None else airfoil
    c = af.chord
    pts = (leading_edge_curve(af, x_spar=X_SPAR_MM, n=401) if skin is None
           else np.real(np.asarray(skin, dtype=complex)).astype(float))
    if pts.ndim != 2 or pts.shape[1] != 2 or pts.shape[0] < 5:
        raise ModelError(f"skin must have shape (m, 2) with m >= 5, got {pts.shape}")
    if n_rear < 8:
        raise ModelError(f"n_rear must be at least 8, got {n_rear}")
    x_f, x_g = pts[0, 0], pts[-1, 0]
    if not (0.0 < x_f < c and 0.0 < x_g < c) or not pts[0, 1] > pts[-1, 1]:
        raise ModelError("the skin must run from F on the upper surface round the nose to G on "
                         f"the lower surface, both inside the chord (0, {c}) mm; got F = "
                         f"{pts[0]}, G = {pts[-1]}")
    if not np.min(pts[:, 0]) < min(x_f, x_g):
        raise ModelError("the skin's nose must lie in front of F and G")
    if not fairing > 0.0:
        raise ModelError(f"fairing must be positive, got {fairing}")
    u = np.linspace(0.0, 1.0, n_rear + 1)
    # upper: trailing edge -> F (F itself excluded); lower: G (excluded) -> trailing edge
    xu = x_f + (c - x_f) * 0.5 * (1.0 + np.cos(np.pi * u[:-1]))
    xl = x_g + (c - x_g) * 0.5 * (1.0 - np.cos(np.pi * u[1:]))
    yu = af.surfaces(xu)[0]
    yl = af.surfaces(xl)[1]
    # blend the rear lower surface into G's height over the fairing (smooth in x_G)
    step = pts[-1, 1] - af.surfaces(np.array([x_g]))[1][0]
    yl = yl + step * (1.0 - _smoothstep((xl - x_g) / fairing))
    return np.vstack([np.column_stack([xu, yu]), pts, np.column_stack([xl, yl])])


class Contour:
    """Cubic spline through a closed airfoil polyline, parameterised by its chord length.

    Parameters
    ----------
    coordinates : array_like, shape (m, 2)
        Points in Selig order (trailing edge upper -> nose -> trailing edge lower), m >= 9.

    Attributes
    ----------
    s_le : float
        Spline parameter of the leading edge: the point farthest from the trailing edge
        (midpoint of the first and last point), found by Newton's method on the spline, so
        it moves continuously with the points.
    length : float
        Parameter at the last point (the polyline's length).
    """

    def __init__(self, coordinates: ArrayLike):
        pts = np.asarray(coordinates, dtype=float)
        if pts.ndim != 2 or pts.shape[1] != 2 or pts.shape[0] < 9:
            raise ModelError(f"coordinates must have shape (m, 2) with m >= 9, got {pts.shape}")
        seg = np.sqrt(np.sum(np.diff(pts, axis=0) ** 2, axis=1))
        if np.any(seg <= 0.0):
            raise ModelError("coordinates contain repeated consecutive points")
        self.points = pts
        self.s = np.concatenate([[0.0], np.cumsum(seg)])
        self.length = float(self.s[-1])
        self._spline = CubicSpline(self.s, pts, axis=0)
        self.te = 0.5 * (pts[0] + pts[-1])
        self.s_le = self._leading_edge()

    def __call__(self, s: ArrayLike, nu: int = 0) -> FloatArray:
        """Points (or their ``nu``-th derivative in s) at parameters ``s``, shape (..., 2)."""
        return self._spline(s, nu)

    def _leading_edge(self) -> float:
        d = self.points - self.te
        k = int(np.argmax(np.sum(d * d, axis=1)))
        s = float(self.s[k])
        lo, hi = self.s[max(k - 1, 0)], self.s[min(k + 1, self.s.size - 1)]
        for _ in range(30):  # Newton on g(s) = (p - te) . p' = 0, kept inside the bracket
            p, dp, ddp = self(s), self(s, 1), self(s, 2)
            g = float(np.dot(p - self.te, dp))
            dg = float(np.dot(dp, dp) + np.dot(p - self.te, ddp))
            step = -g / dg if dg < 0.0 else 0.0  # a maximum has dg < 0
            s = float(np.clip(s + step, lo, hi))
            if abs(step) < 1e-14 * self.length:
                break
        return s

    @property
    def leading_edge(self) -> FloatArray:
        """Leading-edge point, shape (2,)."""
        return self(self.s_le)

    @property
    def chord(self) -> float:
        """Distance from the trailing edge to the leading edge."""
        return float(np.linalg.norm(self.leading_edge - self.te))

    @property
    def chord_angle(self) -> float:
        """Angle [rad] of the chord line (leading edge -> trailing edge) against the x axis,
        positive counter-clockwise (a drooped nose gives a positive angle)."""
        d = self.te - self.leading_edge
        return float(np.arctan2(d[1], d[0]))

    def sides(self, n_per_side: int) -> tuple[FloatArray, FloatArray]:
        """Parameters of ``n_per_side`` points on the upper (trailing edge -> leading edge) and
        lower (leading edge -> trailing edge) surface, cosine-clustered at both ends of each.
        Both include the leading edge; the upper one starts and the lower one ends at the
        trailing edge."""
        u = 0.5 * (1.0 - np.cos(np.pi * np.linspace(0.0, 1.0, n_per_side)))
        return self.s_le * u, self.s_le + (self.length - self.s_le) * u

    def panel_parameters(self, n_panels: int) -> FloatArray:
        """Spline parameters of :meth:`resample`'s nodes, shape (n_panels + 1,)."""
        if n_panels < 16 or n_panels % 2:
            raise ModelError(f"n_panels must be an even number >= 16, got {n_panels}")
        up, low = self.sides(n_panels // 2 + 1)
        return np.concatenate([up, low[1:]])

    def resample(self, n_panels: int) -> FloatArray:
        """Panel nodes for :func:`~morphlab.morphing.panel.panel_solution`: ``n_panels + 1``
        points (n_panels even), clustered at the trailing and leading edges."""
        return self(self.panel_parameters(n_panels))

    def normalized(self, xy: ArrayLike) -> FloatArray:
        """Points in the chord frame: leading edge at (0, 0), trailing edge at (1, 0)."""
        d = np.asarray(xy, dtype=float) - self.leading_edge
        a = self.chord_angle
        c, s = np.cos(a), np.sin(a)
        return np.stack([c * d[..., 0] + s * d[..., 1], -s * d[..., 0] + c * d[..., 1]],
                        axis=-1) / self.chord

    def at_x(self, xc: ArrayLike, upper: bool) -> FloatArray:
        """Spline parameters of the points at chord-frame abscissae ``xc`` (x/c in [0, 1]) on
        the upper or lower surface: Newton's method on the spline from a dense sample."""
        xc = np.atleast_1d(np.asarray(xc, dtype=float))
        if np.any(xc < 0.0) or np.any(xc > 1.0):
            raise ModelError("xc must lie in [0, 1]")
        s = (np.linspace(0.0, self.s_le, 401) if upper
             else np.linspace(self.s_le, self.length, 401))
        x = self.normalized(self(s))[:, 0]
        order = np.argsort(x)
        s_k = np.interp(xc, x[order], s[order])
        lo, hi = s[0], s[-1]
        for _ in range(20):
            p, dp = self.normalized(self(s_k)), self(s_k, 1)
            a = self.chord_angle
            dx = (np.cos(a) * dp[:, 0] + np.sin(a) * dp[:, 1]) / self.chord
            step = (p[:, 0] - xc) / dx
            s_k = np.clip(s_k - step, lo, hi)
            if np.max(np.abs(step)) < 1e-13 * self.length:
                break
        return s_k

    def locate(self, points: ArrayLike) -> FloatArray:
        """Spline parameter of the contour point nearest to each of ``points`` (m, 2): the
        nearest point of the polyline, refined by Newton's method on the spline."""
        q = np.atleast_2d(np.asarray(points, dtype=float))
        a, b = self.points[:-1], self.points[1:]
        ab = b - a
        t = np.clip(np.einsum("ijk,jk->ij", q[:, None, :] - a[None], ab)
                    / np.sum(ab * ab, axis=1)[None], 0.0, 1.0)
        dist = np.sum((a[None] + t[..., None] * ab[None] - q[:, None, :]) ** 2, axis=-1)
        j = np.argmin(dist, axis=1)
        s = self.s[j] + t[np.arange(q.shape[0]), j] * (self.s[j + 1] - self.s[j])
        for _ in range(8):
            p, dp, ddp = self(s), self(s, 1), self(s, 2)
            g = np.sum((p - q) * dp, axis=1)
            dg = np.sum(dp * dp + (p - q) * ddp, axis=1)
            s = np.clip(s - g / dg, 0.0, self.length)
        return s


@dataclass(frozen=True)
class KulfanFit:
    """CST ("Kulfan") parameters of a contour in NeuralFoil's form and the chord frame they
    live in.

    Attributes
    ----------
    parameters : dict
        ``upper_weights``, ``lower_weights`` (8 each, leading edge first),
        ``leading_edge_weight``, ``TE_thickness`` (chord-normalised).
    leading_edge : ndarray, shape (2,)
        Leading-edge point in the coordinates' units.
    chord : float
        Leading edge to trailing edge, in the coordinates' units.
    chord_angle : float
        Chord-line angle against the x axis [rad], positive counter-clockwise.
    rms : float
        RMS of the fit's residual in y/c over the fitted points.
    """

    parameters: dict
    leading_edge: FloatArray
    chord: float
    chord_angle: float
    rms: float


def _bernstein(x: FloatArray, n: int) -> FloatArray:
    k = np.arange(n + 1)
    binom = np.array([comb(n, i) for i in k], dtype=float)
    return binom[None, :] * x[:, None] ** k[None, :] * (1.0 - x[:, None]) ** (n - k)[None, :]


def kulfan_fit(contour: Contour, n_points: int = 120) -> KulfanFit:
    """Least-squares CST fit of a contour with NeuralFoil's parameterisation.

    Parameters
    ----------
    contour : Contour
        The section.
    n_points : int, optional
        Points per surface in the fit (cosine-clustered at both ends).

    Returns
    -------
    KulfanFit

    Notes
    -----
    In the chord frame each surface is ``y = C(x) S(x) +- x t_TE / 2 + w_LE x (1 - x)**8.5``
    with the class function ``C = sqrt(x) (1 - x)``, the shape function ``S`` a Bernstein
    polynomial of degree 7 with the 8 weights of that surface, and Kulfan's leading-edge
    modification ``w_LE`` shared by both (the form NeuralFoil was trained on: Kulfan 2008 and
    "Modification of CST airfoil representation methodology", 2020). ``t_TE`` is not fitted
    but taken from the gap between the first and last point (zero for a sharp trailing edge),
    which keeps the fit one linear least-squares solve with a fixed structure: the weights are
    then smooth functions of the points.
    """
    if n_points < 2 * N_KULFAN:
        raise ModelError(f"n_points must be at least {2 * N_KULFAN}, got {n_points}")
    up, low = contour.sides(n_points)
    pu = contour.normalized(contour(up[:-1]))  # leading edge itself carries no information
    pl = contour.normalized(contour(low[1:]))
    gap = float(np.linalg.norm(contour.points[0] - contour.points[-1])) / contour.chord
    xu, xl = np.clip(pu[:, 0], 0.0, 1.0), np.clip(pl[:, 0], 0.0, 1.0)
    n = N_KULFAN - 1

    def rows(x):
        cls = np.sqrt(x) * (1.0 - x)
        return cls[:, None] * _bernstein(x, n), x * (1.0 - x) ** (N_KULFAN + 0.5)

    bu, lem_u = rows(xu)
    bl, lem_l = rows(xl)
    a = np.zeros((xu.size + xl.size, 2 * N_KULFAN + 1))
    a[: xu.size, :N_KULFAN] = bu
    a[xu.size:, N_KULFAN:2 * N_KULFAN] = bl
    a[: xu.size, -1] = lem_u
    a[xu.size:, -1] = lem_l
    b = np.concatenate([pu[:, 1] - xu * gap / 2.0, pl[:, 1] + xl * gap / 2.0])
    w, *_ = np.linalg.lstsq(a, b, rcond=None)
    rms = float(np.sqrt(np.mean((a @ w - b) ** 2)))
    params = {"upper_weights": w[:N_KULFAN], "lower_weights": w[N_KULFAN:2 * N_KULFAN],
              "leading_edge_weight": float(w[-1]), "TE_thickness": gap}
    return KulfanFit(parameters=params, leading_edge=contour.leading_edge, chord=contour.chord,
                     chord_angle=contour.chord_angle, rms=rms)
