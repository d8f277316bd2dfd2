"""Inviscid pressure distribution of an airfoil: a linear-vorticity panel method and, to verify
it, the exact potential flow about a Kármán–Trefftz airfoil.

The panel method resolves the suction peak at the nose, which the boundary-layer stations of
NeuralFoil (32 per side, the first at x/c = 1/64) do not; :mod:`morphlab.morphing.aero` uses it
for the pressure on the skin. Lengths are those of the coordinates given (any unit); speeds
are per unit freestream speed; angles in degrees.

Method (Katz & Plotkin, *Low-Speed Aerodynamics*, 2nd ed., §11.4, in our own formulation):
the contour, ordered from the trailing edge over the upper surface round the nose and back
along the lower surface (counter-clockwise), carries a vortex sheet whose strength varies
linearly along each panel between nodal values ``gamma_j``. The normal velocity vanishes at
each panel's midpoint and the Kutta condition ``gamma_0 + gamma_N = 0`` closes the system.
The flow inside the contour is then at rest, so the surface speed on the outside equals the
local sheet strength: ``Cp_j = 1 - gamma_j**2`` at every node. Lift follows from the
circulation by Kutta–Joukowski, ``CL = 2 Gamma / (V c)``. The solution is linear in
``(cos alpha, sin alpha)``: two solves give every angle of attack.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..errors import ModelError

__all__ = ["PanelSolution", "panel_solution", "karman_trefftz"]

FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class PanelSolution:
    """Unit solutions of the panel method on one contour.

    Attributes
    ----------
    nodes : ndarray, shape (N + 1, 2)
        Panel end points, trailing edge (upper) -> nose -> trailing edge (lower).
    gamma0, gamma90 : ndarray, shape (N + 1,)
        Nodal sheet strength (= outer surface speed per unit freestream speed, positive in
        the direction of the ordering) for the freestream along x and along y.
    chord : float
        Distance from the trailing edge to the farthest node (the leading edge).
    """

    nodes: FloatArray
    gamma0: FloatArray
    gamma90: FloatArray
    chord: float

    def gamma(self, alpha_deg: float) -> FloatArray:
        """Nodal surface speed per unit freestream speed at angle of attack ``alpha_deg``."""
        a = np.radians(alpha_deg)
        return np.cos(a) * self.gamma0 + np.sin(a) * self.gamma90

    def cp(self, alpha_deg: float) -> FloatArray:
        """Pressure coefficient at the nodes, ``1 - gamma**2``, shape (N + 1,).

        The two trailing-edge nodes are NaN: their strengths carry the Kutta condition and are
        no surface speed (the exact speed at a trailing edge of finite angle is zero).
        """
        cp = 1.0 - self.gamma(alpha_deg) ** 2
        cp[0] = cp[-1] = np.nan
        return cp

    def _circulation(self, g: FloatArray) -> float:
        seg = np.diff(self.nodes, axis=0)
        length = np.sqrt(np.sum(seg * seg, axis=1))
        # clockwise circulation (positive lift) is the sheet integral along the ordering
        return float(np.sum(0.5 * (g[:-1] + g[1:]) * length))

    def cl(self, alpha_deg: float) -> float:
        """Lift coefficient by Kutta–Joukowski, ``2 Gamma / (V c)`` with c = :attr:`chord`."""
        return 2.0 * self._circulation(self.gamma(alpha_deg)) / self.chord

    def alpha_for_cl(self, cl: float) -> float:
        """Angle of attack [deg] at which :meth:`cl` equals ``cl`` (the branch nearest zero).

        ``CL(alpha) = A cos(alpha) + B sin(alpha)`` exactly, so the angle is closed-form.
        """
        A = 2.0 * self._circulation(self.gamma0) / self.chord
        B = 2.0 * self._circulation(self.gamma90) / self.chord
        amp = np.hypot(A, B)
        if not abs(cl) < amp:
            raise ModelError(f"lift coefficient {cl} is beyond the inviscid range +-{amp:.3f}")
        # A cos(alpha) + B sin(alpha) = amp sin(alpha + psi) with psi = atan2(A, B)
        return float(np.degrees(np.arcsin(cl / amp) - np.arctan2(A, B)))


def _influence(nodes: FloatArray) -> tuple[FloatArray, FloatArray]:
    """Normal velocity at every panel midpoint per unit nodal strength, (N, N + 1), and the
    outward normals, (N, 2)."""
    p0, p1 = nodes[:-1], nodes[1:]
    seg = p1 - p0
    length = np.sqrt(np.sum(seg * seg, axis=1))
    t = seg / length[:, None]
    n_left = np.column_stack([-t[:, 1], t[:, 0]])
    mid = 0.5 * (p0 + p1)
    # collocation point i in the frame of panel j: (x, y), panel from (0, 0) to (l_j, 0)
    d = mid[:, None, :] - p0[None, :, :]
    x = np.sum(d * t[None], axis=2)
    y = np.sum(d * n_left[None], axis=2)
    lj = length[None, :]
    r1sq = x * x + y * y
    r2sq = (x - lj) ** 2 + y * y
    i1 = np.arctan2(y, x - lj) - np.arctan2(y, x)
    np.fill_diagonal(i1, 0.0)  # tangential self-induction does not enter the normal velocity
    i2 = 0.5 * np.log(r1sq / r2sq)
    j1 = x * i1 - y * i2
    j2 = x * i2 - (lj - y * i1)
    # velocity of a sheet gamma(xi) = ga (1 - xi/l) + gb xi/l, point vortices of the
    # counter-clockwise sense: u = -1/(2 pi) int gamma y / r^2, v = 1/(2 pi) int gamma (x - xi)/r^2
    ua = -(i1 - j1 / lj) / (2.0 * np.pi)
    ub = -(j1 / lj) / (2.0 * np.pi)
    va = (i2 - j2 / lj) / (2.0 * np.pi)
    vb = (j2 / lj) / (2.0 * np.pi)
    n_out = -n_left  # counter-clockwise contour: the outside is on the right
    # global velocity = u t_j + v n_j; its component along the outward normal of panel i
    tn = t[None, :, 0] * n_out[:, None, 0] + t[None, :, 1] * n_out[:, None, 1]
    nn = n_left[None, :, 0] * n_out[:, None, 0] + n_left[None, :, 1] * n_out[:, None, 1]
    ca = ua * tn + va * nn
    cb = ub * tn + vb * nn
    n_pan = nodes.shape[0] - 1
    a = np.zeros((n_pan, n_pan + 1))
    a[:, :-1] += ca
    a[:, 1:] += cb
    return a, n_out


def panel_solution(nodes: ArrayLike, chord: float | None = None) -> PanelSolution:
    """Solve the linear-vorticity panel method on a closed contour.

    Parameters
    ----------
    nodes : array_like, shape (N + 1, 2)
        Contour points from the trailing edge over the upper surface round the nose to the
        trailing edge on the lower surface (counter-clockwise), N >= 8. The first and last
        point are the trailing edge (equal for a sharp trailing edge).

    Returns
    -------
    PanelSolution
        Unit solutions for the freestream along x and along y.

    Raises
    ------
    ModelError
        For a contour of the wrong shape, with zero-length panels, or ordered clockwise.
    """
    pts = np.asarray(nodes, dtype=float)
    if pts.ndim != 2 or pts.shape[1] != 2 or pts.shape[0] < 9:
        raise ModelError(f"nodes must have shape (N + 1, 2) with N >= 8, got {pts.shape}")
    seg = np.diff(pts, axis=0)
    if np.any(np.sum(seg * seg, axis=1) <= 0.0):
        raise ModelError("nodes contain repeated consecutive points (zero-length panels)")
    area2 = np.sum(pts[:-1, 0] * pts[1:, 1] - pts[1:, 0] * pts[:-1, 1])
    if not area2 > 0.0:
        raise ModelError("nodes must run counter-clockwise: trailing edge, upper surface, nose, "
                         "lower surface (Selig order)")
    a, n_out = _influence(pts)
    n_pan = pts.shape[0] - 1
    m = np.zeros((n_pan + 1, n_pan + 1))
    m[:n_pan] = a
    m[n_pan, 0] = m[n_pan, -1] = 1.0  # Kutta: the two trailing-edge speeds cancel
    rhs = np.zeros((n_pan + 1, 2))
    rhs[:n_pan, 0] = -n_out[:, 0]  # freestream (1, 0)
    rhs[:n_pan, 1] = -n_out[:, 1]  # freestream (0, 1)
    sol = np.linalg.solve(m, rhs)
    if chord is None:
        te = 0.5 * (pts[0] + pts[-1])
        chord = float(np.max(np.sqrt(np.sum((pts - te) ** 2, axis=1))))
    elif not chord > 0.0:
        raise ModelError(f"chord must be positive, got {chord}")
    # the ordering runs against the outer flow on the upper surface: report the speed along it
    return PanelSolution(nodes=pts, gamma0=-sol[:, 0], gamma90=-sol[:, 1], chord=float(chord))


def karman_trefftz(center: complex, exponent: float, alpha_deg: float,
                   n_points: int = 401) -> dict:
    """Exact potential flow about a Kármán–Trefftz airfoil (conformal map of a circle).

    Parameters
    ----------
    center : complex
        Centre ``mu`` of the circle in the ``zeta`` plane; the circle passes through
        ``zeta = 1`` and must enclose ``zeta = -1`` (``real(center) < 0`` suffices for a
        small ``imag(center)``). ``-real`` sets the thickness, ``imag`` the camber.
    exponent : float
        ``n = 2 - tau / pi`` in (1, 2] (tau: trailing-edge angle); 2 is the Joukowski map.
    alpha_deg : float
        Angle of attack of the freestream against the x axis [deg].
    n_points : int
        Contour points (odd), trailing edge first and last.

    Returns
    -------
    dict
        ``"xy"`` (n_points, 2) contour, counter-clockwise from the trailing edge;
        ``"cp"`` (n_points,) exact pressure coefficient (NaN at the trailing edge, where the
        map is singular); ``"cl"`` exact lift coefficient on ``"chord"``, the distance from the
        trailing edge to the farthest contour point.

    Notes
    -----
    Map ``z = n (1 + r) / (1 - r)``, ``r = ((zeta - 1)/(zeta + 1))**n`` (b = 1), so
    ``dz/dzeta = 4 n**2 r / ((zeta**2 - 1)(1 - r)**2)``. On the circle
    ``zeta = mu + R exp(i theta)``, ``R = |1 - mu|``, the complex velocity about the circle
    with circulation ``Gamma = 4 pi R V sin(alpha - theta_TE)`` (Kutta condition at
    ``zeta = 1``) is ``W = V (exp(-i alpha) - R**2 exp(i alpha)/(zeta - mu)**2)
    + i Gamma / (2 pi (zeta - mu))``; the speed on the airfoil is ``|W| / |dz/dzeta|``.
    Because ``(zeta - 1)/(zeta + 1)`` is real and negative only for real zeta in (-1, 1),
    which the circle does not cross, the principal power has no branch cut on the contour.
    """
    mu = complex(center)
    n = float(exponent)
    if not 1.0 < n <= 2.0:
        raise ModelError(f"exponent must lie in (1, 2], got {n}")
    radius = abs(1.0 - mu)
    if not abs(-1.0 - mu) < radius:
        raise ModelError("the circle must enclose zeta = -1 (make real(center) negative)")
    theta_te = np.angle(1.0 - mu)
    theta = theta_te + np.linspace(0.0, 2.0 * np.pi, n_points)
    zeta = mu + radius * np.exp(1j * theta)
    zeta[0] = zeta[-1] = 1.0
    with np.errstate(divide="ignore", invalid="ignore"):
        r = ((zeta - 1.0) / (zeta + 1.0)) ** n
        z = n * (1.0 + r) / (1.0 - r)
        dz = 4.0 * n * n * r / ((zeta * zeta - 1.0) * (1.0 - r) ** 2)
        alpha = np.radians(alpha_deg)
        circulation = 4.0 * np.pi * radius * np.sin(alpha - theta_te)
        w = (np.exp(-1j * alpha) - radius**2 * np.exp(1j * alpha) / (zeta - mu) ** 2
             + 1j * circulation / (2.0 * np.pi * (zeta - mu)))
        speed = np.abs(w) / np.abs(dz)
    cp = 1.0 - speed**2
    cp[0] = cp[-1] = np.nan
    xy = np.column_stack([z.real, z.imag])
    # chord: farthest point from the trailing edge, on a dense sample of the same contour
    dense = mu + radius * np.exp(1j * (theta_te + np.linspace(1e-3, 2.0 * np.pi - 1e-3, 20001)))
    rd = ((dense - 1.0) / (dense + 1.0)) ** n
    chord = float(np.max(np.abs(n * (1.0 + rd) / (1.0 - rd) - n)))
    return {"xy": xy, "cp": cp, "cl": 2.0 * circulation / chord, "chord": chord}
