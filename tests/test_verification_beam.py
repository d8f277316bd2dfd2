"""Closed-form mechanics of a single FFRF beam: invariants, static cantilever, eigenfrequencies.

References
----------
* Invariants of a polyline of straight segments (exact): for a segment P -> Q of length l,
  ``∫ ds = l``, ``∫ u ds = l (P + Q)/2``, ``∫ |u|² ds = l (|P|² + P.Q + |Q|²)/3``.
* Euler–Bernoulli cantilever (Gere & Timoshenko, *Mechanics of Materials*, App. G): tip force
  ``F``: ``v(x) = F x² (3L - x)/(6EI)``, ``v'(x) = F x (2L - x)/(2EI)``; tip moment ``M``:
  ``v = M x²/(2EI)``, ``v' = M x/EI``; root stress ``sigma = N/A -+ M_b c/I``. These fields are
  cubic (or lower), so the cubic Hermite element reproduces them exactly (Tong's theorem on
  nodal exactness, and here even inside the elements).
* Clamped-free bending frequencies ``omega_n = (beta_n L)² sqrt(EI/(rho A L⁴))`` with
  ``cos(beta L) cosh(beta L) = -1`` (Blevins, *Formulas for Natural Frequency and Mode Shape*,
  ch. 8), solved here to full precision; axial ``omega_n = (2n - 1) pi/(2L) sqrt(E/rho)``.

Units: mm, t, s, N, MPa (aluminium strip 2 mm x 10 mm, 100 mm long).
"""

import numpy as np
import pytest
from models import E_AL, RHO_AL, straight_nodes
from scipy.linalg import eigh
from scipy.optimize import brentq

import morphlab as ml

T_SEC, B_SEC, LENGTH = 2.0, 10.0, 100.0
AREA = T_SEC * B_SEC
INERTIA = B_SEC * T_SEC**3 / 12.0
RHOA = RHO_AL * AREA


def one_beam(nodes, reference_node=0):
    m = ml.Model(name="one-beam")
    beam = m.add_beam(nodes, E=E_AL, rho=RHO_AL, thickness=T_SEC, width=B_SEC,
                      reference_node=reference_node, name="beam")
    return m, beam


def flex_matrices(system):
    """Assembled M_ff, S~, K_ff (n_flex, n_flex) of the (only) beam from the element arrays."""
    El = system.arrays.elements
    nf = system.count("flex")
    out = [np.zeros((nf, nf)) for _ in range(3)]
    for e in range(El.fdof.shape[0]):
        fd = El.fdof[e]
        k = fd >= 0
        for A, Ae in zip(out, (El.M[e], El.St[e], El.K[e])):
            A[np.ix_(fd[k], fd[k])] += Ae[np.ix_(k, k)]
    return out


def rotate(vec, angle):
    c, s = np.cos(angle), np.sin(angle)
    return np.array([c * vec[0] - s * vec[1], s * vec[0] + c * vec[1]])


def polyline_invariants(X):
    """(m, I_u (2,), I_00) of a polyline with uniform rhoA about the origin of X (exact)."""
    P, Q = X[:-1], X[1:]
    ell = np.hypot(*(Q - P).T)
    m = RHOA * ell.sum()
    Iu = RHOA * (ell[:, None] * (P + Q) / 2).sum(axis=0)
    I00 = RHOA * (ell * (np.sum(P * P, 1) + np.sum(P * Q, 1) + np.sum(Q * Q, 1)) / 3).sum()
    return m, Iu, I00


def half_circle(n_elem, radius=50.0):
    t = np.linspace(0.0, np.pi, n_elem + 1)
    return radius * np.column_stack([np.cos(t), np.sin(t)])


def body_frame_angle(X, r):
    """Direction of the element that starts at node r (ends there for the last node)."""
    a, b = (r, r + 1) if r < len(X) - 1 else (r - 1, r)
    d = X[b] - X[a]
    return np.arctan2(d[1], d[0])


