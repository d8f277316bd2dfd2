"""Tests of the CST airfoil geometry and the morphing leading-edge target shapes."""

import numpy as np
import pytest

from morphlab.morphing.airfoil import (
    CHORD_MM,
    DEFAULT_DROOP_MM,
    THICKNESS_MM,
    X_SPAR_MM,
    CSTAirfoil,
    arc_length,
    cst_surface,
    drooped_curve,
    high_speed_airfoil,
    leading_edge_curve,
    leading_edge_point,
    resample_equal_arc,
    target_nodes,
)


@pytest.fixture(scope="module")
def airfoil() -> CSTAirfoil:
    return high_speed_airfoil()


@pytest.fixture(scope="module")
def curve(airfoil: CSTAirfoil) -> np.ndarray:
    return leading_edge_curve(airfoil)


@pytest.fixture(scope="module")
def drooped(curve: np.ndarray) -> np.ndarray:
    return drooped_curve(curve, DEFAULT_DROOP_MM)


def _circle_arc(radius: float, phi0: float, phi1: float, m: int) -> np.ndarray:
    phi = np.linspace(phi0, phi1, m)
    return radius * np.column_stack([np.cos(phi), np.sin(phi)])


def _angle(u: np.ndarray, v: np.ndarray) -> float:
    """Signed angle from vector u to vector v [rad]."""
    return float(np.arctan2(u[0] * v[1] - u[1] * v[0], u @ v))


@pytest.mark.parametrize("order", [1, 3, 5, 8])
def test_cst_unit_weights_give_class_function(order: int) -> None:
    psi = np.linspace(0.0, 1.0, 101)
    y = cst_surface(psi, np.ones(order + 1), n1=0.5, n2=1.0)
    # Bernstein polynomials sum to one; only round-off of ~order terms of size <= 1 remains.
    np.testing.assert_allclose(y, np.sqrt(psi) * (1.0 - psi), rtol=0.0, atol=1e-14)


def test_cst_trailing_edge_offset_and_range() -> None:
    psi = np.linspace(0.0, 1.0, 11)
    base = cst_surface(psi, [0.2, 0.1, 0.3])
    shifted = cst_surface(psi, [0.2, 0.1, 0.3], te=0.01)
    # The offset is the linear term psi * te, added exactly up to round-off.
    np.testing.assert_allclose(shifted - base, 0.01 * psi, rtol=0.0, atol=1e-15)
    with pytest.raises(ValueError):
        cst_surface([1.5], [0.2, 0.1])


def test_high_speed_airfoil_chord_and_thickness(airfoil: CSTAirfoil) -> None:
    assert airfoil.chord == CHORD_MM
    # Golden-section refinement to 1e-13 chords at a stationary point: exact to round-off.
    assert abs(airfoil.max_thickness() - THICKNESS_MM) < 1e-9
    # Brute-force check: a fine uniform sample never exceeds the refined maximum (beyond
    # round-off) and comes within the sampling error t'' dx^2 / 8 ~ 1e-7 mm of it.
    t = airfoil.thickness(np.linspace(0.0, CHORD_MM, 200_001))
    assert THICKNESS_MM - 1e-5 < t.max() <= THICKNESS_MM + 1e-9
    # Sharp trailing edge and the leading edge at the origin (class function vanishes there).
    y_u, y_l = airfoil.surfaces(np.array([0.0, CHORD_MM]))
    np.testing.assert_allclose([*y_u, *y_l], 0.0, atol=1e-12)  # round-off of the CST sum
    # Cambered: the camber line is above the chord at mid-chord.
    y_u, y_l = airfoil.surfaces(0.5 * CHORD_MM)
    assert y_u + y_l > 0.0


