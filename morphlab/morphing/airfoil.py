"""CST airfoil geometry and the target shapes of the morphing leading edge (paper §4).

The wing section of the paper has a chord of 550 mm and a maximum thickness of 67.5 mm; its
leading-edge section is the front 137.5 mm of the chord, bounded by the front spar. The flexible
skin runs from point F (upper surface at the spar) round the nose to point G (lower surface at
the spar). F is clamped; G keeps its y coordinate and its rotation and slides freely in x.

This module provides

* the class/shape transformation (CST) of Kulfan [1]_ and the high-speed airfoil used as the
  undeformed skin shape (from :mod:`morphlab.morphing.cst`),
* polyline tools (:func:`leading_edge_curve`, :func:`arc_length`, :func:`resample_equal_arc`),
* the drooped-nose low-speed target (:func:`drooped_curve`) and the node-by-node mapping of
  both shapes at equal arc length (:func:`target_nodes`).

All lengths are in mm, all angles in rad. Only the geometry is computed here; nothing in this
module is a design variable of the sensitivity analysis, so it works on float64 arrays only.

References
----------
.. [1] B. M. Kulfan, "Universal parametric geometry representation method", Journal of
   Aircraft 45(1), 142-158, 2008. doi:10.2514/1.29958
"""

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .cst import CHORD_MM, THICKNESS_MM, CSTAirfoil, cst_surface, high_speed_airfoil

__all__ = [
    "CHORD_MM",
    "THICKNESS_MM",
    "X_SPAR_MM",
    "DEFAULT_DROOP_MM",
    "cst_surface",
    "CSTAirfoil",
    "high_speed_airfoil",
    "leading_edge_curve",
    "arc_length",
    "resample_equal_arc",
    "leading_edge_point",
    "drooped_curve",
    "target_nodes",
]

FloatArray = NDArray[np.float64]

#: x position of the front spar, i.e. of the skin ends F and G [mm].
X_SPAR_MM = 137.5
#: Default droop of the low-speed target: downward displacement of the leading edge [mm].
#: With this value the skin's tangent turns by at most ~0.096 rad (see :func:`target_nodes`),
#: so the spurious stretch of linear FFRF kinematics (~phi^2/2 of an element's length) stays
#: below 0.5 % locally and sums to ~0.5 mm over the whole skin.
DEFAULT_DROOP_MM = 6.0

def _as_curve(curve: ArrayLike, min_points: int = 2) -> FloatArray:
    pts = np.asarray(curve, dtype=float)
    if pts.ndim != 2 or pts.shape[1] != 2 or pts.shape[0] < min_points:
        raise ValueError(f"curve must have shape (m, 2) with m >= {min_points}")
    return pts


def leading_edge_curve(airfoil: CSTAirfoil, x_spar: float = X_SPAR_MM, n: int = 2001) -> FloatArray:
    """Dense polyline of the skin from F round the nose to G.

    Parameters
    ----------
    airfoil : CSTAirfoil
        Airfoil whose front part is the skin.
    x_spar : float, optional
        Chordwise position of the front spar, i.e. of F and G [mm]. Default 137.5 mm.
    n : int, optional
        Number of points (>= 3). Default 2001.

    Returns
    -------
    ndarray of float64, shape (n, 2)
        Points ``(x, y)`` [mm] ordered F = (x_spar, y_upper(x_spar)) -> nose ->
        G = (x_spar, y_lower(x_spar)).

    Notes
    -----
    The points use ``x = x_spar (1 + cos beta) / 2`` with beta equally spaced in [0, 2 pi]
    (upper surface for beta <= pi). Since ``y ~ sqrt(x)`` at the nose, ``y`` is then a smooth,
    sign-changing function of beta there, and the nose is as well resolved as the rest. For odd
    `n` the leading edge (0, 0) is one of the points. With n = 2001 the largest segment is
    about 0.2 mm long and the polyline stays within 1e-4 mm of the true contour.
    """
    if not 0.0 < x_spar < airfoil.chord:
        raise ValueError("x_spar must lie inside the chord")
    if n < 3:
        raise ValueError("n must be at least 3")
    beta = np.linspace(0.0, 2.0 * np.pi, n)
    x = 0.5 * x_spar * (1.0 + np.cos(beta))
    x[0] = x[-1] = x_spar  # cos(2 pi) is not exactly 1 in floating point
    y_u, y_l = airfoil.surfaces(x)
    y = np.where(beta <= np.pi, y_u, y_l)
    return np.column_stack([x, y])