def check_dilation_identities(system):
    """The flex arrays must agree with the scalars for a uniform dilation about the reference
    node, q_d = (u, v, phi)_k = (x_k, y_k, 0) (body frame). It is representable (it leaves the
    reference node and every element direction unchanged) and the element fields reproduce
    it exactly (S q_d = u0: linear along each straight element), so
    I_S^T q_d = I_u, I_0S.q_d = I_00, I_0ĨS.q_d = 0, M_ff q_d = I_0S, S~ q_d = I_0ĨS, and
    the strain energy of a unit strain, q_d^T K q_d = EA * (total length)."""
    info = system.body("beam")
    Fx = system.arrays.flex
    m, Iux, Iuy, I00 = system.arrays.bodies.scal[0]
    where = {int(g): k for k, g in enumerate(Fx.dof)}
    qd = np.zeros(Fx.dof.size)
    for k, X in enumerate(info.X):
        for j, val in enumerate((X[0], X[1], 0.0)):
            if info.node_dofs[k, j] >= 0:
                qd[where[int(info.node_dofs[k, j])]] = val
    Mff, St, K = flex_matrices(system)
    size = np.max(np.abs(info.X))
    # every identity is an exact polynomial integral: round-off relative to its scale
    tol = 1e-13
    np.testing.assert_allclose(Fx.IS.T @ qd, [Iux, Iuy], rtol=0, atol=tol * m * size)
    np.testing.assert_allclose(Fx.I0S @ qd, I00, rtol=tol)
    assert abs(Fx.I0IS @ qd) < tol * I00
    np.testing.assert_allclose(Mff @ qd, Fx.I0S, rtol=0, atol=tol * m * size**2)
    np.testing.assert_allclose(St @ qd, Fx.I0IS, rtol=0, atol=tol * m * size**2)
    np.testing.assert_allclose(qd @ Mff @ qd, I00, rtol=tol)
    length = np.sum(np.hypot(*np.diff(info.X, axis=0).T))
    np.testing.assert_allclose(qd @ K @ qd, E_AL * AREA * length, rtol=tol)


# ---------------------------------------------------------------- invariants
@pytest.mark.parametrize("ref", [0, 4, 8])
def test_straight_beam_invariants(ref):
    n_elem = 8
    model, _ = one_beam(straight_nodes(n_elem, LENGTH, angle=0.3, origin=(5.0, -2.0)), ref)
    system = ml.compile_model(model)
    xr = LENGTH * ref / n_elem  # body frame: origin at node `ref`, x along the beam
    m = RHOA * LENGTH
    expected = [m, m * (LENGTH / 2 - xr), 0.0, RHOA * ((LENGTH - xr) ** 3 + xr**3) / 3]
    # exact integrals of polynomials; round-off only (the beam is inclined in the global frame,
    # so the body-frame node coordinates carry ~1e-14 relative error)
    np.testing.assert_allclose(system.arrays.bodies.scal[0], expected, rtol=1e-13,
                               atol=1e-13 * m * LENGTH)
    if ref == 0:  # the textbook values about the end
        np.testing.assert_allclose(system.arrays.bodies.scal[0, [0, 1, 3]],
                                   [RHOA * LENGTH, RHOA * LENGTH**2 / 2, RHOA * LENGTH**3 / 3],
                                   rtol=1e-13)
    check_dilation_identities(system)


@pytest.mark.parametrize("ref", [0, -1])
def test_half_circle_polyline_invariants(ref):
    X = half_circle(24)
    r = ref % len(X)
    system = ml.compile_model(one_beam(X, ref)[0])
    m, Iu, I00 = polyline_invariants(X - X[r])
    Iu_body = rotate(Iu, -body_frame_angle(X, r))
    got = system.arrays.bodies.scal[0]
    # the kernel integrates each straight element exactly: round-off of 24 terms
    np.testing.assert_allclose(got[0], m, rtol=1e-13)
    np.testing.assert_allclose(got[1:3], Iu_body, rtol=0, atol=1e-13 * m * 100.0)
    np.testing.assert_allclose(got[3], I00, rtol=1e-13)
    check_dilation_identities(system)


# ---------------------------------------------------------------- static cantilever
def cantilever_closed_form(x, F_t, F_a, M_t):
    """Transverse v, axial u, rotation v' along a cantilever of length LENGTH (local frame)."""
    EI = E_AL * INERTIA
    v = F_t * x**2 * (3 * LENGTH - x) / (6 * EI) + M_t * x**2 / (2 * EI)
    dv = F_t * x * (2 * LENGTH - x) / (2 * EI) + M_t * x / EI
    u = F_a * x / (E_AL * AREA)
    return u, v, dv