def test_scaling_keeps_proportions() -> None:
    base = CSTAirfoil(upper=(0.2, 0.25, 0.2), lower=(-0.15, -0.1, -0.05), chord=100.0)
    scaled = base.scaled_to_thickness(9.0)
    # Same refinement as above: the scaled maximum is exact to round-off.
    assert abs(scaled.max_thickness() - 9.0) < 1e-10
    k = 9.0 / base.max_thickness()
    # The scale factor is one number for all weights (camber/thickness ratio kept).
    np.testing.assert_allclose(scaled.upper, k * np.array(base.upper), rtol=1e-14)
    np.testing.assert_allclose(scaled.lower, k * np.array(base.lower), rtol=1e-14)


def test_contour_order_and_closure(airfoil: CSTAirfoil) -> None:
    pts = airfoil.contour(201)
    assert pts.shape == (201, 2)
    # Starts and ends at the sharp trailing edge, passes through the nose (odd n): round-off.
    np.testing.assert_allclose(pts[0], [CHORD_MM, 0.0], atol=1e-12)
    np.testing.assert_allclose(pts[-1], [CHORD_MM, 0.0], atol=1e-12)
    np.testing.assert_allclose(pts[100], [0.0, 0.0], atol=1e-12)
    assert np.all(pts[1:100, 1] > 0.0) and np.all(pts[101:-1, 1] < 0.0)


def test_leading_edge_curve_ends(airfoil: CSTAirfoil, curve: np.ndarray) -> None:
    y_u, y_l = airfoil.surfaces(X_SPAR_MM)
    assert curve.shape == (2001, 2)
    # F and G are set from the surface functions directly: identical values.
    np.testing.assert_array_equal(curve[0], [X_SPAR_MM, y_u])
    np.testing.assert_array_equal(curve[-1], [X_SPAR_MM, y_l])
    # The nose (0, 0) is the middle point for odd n; the class function vanishes there.
    np.testing.assert_allclose(curve[1000], [0.0, 0.0], atol=1e-12)
    x_le, y_le, _ = leading_edge_point(curve)
    # Parabolic refinement on a smooth, vertical-tangent nose: error O(h^3), h ~ 1e-3 mm there.
    assert abs(x_le) < 1e-9 and abs(y_le) < 1e-6


def test_arc_length_of_circle_polyline() -> None:
    radius, m = 50.0, 20_001
    pts = _circle_arc(radius, 0.0, 0.5 * np.pi, m)
    delta = 0.5 * np.pi / (m - 1)
    exact_polyline = (m - 1) * 2.0 * radius * np.sin(0.5 * delta)
    # Chords of equal arcs: the polyline length is known in closed form (round-off only).
    assert abs(arc_length(pts) - exact_polyline) < 1e-10
    # And it approaches the arc R * phi with the chord error R phi delta^2 / 24 ~ 2e-8 mm.
    assert abs(arc_length(pts) - radius * 0.5 * np.pi) < 1e-7


def test_resample_equal_arc_on_circle() -> None:
    radius, m, n_nodes = 50.0, 20_001, 13
    phi0, phi1 = 0.3, 2.4
    dense = _circle_arc(radius, phi0, phi1, m)
    nodes = resample_equal_arc(dense, n_nodes)
    assert nodes.shape == (n_nodes, 2)
    np.testing.assert_array_equal(nodes[0], dense[0])
    np.testing.assert_array_equal(nodes[-1], dense[-1])
    chords = np.hypot(*np.diff(nodes, axis=0).T)
    expected = 2.0 * radius * np.sin(0.5 * (phi1 - phi0) / (n_nodes - 1))
    # Nodes lie on chords of the dense polyline, at most R delta^2 / 8 ~ 7e-8 mm inside the
    # circle (delta: dense angular step), so the node chords match 2 R sin(dphi/2) to ~1e-7.
    np.testing.assert_allclose(chords, expected, rtol=0.0, atol=1e-6)
    # Nodes are on the circle to the same sagitta bound.
    np.testing.assert_allclose(np.hypot(*nodes.T), radius, rtol=0.0, atol=1e-6)


def test_resample_uneven_polyline() -> None:
    # Straight line with uneven vertices: equal-arc nodes are exactly evenly spaced.
    x = np.array([0.0, 0.1, 0.5, 3.0, 7.0, 10.0])
    nodes = resample_equal_arc(np.column_stack([x, 2.0 * x]), 6)
    # Linear interpolation is exact on a straight line; round-off only.
    np.testing.assert_allclose(nodes[:, 0], np.linspace(0.0, 10.0, 6), atol=1e-12)


