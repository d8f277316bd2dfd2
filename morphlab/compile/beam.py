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

These are model-building functions, in NumPy: every function takes one element (``X1``, ``X2``
of shape (2,)) or a stack of them (shape (..., 2), section data broadcast against the leading
axes), so :func:`beam_element_arrays` computes all elements of a beam in a few array
operations and no compiled code is needed before the first run. Every function is written for
float64 and complex128 alike (complex-step safe): lengths use ``sqrt(dx*dx + dy*dy)``, there
are no ``abs``, comparisons or ``arctan2`` on real-valued data. A float and a complex evaluation
of the same real data agree bit for bit (an incremental compile copies float frames into a
complex system): divisions are products with ``1 / L``, because NumPy divides complex numbers
by Smith's algorithm, which for a zero imaginary part gives ``a (1 / b)``, not ``a / b``, and
every sum starts from ``+0`` (a complex product can carry a ``-0`` imaginary part).
"""

from typing import NamedTuple

import numpy as np

# 4-point Gauss–Legendre rule on [0, 1]: exact for polynomials up to degree 7, enough for
# S^T S (degree 6) and u0^T S (degree 4), so every invariant below is integrated exactly.
_G4 = np.array([0.33998104358485626, 0.8611363115940526])
_W4 = np.array([0.6521451548625461, 0.34785484513745385])
GAUSS_XI = np.array(
    [0.5 - 0.5 * _G4[1], 0.5 - 0.5 * _G4[0], 0.5 + 0.5 * _G4[0], 0.5 + 0.5 * _G4[1]]
)
GAUSS_W = np.array([0.5 * _W4[1], 0.5 * _W4[0], 0.5 * _W4[0], 0.5 * _W4[1]])


def element_geometry(X1, X2):
    """Length and direction cosines of the element(s) X1 -> X2 (body frame; (..., 2) each).

    Returns ``(L, c, s)``, each of the leading shape; complex-step safe.
    """
    X1, X2 = np.asarray(X1), np.asarray(X2)
    dx = X2[..., 0] - X1[..., 0]
    dy = X2[..., 1] - X1[..., 1]
    L = np.sqrt(dx * dx + dy * dy)
    inv = 1.0 / L
    return L, dx * inv, dy * inv


def shape_matrix(xi, L, c, s, S):
    """Body-frame shape matrix of the element(s) at ``xi`` in [0, 1].

    Parameters
    ----------
    xi : float
        Position along the element, 0 at X1 and 1 at X2.
    L, c, s : scalar or (...) arrays
        Element length and direction cosines (from :func:`element_geometry`).
    S : (..., 2, 6) array, out
        ``w(xi) = S @ d`` with ``d`` the body-frame element DOFs.
    """
    x2 = xi * xi
    x3 = x2 * xi
    # axial (linear) and transverse (Hermite) functions of each node; the rotation carries L
    axial = (1.0 - xi, xi)
    trans = (1.0 - 3.0 * x2 + 2.0 * x3, 3.0 * x2 - 2.0 * x3)
    rot = ((xi - 2.0 * x2 + x3) * L, (x3 - x2) * L)
    # u' = c ux + s uy, v' = -s ux + c uy; w = Rot(alpha) (u', v'): wx = c u' - s v',
    # wy = s u' + c v'
    for node in range(2):
        na, hv, hr = axial[node], trans[node], rot[node]
        j = 3 * node
        S[..., 0, j] = c * na * c + s * hv * s
        S[..., 0, j + 1] = c * na * s - s * hv * c
        S[..., 0, j + 2] = -s * hr
        S[..., 1, j] = s * na * c - c * hv * s
        S[..., 1, j + 1] = s * na * s + c * hv * c
        S[..., 1, j + 2] = c * hr


def element_invariants(X1, X2, rhoA, scal, IS, I0S, I0IS, Mff, St):
    """The FFRF invariants of the element(s) (``docs/theory.md`` §2.4).

    Parameters
    ----------
    X1, X2 : (..., 2) arrays
        Undeformed end points in the body frame [length].
    rhoA : scalar or (...) array
        Mass per unit length [mass/length].
    scal : (..., 4) array, in/out
        ``[m, I_u_x, I_u_y, I_00]`` of each element: mass, first moment ``∫ρ u0 dV`` and
        ``∫ρ u0^T u0 dV``, accumulated (added to).
    IS : (..., 2, 6) array, out
        ``∫ρ S dV`` of each element (overwritten).
    I0S : (..., 6) array, out
        ``∫ρ u0^T S dV`` (overwritten).
    I0IS : (..., 6) array, out
        ``∫ρ u0^T Ĩ^T S dV`` with ``Ĩ = [[0, -1], [1, 0]]`` (overwritten).
    Mff : (..., 6, 6) array, out
        ``∫ρ S^T S dV`` (overwritten).
    St : (..., 6, 6) array, out
        ``S̃ = ∫ρ S^T Ĩ S dV`` (skew-symmetric; overwritten).

    Notes
    -----
    Integrated with the 4-point Gauss rule, exact for these polynomial integrands.
    """
    X1, X2 = np.asarray(X1), np.asarray(X2)
    L, c, s = element_geometry(X1, X2)
    S = np.zeros(IS.shape, dtype=IS.dtype)
    for out in (IS, I0S, I0IS, Mff, St):
        out[...] = 0.0
    for xi, w in zip(GAUSS_XI, GAUSS_W):
        wq = w * rhoA * L
        shape_matrix(xi, L, c, s, S)
        u0x = X1[..., 0] + xi * (X2[..., 0] - X1[..., 0])
        u0y = X1[..., 1] + xi * (X2[..., 1] - X1[..., 1])
        scal[..., 0] += wq
        scal[..., 1] += wq * u0x
        scal[..., 2] += wq * u0y
        scal[..., 3] += wq * (u0x * u0x + u0y * u0y)
        wq = np.asarray(wq)[..., None]
        Sx, Sy = S[..., 0, :], S[..., 1, :]
        IS += wq[..., None] * S
        I0S += wq * (u0x[..., None] * Sx + u0y[..., None] * Sy)
        # u0^T Ĩ^T S = (Ĩ u0)^T S, Ĩ u0 = (-u0y, u0x)
        I0IS += wq * (-u0y[..., None] * Sx + u0x[..., None] * Sy)
        Mff += wq[..., None] * (Sx[..., :, None] * Sx[..., None, :]
                                + Sy[..., :, None] * Sy[..., None, :])
        # S^T Ĩ S: (Ĩ S)_b = (-S[1, b], S[0, b])
        St += wq[..., None] * (Sx[..., :, None] * (-Sy[..., None, :])
                               + Sy[..., :, None] * Sx[..., None, :])


def _local_transform(c, s):
    """``T`` (..., 6, 6) with ``d_local = T d_body``: the nodal displacements rotated into the
    element frame."""
    c = np.asarray(c)
    T = np.zeros(c.shape + (6, 6), dtype=np.result_type(c, s))
    for j in (0, 3):
        T[..., j, j] = c
        T[..., j, j + 1] = s
        T[..., j + 1, j] = -s
        T[..., j + 1, j + 1] = c
        T[..., j + 2, j + 2] = 1.0
    return T


#: The rows ``i`` with ``T[i, b] != 0`` in each column ``b`` of the element rotation ``T``.
_T_ROWS = ((0, 1), (0, 1), (2,), (3, 4), (3, 4), (5,))


def _sum_nz(x, y, b):
    """``sum_i x[..., i] y[..., i]`` over the rows ``i`` where column ``b`` of the element
    rotation is not zero, as elementwise operations in a fixed order: the same bits for an
    element computed alone or in a stack (an incremental compile relies on it; a reduction by
    ``einsum`` or BLAS may group the sum differently with the array's size)."""
    acc = 0.0  # a zero sum is +0, also in the imaginary part (a float and a complex run agree)
    for i in _T_ROWS[b]:
        acc = acc + x[..., i] * y[..., i]
    return acc


#: The classical bending block on (v1, phi1, v2, phi2), in units of EI/L^3 with phi scaled by L.
_KB = np.array([[12.0, 6.0, -12.0, 6.0],
                [6.0, 4.0, -6.0, 2.0],
                [-12.0, -6.0, 12.0, -6.0],
                [6.0, 2.0, -6.0, 4.0]])


def element_stiffness(X1, X2, EA, EI, K):
    """Linear Euler–Bernoulli stiffness of the element(s) in body-frame DOFs.

    Parameters
    ----------
    X1, X2 : (..., 2) arrays
        Undeformed end points [length].
    EA, EI : scalar or (...) arrays
        Axial stiffness [force] and bending stiffness [force·length²].
    K : (..., 6, 6) array, out
        ``T^T K_local T`` with the classical axial/bending element matrix.
    """
    L, c, s = element_geometry(X1, X2)
    Kl = np.zeros(K.shape, dtype=K.dtype)
    inv = 1.0 / L
    ka = EA * inv
    Kl[..., 0, 0] = ka
    Kl[..., 0, 3] = -ka
    Kl[..., 3, 0] = -ka
    Kl[..., 3, 3] = ka
    # bending block on (v1, phi1, v2, phi2) = local indices (1, 2, 4, 5); phi carries L
    idx = (1, 2, 4, 5)
    kb = EI * inv * inv * inv
    for a in range(4):
        for b in range(4):
            scale = kb * L if a % 2 else kb
            Kl[..., idx[a], idx[b]] = _KB[a, b] * (scale * L if b % 2 else scale)
    T = _local_transform(c, s)
    P = np.zeros(K.shape, dtype=K.dtype)  # Kl T
    for i in range(6):
        for b in range(6):
            P[..., i, b] = _sum_nz(Kl[..., i, :], T[..., :, b], b)
    for a in range(6):
        for b in range(6):
            K[..., a, b] = _sum_nz(T[..., :, a], P[..., :, b], a)


def _stress_rows(X1, X2, dtype):
    """``(Bs, Bk)`` (..., 2, 6): per element end, the axial strain ``eps = (u2' - u1')/L`` and
    the curvature ``kappa = v''`` as rows on the body-frame element DOFs."""
    L, c, s = element_geometry(X1, X2)
    inv = 1.0 / L
    T = _local_transform(c, s)
    Bs = np.zeros(L.shape + (2, 6), dtype=dtype)
    Bk = np.zeros(L.shape + (2, 6), dtype=dtype)
    for end in range(2):
        xi = float(end)
        bl = np.zeros(L.shape + (6,), dtype=dtype)  # the strain part
        bl[..., 0] = -inv
        bl[..., 3] = inv
        kap = np.zeros(L.shape + (6,), dtype=dtype)  # the curvature v''
        kap[..., 1] = (-6.0 + 12.0 * xi) * inv * inv
        kap[..., 2] = (-4.0 + 6.0 * xi) * inv
        kap[..., 4] = (6.0 - 12.0 * xi) * inv * inv
        kap[..., 5] = (-2.0 + 6.0 * xi) * inv
        for b in range(6):
            Bs[..., end, b] = _sum_nz(bl, T[..., :, b], b)
            Bk[..., end, b] = _sum_nz(kap, T[..., :, b], b)
    return Bs, Bk


def element_stress_matrix(X1, X2, E, cfib, B):
    """Linear map from element DOFs to the outer-fibre normal stress at both element ends.

    Parameters
    ----------
    X1, X2 : (..., 2) arrays
        Undeformed end points [length].
    E : scalar or (...) array
        Young's modulus [stress].
    cfib : scalar or (...) array
        Distance of the outer fibres from the centre line [length] (``t/2`` for a rectangle).
    B : (..., 2, 2, 6) array, out
        ``sigma[end, fibre] = B[end, fibre] @ d``; ``end`` 0 at X1, 1 at X2; ``fibre`` 0 at
        ``y' = +cfib`` (left of the direction X1 -> X2), 1 at ``y' = -cfib``.

    Notes
    -----
    ``sigma = E (eps - y' kappa)`` with ``eps = (u2' - u1')/L`` and ``kappa = v''`` of the cubic
    Hermite interpolation, which is linear along the element and so peaks at an end.
    """
    B[...] = _stresses(*_stress_rows(X1, X2, B.dtype), E, cfib)


def _stresses(Bs, Bk, E, cfib):
    """The stress maps (..., 2, 2, 6) ``E (eps - y' kappa)`` at ``y' = +cfib, -cfib`` from the
    rows of :func:`_stress_rows`."""
    E, c = np.asarray(E)[..., None, None], np.asarray(cfib)[..., None, None]
    return np.stack([E * (Bs - c * Bk), E * (Bs + c * Bk)], axis=-2)


class Units(NamedTuple):
    """The data of a stack of elements per unit section value: they depend on the geometry
    alone, and the data are linear in the section (:func:`element_data`). ``scal`` (n, 4),
    ``IS`` (n, 2, 6), ``I0S``, ``I0IS`` (n, 6), ``Mff``, ``St`` (n, 6, 6): the invariants per
    unit ``rhoA``; ``Ka``, ``Kb`` (n, 6, 6): the stiffness per unit ``EA`` and ``EI``; ``Bs``,
    ``Bk`` (n, 2, 6): the strain and curvature rows of each end (the stress maps per unit ``E``
    and ``E cfib``)."""

    scal: np.ndarray
    IS: np.ndarray
    I0S: np.ndarray
    I0IS: np.ndarray
    Mff: np.ndarray
    St: np.ndarray
    Ka: np.ndarray
    Kb: np.ndarray
    Bs: np.ndarray
    Bk: np.ndarray


def element_units(X1, X2, dtype) -> Units:
    """The :class:`Units` of the elements ``X1 -> X2`` ((n, 2) each, in their frames)."""
    n = X1.shape[0]
    scal = np.zeros((n, 4), dtype=dtype)
    IS = np.zeros((n, 2, 6), dtype=dtype)
    I0S, I0IS = np.zeros((n, 6), dtype=dtype), np.zeros((n, 6), dtype=dtype)
    Mff, St, Ka, Kb = (np.zeros((n, 6, 6), dtype=dtype) for _ in range(4))
    element_invariants(X1, X2, 1.0, scal, IS, I0S, I0IS, Mff, St)
    element_stiffness(X1, X2, 1.0, 0.0, Ka)
    element_stiffness(X1, X2, 0.0, 1.0, Kb)
    return Units(scal, IS, I0S, I0IS, Mff, St, Ka, Kb, *_stress_rows(X1, X2, dtype))


def element_data(u: Units, rhoA, EA, EI, E, cfib) -> tuple:
    """The arrays of :func:`element_arrays` from the elements' units ``u`` and their section
    ``rhoA, EA, EI, E, cfib`` ((n,) each): products and one sum per entry, each element's
    from its own units and section (the same bits for an element alone or in a stack)."""
    r = np.asarray(rhoA)
    EA, EI = np.asarray(EA)[:, None, None], np.asarray(EI)[:, None, None]
    return (r[:, None] * u.scal, r[:, None, None] * u.IS, r[:, None] * u.I0S,
            r[:, None] * u.I0IS, r[:, None, None] * u.Mff, r[:, None, None] * u.St,
            EA * u.Ka + EI * u.Kb, _stresses(u.Bs, u.Bk, E, cfib))


def element_arrays(X1, X2, rhoA, EA, EI, E, cfib, dtype) -> tuple:
    """The arrays of a stack of elements, in one pass of array operations.

    ``X1, X2`` (n, 2): end points, each element in the frame of its own body; ``rhoA, EA, EI,
    E, cfib`` (n,) or scalars: section data (:func:`beam_element_arrays`). Returns ``(scal
    (n, 4), IS (n, 2, 6), I0S (n, 6), I0IS (n, 6), Mff (n, 6, 6), St (n, 6, 6), K (n, 6, 6),
    B (n, 2, 2, 6))``, ``scal`` each element's share of its body's ``[m, I_u_x, I_u_y,
    I_00]``: the :class:`Units` of the geometry scaled by the section (:func:`element_data`).
    Every entry of element ``e`` comes from element ``e``'s data alone by elementwise
    operations, so it has the same bits whatever else is in the stack."""
    n = X1.shape[0]

    def each(v):
        return np.broadcast_to(np.asarray(v, dtype=dtype), (n,))

    return element_data(element_units(X1, X2, dtype), *(each(v) for v in
                                                        (rhoA, EA, EI, E, cfib)))


def beam_element_arrays(X, conn, rhoA, EA, EI, E, cfib, body_scalars, IS, I0S, I0IS, Mff, St, K,
                        B):
    """Element arrays of one beam body, all elements at once (:func:`element_arrays`).

    Parameters
    ----------
    X : (n_node, 2)
        Undeformed node positions in the body frame.
    conn : (n_elem, 2) int64
        Node indices of each element.
    rhoA, EA, EI, E, cfib : (n_elem,) arrays
        Section data per element.
    body_scalars : (4,) out
        ``[m, I_u_x, I_u_y, I_00]`` summed over the elements.
    IS : (n_elem, 2, 6), I0S, I0IS : (n_elem, 6), Mff, St, K : (n_elem, 6, 6), B : (n_elem, 2, 2, 6)
        Per-element invariant contributions, stiffness and stress matrices (out).
    """
    arrays = element_arrays(X[conn[:, 0]], X[conn[:, 1]], rhoA, EA, EI, E, cfib,
                            body_scalars.dtype)
    body_scalars[:] = arrays[0].sum(axis=0)
    for out, value in zip((IS, I0S, I0IS, Mff, St, K, B), arrays[1:]):
        out[...] = value