def solve_cantilever(n_elem, angle, force, moment):
    nodes = straight_nodes(n_elem, LENGTH, angle=angle, origin=(3.0, 1.0))
    model, beam = one_beam(nodes)
    model.add_fix(beam, at=tuple(nodes[0]))
    if force is not None:
        model.add_force(beam, at=tuple(nodes[-1]), force=force)
    if moment is not None:
        model.add_torque(beam, moment, at=tuple(nodes[-1]))
    res = ml.static(model)
    assert res.status == "ok"
    return nodes, res


LOADS = {"tip force": ((0.0, -0.5), None), "tip moment": (None, 30.0),
         "force and moment": ((0.2, 0.4), -25.0)}


@pytest.mark.parametrize("n_elem", [1, 5])
@pytest.mark.parametrize("load", list(LOADS))
def test_cantilever_deflection_and_rotation(load, n_elem):
    force, moment = LOADS[load]
    nodes, res = solve_cantilever(n_elem, 0.0, force, moment)
    F = np.zeros(2) if force is None else np.array(force)
    x = nodes[:, 0] - nodes[0, 0]
    u, v, dv = cantilever_closed_form(x, F[1], F[0], 0.0 if moment is None else moment)
    disp = res.node_positions("beam")[-1] - nodes
    rot = res.node_rotations("beam")[-1]
    scale = np.max(np.abs(v)) + np.max(np.abs(u))
    # the cubic element is nodally exact for these (at most cubic) fields; what remains is the
    # round-off of the linear solve, cond(K) eps ~ 1e-11, and Newton stops after a correction
    # of round-off size: 1e-9 of the tip deflection leaves margin without hiding any O(h) error
    np.testing.assert_allclose(disp[:, 0], u, rtol=0, atol=1e-9 * scale)
    np.testing.assert_allclose(disp[:, 1], v, rtol=0, atol=1e-9 * scale)
    np.testing.assert_allclose(rot, dv, rtol=0, atol=1e-9 * np.max(np.abs(dv)))


@pytest.mark.parametrize("load", list(LOADS))
def test_inclined_cantilever_is_the_rotated_answer(load):
    force, moment = LOADS[load]
    angle = 0.7
    # the same loads in the beam's frame on a horizontal cantilever ...
    f_loc = None if force is None else tuple(rotate(np.array(force), -angle))
    nodes_h, res_h = solve_cantilever(4, 0.0, f_loc, moment)
    nodes_i, res_i = solve_cantilever(4, angle, force, moment)
    disp_h = res_h.node_positions("beam")[-1] - nodes_h
    disp_i = res_i.node_positions("beam")[-1] - nodes_i
    # ... give the displacements rotated by the inclination (frame invariance of the model),
    # and the same nodal rotations and stresses; round-off of the two solves as above
    scale = np.max(np.abs(disp_h))
    np.testing.assert_allclose(disp_i, rotate(disp_h.T, angle).T, rtol=0, atol=1e-9 * scale)
    np.testing.assert_allclose(res_i.node_rotations("beam")[-1], res_h.node_rotations("beam")[-1],
                               rtol=0, atol=1e-9 * np.max(np.abs(res_h.node_rotations("beam"))))
    s_h, s_i = res_h.stress("beam")[-1], res_i.stress("beam")[-1]
    np.testing.assert_allclose(s_i, s_h, rtol=0, atol=1e-9 * np.max(np.abs(s_h)))
    # and the closed form in the beam's frame
    F_loc = np.zeros(2) if f_loc is None else np.array(f_loc)
    u, v, _ = cantilever_closed_form(LENGTH, F_loc[1], F_loc[0], moment or 0.0)
    np.testing.assert_allclose(disp_i[-1], rotate(np.array([u, v]), angle), rtol=0,
                               atol=1e-9 * scale)