def test_drooped_curve_keeps_length_and_ends(curve: np.ndarray, drooped: np.ndarray) -> None:
    assert drooped.shape == curve.shape
    # Every segment is only rotated: the arc length is kept to round-off.
    assert abs(arc_length(drooped) / arc_length(curve) - 1.0) < 1e-12
    # F is the start of the integration and is copied: identical.
    np.testing.assert_array_equal(drooped[0], curve[0])
    # Tangents at F and G: the blend b(xi) ~ 3 xi^2 is ~1e-12 on the end segments.
    first0, first1 = curve[1] - curve[0], drooped[1] - drooped[0]
    last0, last1 = curve[-1] - curve[-2], drooped[-1] - drooped[-2]
    assert abs(_angle(first0, first1)) < 1e-9
    assert abs(_angle(last0, last1)) < 1e-9
    # G keeps y (Newton tolerance 1e-11 mm) and moves in x only.
    assert abs(drooped[-1, 1] - curve[-1, 1]) < 1e-9
    # Near F nothing changes: with zero rotation and zero rotation rate at F, displacements
    # grow like s^3; within 1 mm of arc they stay below ~1e-5 mm.
    s = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(curve, axis=0).T))])
    near = s < 1.0
    assert np.max(np.hypot(*(drooped[near] - curve[near]).T)) < 1e-4


def test_drooped_curve_droop_at_leading_edge(curve: np.ndarray, drooped: np.ndarray) -> None:
    _, y_le0, _ = leading_edge_point(curve)
    _, y_le1, _ = leading_edge_point(drooped)
    # The droop is one of the two Newton conditions (tolerance 1e-11 mm).
    assert abs((y_le0 - y_le1) - DEFAULT_DROOP_MM) < 1e-9


def test_drooped_curve_nose_up(curve: np.ndarray) -> None:
    up = drooped_curve(curve, -3.0)
    # Same Newton tolerances as above, for a negative droop (nose up).
    assert abs(leading_edge_point(up)[1] - leading_edge_point(curve)[1] - 3.0) < 1e-9
    assert abs(up[-1, 1] - curve[-1, 1]) < 1e-9


def test_target_nodes_default() -> None:
    res = target_nodes()
    und, tgt = res["undeformed"], res["target"]
    assert und.shape == tgt.shape == (31, 2)
    # F identical in both node sets (copied); G only slides in x (Newton tolerance).
    np.testing.assert_array_equal(und[0], tgt[0])
    assert abs(und[-1, 1] - tgt[-1, 1]) < 1e-9
    assert abs(res["g_shift"] - (tgt[-1, 0] - und[-1, 0])) < 1e-12  # same numbers, round-off
    # Both shapes have the same skin length (segments are only rotated; round-off).
    length = res["arc_length"]
    assert abs(arc_length(res["curve"]) - length) < 1e-12 * length
    assert abs(arc_length(res["target_curve"]) - length) < 1e-12 * length
    # A visible droop with a modest rotation (bound for linear FFRF, docs/theory.md §2.10, §9.4).
    assert 0.0 < res["max_rotation"] < 0.15
    assert 0.0 < res["max_chord_rotation"] <= res["max_rotation"] + 1e-12


def test_target_nodes_zero_droop_reproduces_undeformed() -> None:
    res = target_nodes(droop=0.0)
    # Zero rotation everywhere: the rebuilt curve differs only by cumulative-sum round-off.
    np.testing.assert_allclose(res["target"], res["undeformed"], rtol=0.0, atol=1e-10)
    assert abs(res["g_shift"]) < 1e-10
    # Rebuilt segments as short as ~3e-4 mm (cosine clustering at F and G) carry point
    # round-off of ~1e-14 mm, i.e. angle noise of ~1e-10 rad at most.
    assert res["max_rotation"] < 1e-9
