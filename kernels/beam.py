"""Planar Euler–Bernoulli beam element: shape functions, quadrature, invariants, stiffness, stress.

Element conventions
-------------------
An element joins body-frame points ``X1`` and ``X2`` (undeformed, in the body frame of its
FFRF body). Its six degrees of freedom are the nodal displacements and rotations expressed in the
*body* frame, ``d = (ux1, uy1, phi1, ux2, uy2, phi2)``. In the element frame (axis x' along
``X2 - X1``, y' = x' turned by +90 deg) the axial displacement is linear and the transverse
displacement a cubic Hermite polynomial in ``xi = x'/L``::

    u'(xi) = (1 - xi) u1' + xi u2'
    v'(xi) = H1 v1' + L H2 phi1 + H3 v2' + L H4 phi2
    H1 = 1 - 3 xi^2 + 2 xi^3,  H2 = xi - 2 xi^2 + xi^3,  H3 = 3 xi^2 - 2 xi^3,  H4 = xi^3 - xi^2

and the body-frame displacement of the centre line is ``w(xi) = Rot(alpha) (u', v') = S(xi) d``,
the 2 x 6 shape matrix of ``docs/theory.md`` §3.1. Mass is a line density ``rhoA`` (mass per
length): the rotary inertia of the cross-section is neglected, as in the Euler–Bernoulli theory.

Every kernel here is written for float64 and complex128 alike (complex-step safe): lengths use
``sqrt(dx*dx + dy*dy)``, there are no ``abs``, comparisons or ``arctan2`` on real-valued data.
"""

import numpy as np
from numba import njit

# 4-point Gauss–Legendre rule on [0, 1]: exact for polynomials up to degree 7, enough for
# S^T S (degree 6) and u0^T S (degree 4), so every invariant below is integrated exactly.
_G4 = np.array([0.33998104358485626, 0.8611363115940526])
_W4 = np.array([0.6521451548625461, 0.34785484513745385])
GAUSS_XI = np.array(
    [0.5 - 0.5 * _G4[1], 0.5 - 0.5 * _G4[0], 0.5 + 0.5 * _G4[0], 0.5 + 0.5 * _G4[1]]
)
GAUSS_W = np.array([0.5 * _W4[1], 0.5 * _W4[0], 0.5 * _W4[0], 0.5 * _W4[1]])


@njit(cache=True)
def element_geometry(X1, X2):
    """Length and direction cosines of the element X1 -> X2 (body frame).

    Returns ``(L, c, s)``; complex-step safe.
    """
    dx = X2[0] - X1[0]
    dy = X2[1] - X1[1]
    L = np.sqrt(dx * dx + dy * dy)
    return L, dx / L, dy / L


@njit(cache=True)
def shape_matrix(xi, L, c, s, S):
    """Body-frame shape matrix of the element at ``xi`` in [0, 1].

    Parameters
    ----------
    xi : float
        Position along the element, 0 at X1 and 1 at X2.
    L, c, s : scalar
        Element length and direction cosines (from :func:`element_geometry`).
    S : (2, 6) array, out
        ``w(xi) = S @ d`` with ``d`` the body-frame element DOFs.
    """
    x2 = xi * xi
    x3 = x2 * xi
    n_ax1 = 1.0 - xi
    n_ax2 = xi
    h1 = 1.0 - 3.0 * x2 + 2.0 * x3
    h2 = (xi - 2.0 * x2 + x3) * L
    h3 = 3.0 * x2 - 2.0 * x3
    h4 = (x3 - x2) * L
    # local (u', v') in terms of body-frame nodal displacements: u' = c ux + s uy, v' = -s ux + c uy
    # w = Rot(alpha) (u', v') -> rows: wx = c u' - s v', wy = s u' + c v'
    for node in range(2):
        na = n_ax1 if node == 0 else n_ax2
        hv = h1 if node == 0 else h3
        hr = h2 if node == 0 else h4
        j = 3 * node
        # d u'/d(ux, uy) = (c, s) * na ; d v'/d(ux, uy) = (-s, c) * hv ; d v'/d phi = hr
        S[0, j] = c * na * c + s * hv * s
        S[0, j + 1] = c * na * s - s * hv * c
        S[0, j + 2] = -s * hr
        S[1, j] = s * na * c - c * hv * s
        S[1, j + 1] = s * na * s + c * hv * c
        S[1, j + 2] = c * hr