def _cumulative_arc(pts: FloatArray) -> FloatArray:
    seg = np.diff(pts, axis=0)
    return np.concatenate([[0.0], np.cumsum(np.hypot(seg[:, 0], seg[:, 1]))])


def arc_length(curve: ArrayLike) -> float:
    """Length of a polyline.

    Parameters
    ----------
    curve : array_like, shape (m, 2)
        Vertices [mm].

    Returns
    -------
    float
        Sum of the segment lengths [mm].
    """
    pts = _as_curve(curve)
    return float(_cumulative_arc(pts)[-1])


def resample_equal_arc(curve: ArrayLike, n_nodes: int) -> FloatArray:
    """Points at equal arc-length spacing along a polyline.

    Parameters
    ----------
    curve : array_like, shape (m, 2)
        Vertices of a dense polyline [mm].
    n_nodes : int
        Number of points to return (>= 2).

    Returns
    -------
    ndarray of float64, shape (n_nodes, 2)
        Point k lies at arc length ``k L / (n_nodes - 1)`` along the polyline (L: its length),
        found by linear interpolation within the segment that contains it. The first and last
        vertices are returned exactly.
    """
    pts = _as_curve(curve)
    if n_nodes < 2:
        raise ValueError("n_nodes must be at least 2")
    s = _cumulative_arc(pts)
    if not s[-1] > 0.0:
        raise ValueError("curve has zero length")
    s_new = np.linspace(0.0, s[-1], n_nodes)
    out = np.column_stack([np.interp(s_new, s, pts[:, 0]), np.interp(s_new, s, pts[:, 1])])
    out[0] = pts[0]
    out[-1] = pts[-1]
    return out


def leading_edge_point(curve: ArrayLike) -> tuple[float, float, float]:
    """Point of minimum x of a polyline, refined between vertices.

    Parameters
    ----------
    curve : array_like, shape (m, 2)
        Vertices [mm].

    Returns
    -------
    x_le, y_le, s_le : float
        Coordinates of the leading-edge point [mm] and its arc-length position from the first
        vertex [mm].

    Notes
    -----
    A parabola in the arc length through the vertex of smallest x and its two neighbours gives
    the position of the minimum; x and y are then interpolated quadratically through the same
    three vertices. On a smooth, densely sampled curve this is accurate to O(h^3) (h: segment
    length) and varies continuously when the curve moves, which the droop solver relies on.
    """
    pts = _as_curve(curve)
    s = _cumulative_arc(pts)
    k = int(np.argmin(pts[:, 0]))
    if k == 0 or k == pts.shape[0] - 1:
        return float(pts[k, 0]), float(pts[k, 1]), float(s[k])
    s3 = s[k - 1 : k + 2]
    x3 = pts[k - 1 : k + 2, 0]
    y3 = pts[k - 1 : k + 2, 1]
    px = np.polyfit(s3 - s3[1], x3, 2)
    py = np.polyfit(s3 - s3[1], y3, 2)
    ds = -px[1] / (2.0 * px[0]) if px[0] > 0.0 else 0.0
    ds = float(np.clip(ds, s3[0] - s3[1], s3[2] - s3[1]))
    return float(np.polyval(px, ds)), float(np.polyval(py, ds)), float(s3[1] + ds)


def _rotate_segments(seg: FloatArray, angle: FloatArray) -> FloatArray:
    c, s = np.cos(angle), np.sin(angle)
    return np.column_stack([c * seg[:, 0] - s * seg[:, 1], s * seg[:, 0] + c * seg[:, 1]])