@pytest.mark.parametrize("load", list(LOADS))
def test_cantilever_stress_is_N_over_A_plus_Mc_over_I(load):
    force, moment = LOADS[load]
    n_elem = 4
    nodes, res = solve_cantilever(n_elem, 0.0, force, moment)
    F = np.zeros(2) if force is None else np.array(force)
    M_t = 0.0 if moment is None else moment
    sigma = res.stress("beam")[-1]  # (n_elem, 2 ends, 2 fibres)
    x_end = np.stack([nodes[:-1, 0], nodes[1:, 0]], axis=1) - nodes[0, 0]
    # bending moment EI v'' = F_y (L - x) + M_t; fibre 0 at y' = +c (left of the beam axis)
    M_b = F[1] * (LENGTH - x_end) + M_t
    c = T_SEC / 2
    expected = np.stack([F[0] / AREA - M_b * c / INERTIA, F[0] / AREA + M_b * c / INERTIA],
                        axis=-1)
    # the curvature of the exact (<= cubic) field is reproduced: round-off as above
    np.testing.assert_allclose(sigma, expected, rtol=0, atol=1e-9 * np.max(np.abs(expected)))
    # root stress against M c / I directly (tip force: M = F L)
    root = abs(F[1] * LENGTH + M_t) * c / INERTIA
    assert abs(abs(sigma[0, 0, 0] - F[0] / AREA) - root) <= 1e-9 * root


# ---------------------------------------------------------------- eigenfrequencies
BETA_L = np.array([brentq(lambda b: np.cos(b) * np.cosh(b) + 1.0, (n - 0.5) * np.pi - 0.5,
                          (n - 0.5) * np.pi + 0.5, xtol=1e-14, rtol=4 * np.finfo(float).eps)
                   for n in (1, 2, 3)])


def bending_reference():
    return BETA_L**2 * np.sqrt(E_AL * INERTIA / (RHOA * LENGTH**4))


def axial_reference():
    return (2 * np.arange(1, 4) - 1) * np.pi / (2 * LENGTH) * np.sqrt(E_AL / RHO_AL)


def clamped_free_frequencies(n_elem):
    """Bending and axial angular frequencies [rad/s] of the body's flex coordinates.

    With the reference node at the root, the flex coordinates are the clamped-free FE model.
    A mode is axial when its (mass-normalized) eigenvector lives on the u coordinates.
    """
    system = ml.compile_model(one_beam(straight_nodes(n_elem, LENGTH))[0])
    Mff, _, K = flex_matrices(system)
    w2, V = eigh(K, Mff)
    names = [system.dof_names[g] for g in system.arrays.flex.dof]
    is_u = np.array([n.endswith(".u") for n in names])
    axial_share = np.sum(V[is_u] ** 2, axis=0) / np.sum(V**2, axis=0)
    # the straight beam decouples exactly: each mode is purely axial or purely bending
    assert np.all((axial_share < 1e-12) | (axial_share > 1 - 1e-12))
    return np.sqrt(w2[axial_share < 0.5]), np.sqrt(w2[axial_share > 0.5])


def test_beta_roots():
    # the roots used as reference: textbook values 1.8751, 4.6941, 7.8548 (5 digits)
    np.testing.assert_allclose(BETA_L, [1.8751, 4.6941, 7.8548], atol=5e-5)
    assert np.all(np.abs(np.cos(BETA_L) * np.cosh(BETA_L) + 1.0) < 1e-11)


def test_clamped_free_bending_and_axial_frequencies():
    n_elem = 16
    bend, axial = clamped_free_frequencies(n_elem)
    h = LENGTH / n_elem
    err_b = bend[:3] / bending_reference() - 1.0
    err_a = axial[:3] / axial_reference() - 1.0
    # Rayleigh–Ritz with consistent mass: upper bounds (errors > 0). Size: a Bloch-wave
    # analysis of the element on an infinite mesh gives lambda_h / lambda = 1 + (k h)^4/720
    # - (k h)^6/25200 + ... for the cubic Hermite bending element and 1 + (k h)^2/12 + ... for
    # the linear axial element (derived with sympy), so omega errors (k h)^4/1440 and
    # (k h)^2/24. The next term and the boundary layers of the cantilever change that by a
    # few per cent at k h <= 0.5 (mode 3 here); we allow 0.9 to 1.05 times the estimate.
    est_b = (BETA_L * h / LENGTH) ** 4 / 1440.0
    est_a = ((2 * np.arange(1, 4) - 1) * np.pi / 2 * h / LENGTH) ** 2 / 24.0
    assert np.all(err_b > 0) and np.all(err_a > 0)
    np.testing.assert_array_less(0.9 * est_b, err_b)
    np.testing.assert_array_less(err_b, 1.05 * est_b)
    np.testing.assert_array_less(0.9 * est_a, err_a)
    np.testing.assert_array_less(err_a, 1.05 * est_a)
    # in plain numbers: the first three bending frequencies within 5e-5 of the closed form
    assert np.max(err_b) < 5e-5