@njit(cache=True)
def element_invariants(X1, X2, rhoA, scal, IS, I0S, I0IS, Mff, St):
    """Add one element's contributions to the FFRF invariants of its body (``docs/theory.md`` §2.4).

    Parameters
    ----------
    X1, X2 : (2,) arrays
        Undeformed end points in the body frame [length].
    rhoA : scalar
        Mass per unit length [mass/length].
    scal : (4,) array, in/out
        ``[m, I_u_x, I_u_y, I_00]``: mass, first moment ``∫ρ u0 dV`` and ``∫ρ u0^T u0 dV``,
        accumulated (added to).
    IS : (2, 6) array, out
        ``∫ρ S dV`` of this element (overwritten).
    I0S : (6,) array, out
        ``∫ρ u0^T S dV`` (overwritten).
    I0IS : (6,) array, out
        ``∫ρ u0^T Ĩ^T S dV`` with ``Ĩ = [[0, -1], [1, 0]]`` (overwritten).
    Mff : (6, 6) array, out
        ``∫ρ S^T S dV`` (overwritten).
    St : (6, 6) array, out
        ``S̃ = ∫ρ S^T Ĩ S dV`` (skew-symmetric; overwritten).

    Notes
    -----
    Integrated with the 4-point Gauss rule, exact for these polynomial integrands.
    """
    L, c, s = element_geometry(X1, X2)
    S = np.zeros((2, 6), dtype=IS.dtype)
    IS[:, :] = 0.0
    I0S[:] = 0.0
    I0IS[:] = 0.0
    Mff[:, :] = 0.0
    St[:, :] = 0.0
    for g in range(4):
        xi = GAUSS_XI[g]
        wq = GAUSS_W[g] * rhoA * L
        shape_matrix(xi, L, c, s, S)
        u0x = X1[0] + xi * (X2[0] - X1[0])
        u0y = X1[1] + xi * (X2[1] - X1[1])
        scal[0] += wq
        scal[1] += wq * u0x
        scal[2] += wq * u0y
        scal[3] += wq * (u0x * u0x + u0y * u0y)
        for a in range(6):
            IS[0, a] += wq * S[0, a]
            IS[1, a] += wq * S[1, a]
            I0S[a] += wq * (u0x * S[0, a] + u0y * S[1, a])
            # u0^T Ĩ^T S = (Ĩ u0)^T S, Ĩ u0 = (-u0y, u0x)
            I0IS[a] += wq * (-u0y * S[0, a] + u0x * S[1, a])
            for b in range(6):
                Mff[a, b] += wq * (S[0, a] * S[0, b] + S[1, a] * S[1, b])
                # S^T Ĩ S: (Ĩ S)_b = (-S[1,b], S[0,b])
                St[a, b] += wq * (S[0, a] * (-S[1, b]) + S[1, a] * S[0, b])


@njit(cache=True)
def element_stiffness(X1, X2, EA, EI, K):
    """Linear Euler–Bernoulli stiffness of the element in body-frame DOFs.

    Parameters
    ----------
    X1, X2 : (2,) arrays
        Undeformed end points [length].
    EA, EI : scalar
        Axial stiffness [force] and bending stiffness [force·length²].
    K : (6, 6) array, out
        ``T^T K_local T`` with the classical axial/bending element matrix.
    """
    L, c, s = element_geometry(X1, X2)
    Kl = np.zeros((6, 6), dtype=K.dtype)
    ka = EA / L
    kb = EI / (L * L * L)
    Kl[0, 0] = ka
    Kl[0, 3] = -ka
    Kl[3, 0] = -ka
    Kl[3, 3] = ka
    # bending block on (v1, phi1, v2, phi2) = local indices (1, 2, 4, 5)
    idx = (1, 2, 4, 5)
    kbm = np.array(
        [
            [12.0, 6.0, -12.0, 6.0],
            [6.0, 4.0, -6.0, 2.0],
            [-12.0, -6.0, 12.0, -6.0],
            [6.0, 2.0, -6.0, 4.0],
        ]
    )
    lp = np.array([1.0, 0.0, 1.0, 0.0])  # power of L for each bending DOF (phi carries L)
    for a in range(4):
        for b in range(4):
            scale = kb
            if lp[a] == 0.0:
                scale = scale * L
            if lp[b] == 0.0:
                scale = scale * L
            Kl[idx[a], idx[b]] = kbm[a, b] * scale
    T = np.zeros((6, 6), dtype=K.dtype)
    _local_transform(c, s, T)
    # K = T^T Kl T
    for a in range(6):
        for b in range(6):
            acc = 0.0 * K[0, 0]
            for i in range(6):
                for j in range(6):
                    acc += T[i, a] * Kl[i, j] * T[j, b]
            K[a, b] = acc