def drooped_curve(
    curve: ArrayLike,
    droop: float,
    x_spar: float = X_SPAR_MM,
    *,
    blend_depth: float = 1.0,
    tol: float = 1e-11,
    max_iter: int = 50,
) -> FloatArray:
    """Low-speed target: the skin curve with its nose drooped, at constant arc length.

    (Long for its documentation: the code builds the blend and solves for its two
    coefficients.)

    Parameters
    ----------
    curve : array_like, shape (m, 2)
        Dense skin polyline F -> nose -> G [mm], e.g. from :func:`leading_edge_curve`; both
        ends at ``x >= x_spar``, the nose at its minimum x.
    droop : float
        Required downward displacement of the leading edge [mm] (positive: nose down).
    x_spar : float, optional
        x position of the spar [mm]; the skin behind it (x >= x_spar) is not rotated.
        Default 137.5 mm.
    blend_depth : float, optional
        Fraction of the spar-to-leading-edge distance over which the rotation fades in, in
        (0, 1]. 1 (default): the rotation grows all the way to the leading edge (smallest
        change of curvature). Smaller values turn the front of the nose as a rigid body and
        concentrate the bending near the spar (smaller rotations and G shift, larger
        curvature change; for a 6 mm droop, 0.5 gives 0.063 rad and 3.5 mm instead of
        0.096 rad and 4.6 mm).
    tol : float, optional
        Tolerance on the two closure conditions below [mm].
    max_iter : int, optional
        Maximum number of Newton iterations.

    Returns
    -------
    ndarray of float64, shape (m, 2)
        Drooped polyline [mm]; vertex j is the image of vertex j of `curve` (same arc-length
        position), F is unchanged and G has moved in x only.

    Raises
    ------
    ValueError
        If the curve's ends lie in front of the spar.
    RuntimeError
        If Newton's method does not converge.

    Notes
    -----
    The construction rotates the skin's tangent and integrates it again, segment by segment:

    1. Each segment k of the polyline (vector ``d_k``, arc-length midpoint ``s_k``, midpoint
       abscissa ``x_k``) is turned by an angle ``dtheta_k`` and the vertices are rebuilt from F
       by summing the turned segments: ``p'_0 = F``, ``p'_{j+1} = p'_j + R(dtheta_j) d_j``.
       Rotation keeps every segment length, so the arc length F -> G and the arc-length
       position of every vertex are kept exactly (to round-off).
    2. The turning angle is ``dtheta(s) = b(xi) (a + c (s - s_le) / L)`` with
       ``xi = (x_spar - x) / (blend_depth (x_spar - x_le))`` clipped to [0, 1] (0 at the
       spar, 1 at the leading edge for ``blend_depth = 1``), the smooth step
       ``b(xi) = xi^2 (3 - 2 xi)``, L the arc length and s_le the arc-length position of the
       leading edge. The term ``a`` turns the nose downwards about the spar region (a
       hinge-like rotation that fades out towards F and G); the term ``c`` tilts the rotation
       towards the upper or the lower side.
    3. ``b`` and its derivative vanish at ``xi = 0``, so ``dtheta`` and ``d dtheta / ds``
       vanish at F and G: position and tangent at F are kept, the tangent at G is kept, and
       even the curvature at F and G is unchanged (the change of curvature along the skin is
       ``d dtheta / ds``, continuous everywhere).
    4. The two coefficients (a, c) are found by Newton's method (finite-difference Jacobian) so
       that (i) G keeps its y coordinate and (ii) the leading edge of the result -- its point
       of minimum x, see :func:`leading_edge_point` -- lies `droop` below the leading edge of
       `curve`: ``y_le(target) = y_le(curve) - droop``. G's x coordinate is free (G slides
       along x); its change is ``result[-1, 0] - curve[-1, 0]``.

    Because F is the clamp and the construction starts there, no trimming or extension near G
    is needed. On a discrete polyline the tangent at F and G changes by ``dtheta`` of the
    first and last segment, ``~3 a xi^2`` with xi of that segment's midpoint (~1e-12 rad for
    :func:`leading_edge_curve` with n = 2001).

    For the default airfoil and droop (6 mm) the result has ``a = 0.096 rad``, G moves
    4.6 mm aft, and the leading edge moves 3.0 mm aft as well: a rotation that fades in
    gradually curls the skin (more turning per length), which shortens the nose in x.
    """
    pts = _as_curve(curve, min_points=3)
    droop = float(droop)
    x_le0, y_le0, s_le0 = leading_edge_point(pts)
    depth = x_spar - x_le0
    if not depth > 0.0:
        raise ValueError("the leading edge must lie in front of the spar")
    if min(pts[0, 0], pts[-1, 0]) < x_spar - 1e-9 * depth:
        raise ValueError("the curve's ends must not lie in front of the spar")

    seg = np.diff(pts, axis=0)
    seg_len = np.hypot(seg[:, 0], seg[:, 1])
    s_mid = np.cumsum(seg_len) - 0.5 * seg_len
    length = float(np.sum(seg_len))
    if not 0.0 < blend_depth <= 1.0:
        raise ValueError("blend_depth must lie in (0, 1]")
    xi = np.clip((x_spar - 0.5 * (pts[:-1, 0] + pts[1:, 0])) / (blend_depth * depth), 0.0, 1.0)
    blend = xi * xi * (3.0 - 2.0 * xi)
    basis = np.stack([blend, blend * (s_mid - s_le0) / length])  # (2, m - 1)

    def build(coef: FloatArray) -> FloatArray:
        turned = _rotate_segments(seg, coef @ basis)
        return np.vstack([pts[:1], pts[0] + np.cumsum(turned, axis=0)])

    def residual(coef: FloatArray) -> FloatArray:
        new = build(coef)
        _, y_le, _ = leading_edge_point(new)
        return np.array([y_le - (y_le0 - droop), new[-1, 1] - pts[-1, 1]])

    # start: a rigid rotation about the spar, to first order
    coef = _newton_2(residual, np.array([droop / depth, 0.0]), tol, max_iter)
    return build(coef)


def _newton_2(residual, coef: FloatArray, tol: float, max_iter: int) -> FloatArray:
    """Newton's method on two equations with a central-difference Jacobian (step 1e-7)."""
    res = residual(coef)
    h = 1e-7
    for _ in range(max_iter):
        if np.max(np.abs(res)) <= tol:
            return coef
        jac = np.empty((2, 2))
        for j in range(2):
            step = np.zeros(2)
            step[j] = h
            jac[:, j] = (residual(coef + step) - residual(coef - step)) / (2.0 * h)
        coef = coef - np.linalg.solve(jac, res)
        res = residual(coef)
    if np.max(np.abs(res)) <= tol:
        return coef
    raise RuntimeError(f"droop construction did not converge (residual {res} mm)")


def _turn_angles(a: FloatArray, b: FloatArray) -> FloatArray:
    """Signed angle [rad] from each segment of polyline `a` to the same segment of `b`."""
    da, db = np.diff(a, axis=0), np.diff(b, axis=0)
    cross = da[:, 0] * db[:, 1] - da[:, 1] * db[:, 0]
    dot = da[:, 0] * db[:, 0] + da[:, 1] * db[:, 1]
    return np.arctan2(cross, dot)


def target_nodes(
    airfoil: CSTAirfoil | None = None,
    droop: float = DEFAULT_DROOP_MM,
    n_nodes: int = 31,
    x_spar: float = X_SPAR_MM,
    *,
    n_dense: int = 2001,
) -> dict[str, FloatArray | float]:
    """Skin nodes of the undeformed (high-speed) and the target (low-speed) shape.

    Parameters
    ----------
    airfoil : CSTAirfoil, optional
        Undeformed airfoil; default :func:`high_speed_airfoil`.
    droop : float, optional
        Nose droop of the target [mm], see :func:`drooped_curve`. Default
        :data:`DEFAULT_DROOP_MM`.
    n_nodes : int, optional
        Number of skin nodes (31 in the paper: 30 beam elements).
    x_spar : float, optional
        Spar position, x of F and G [mm]. Default 137.5 mm.
    n_dense : int, optional
        Points of the dense polyline the nodes are taken from.

    Returns
    -------
    dict
        ``"undeformed"`` : ndarray, shape (n_nodes, 2)
            Nodes at equal arc length on the undeformed skin, F first, G last [mm].
        ``"target"`` : ndarray, shape (n_nodes, 2)
            Nodes at the same arc-length positions on the drooped skin [mm]; node k of the
            target is the image of node k of the undeformed skin.
        ``"curve"``, ``"target_curve"`` : ndarray, shape (n_dense, 2)
            The dense polylines both node sets were taken from [mm] (e.g. for plots).
        ``"arc_length"`` : float
            Skin length F -> G, the same for both shapes [mm].
        ``"g_shift"`` : float
            x displacement of G from the undeformed to the target shape [mm].
        ``"max_rotation"`` : float
            Largest change of the tangent angle along the skin between the two shapes at equal
            arc length, from the dense polylines [rad].
        ``"max_chord_rotation"`` : float
            Largest rotation of a node-to-node chord (an element's rigid rotation in the beam
            model) between the two node sets [rad].
    """
    af = high_speed_airfoil() if airfoil is None else airfoil
    curve = leading_edge_curve(af, x_spar=x_spar, n=n_dense)
    target_curve = drooped_curve(curve, droop, x_spar=x_spar)
    undeformed = resample_equal_arc(curve, n_nodes)
    target = resample_equal_arc(target_curve, n_nodes)
    return {
        "undeformed": undeformed,
        "target": target,
        "curve": curve,
        "target_curve": target_curve,
        "arc_length": arc_length(curve),
        "g_shift": float(target_curve[-1, 0] - curve[-1, 0]),
        "max_rotation": float(np.max(np.abs(_turn_angles(curve, target_curve)))),
        "max_chord_rotation": float(np.max(np.abs(_turn_angles(undeformed, target)))),
    }