@njit(cache=True)
def _local_transform(c, s, T):
    """``d_local = T d_body``: rotate the nodal displacements into the element frame."""
    T[:, :] = 0.0
    for n in range(2):
        j = 3 * n
        T[j, j] = c
        T[j, j + 1] = s
        T[j + 1, j] = -s
        T[j + 1, j + 1] = c
        T[j + 2, j + 2] = 1.0


@njit(cache=True)
def element_stress_matrix(X1, X2, E, cfib, B):
    """Linear map from element DOFs to the outer-fibre normal stress at both element ends.

    Parameters
    ----------
    X1, X2 : (2,) arrays
        Undeformed end points [length].
    E : scalar
        Young's modulus [stress].
    cfib : scalar
        Distance of the outer fibres from the centre line [length] (``t/2`` for a rectangle).
    B : (2, 2, 6) array, out
        ``sigma[end, fibre] = B[end, fibre] @ d``; ``end`` 0 at X1, 1 at X2; ``fibre`` 0 at
        ``y' = +cfib`` (left of the direction X1 -> X2), 1 at ``y' = -cfib``.

    Notes
    -----
    ``sigma = E (eps - y' kappa)`` with ``eps = (u2' - u1')/L`` and ``kappa = v''`` of the cubic
    Hermite interpolation, which is linear along the element and so peaks at an end.
    """
    L, c, s = element_geometry(X1, X2)
    T = np.zeros((6, 6), dtype=B.dtype)
    _local_transform(c, s, T)
    bl = np.zeros(6, dtype=B.dtype)
    for end in range(2):
        xi = float(end)
        bl[:] = 0.0
        bl[0] = -1.0 / L  # strain part
        bl[3] = 1.0 / L
        kap = np.zeros(6, dtype=B.dtype)
        kap[1] = (-6.0 + 12.0 * xi) / (L * L)
        kap[2] = (-4.0 + 6.0 * xi) / L
        kap[4] = (6.0 - 12.0 * xi) / (L * L)
        kap[5] = (-2.0 + 6.0 * xi) / L
        for f in range(2):
            y = cfib if f == 0 else -cfib
            for b in range(6):
                acc = 0.0 * B[0, 0, 0]
                for i in range(6):
                    acc += E * (bl[i] - y * kap[i]) * T[i, b]
                B[end, f, b] = acc


@njit(cache=True)
def beam_element_arrays(X, conn, rhoA, EA, EI, E, cfib, body_scalars, IS, I0S, I0IS, Mff, St, K, B):
    """Element arrays of one beam body, all elements in one call (no Python loop over elements).

    Parameters
    ----------
    X : (n_node, 2)
        Undeformed node positions in the body frame.
    conn : (n_elem, 2) int64
        Node indices of each element.
    rhoA, EA, EI, E, cfib : (n_elem,) arrays
        Section data per element.
    body_scalars : (4,) out
        ``[m, I_u_x, I_u_y, I_00]`` accumulated over the elements.
    IS : (n_elem, 2, 6), I0S, I0IS : (n_elem, 6), Mff, St, K : (n_elem, 6, 6), B : (n_elem, 2, 2, 6)
        Per-element invariant contributions, stiffness and stress matrices (out).
    """
    body_scalars[:] = 0.0
    for e in range(conn.shape[0]):
        X1 = X[conn[e, 0]]
        X2 = X[conn[e, 1]]
        element_invariants(X1, X2, rhoA[e], body_scalars, IS[e], I0S[e], I0IS[e], Mff[e], St[e])
        element_stiffness(X1, X2, EA[e], EI[e], K[e])
        element_stress_matrix(X1, X2, E[e], cfib[e], B[e])
