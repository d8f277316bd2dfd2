"""Element functions of ``morphlab.compile.beam`` against independent NumPy references.

References
----------
* Shape functions: the defining interpolation conditions of the element (axial field linear,
  transverse field cubic, nodal values and nodal slopes reproduced), checked directly on the
  kernel's output — they determine the linear/cubic Hermite interpolant uniquely.
* Invariants, stiffness and stress: the definitions (docs/theory.md §2.4, §3; Shabana, *Dynamics of
  Multibody Systems*, ch. 5 for the FFRF invariants; Przemieniecki, *Theory of Matrix Structural
  Analysis*, ch. 5 for the beam element) evaluated here with NumPy and a Gauss–Legendre rule of a
  different order than the kernel's.
* Complex step: the kernels run unchanged on complex128 input (identical values for a zero
  imaginary part), and the complex-step derivative matches a central difference.
"""

import numpy as np
import pytest

from morphlab.compile import beam as kb

EPS = np.finfo(float).eps

# an inclined element with non-trivial section data (unit-free: only the algebra is tested)
X1 = np.array([0.3, -0.2])
X2 = np.array([2.1, 0.9])
RHOA, EA, EI, E, CFIB = 0.8, 3.0, 0.5, 2.0, 0.1


# ---------------------------------------------------------------- NumPy reference element
def local_shape(xi, ell):
    """Element-frame shape functions ``(u', v') = N d_local`` (2, 6) and their x-derivatives.

    Returns ``N, dN, ddN`` with ``d/dx' = (1/ell) d/dxi``: linear axial field, cubic Hermite
    transverse field (nodal values and slopes), d_local = (u1', v1', phi1, u2', v2', phi2).
    """
    x2, x3 = xi * xi, xi * xi * xi
    N = np.zeros((2, 6), dtype=np.result_type(xi, ell))
    dN = np.zeros_like(N)
    ddN = np.zeros_like(N)
    N[0, 0], N[0, 3] = 1 - xi, xi
    dN[0, 0], dN[0, 3] = -1 / ell, 1 / ell
    N[1, 1] = 1 - 3 * x2 + 2 * x3
    N[1, 2] = ell * (xi - 2 * x2 + x3)
    N[1, 4] = 3 * x2 - 2 * x3
    N[1, 5] = ell * (x3 - x2)
    dN[1, 1] = (-6 * xi + 6 * x2) / ell
    dN[1, 2] = 1 - 4 * xi + 3 * x2
    dN[1, 4] = (6 * xi - 6 * x2) / ell
    dN[1, 5] = 3 * x2 - 2 * xi
    ddN[1, 1] = (-6 + 12 * xi) / ell**2
    ddN[1, 2] = (-4 + 6 * xi) / ell
    ddN[1, 4] = (6 - 12 * xi) / ell**2
    ddN[1, 5] = (6 * xi - 2) / ell
    return N, dN, ddN


def element_frame(P1, P2):
    """Length, 2 x 2 rotation element -> body frame, and the 6 x 6 map d_local = T d_body."""
    d = P2 - P1
    ell = np.sqrt(d @ d)
    c, s = d / ell
    rot = np.array([[c, -s], [s, c]])
    T = np.zeros((6, 6), dtype=rot.dtype)
    for j in (0, 3):
        T[j:j + 2, j:j + 2] = rot.T
        T[j + 2, j + 2] = 1.0
    return ell, rot, T


def shape_reference(xi, P1, P2):
    """Body-frame shape matrix S (2, 6): ``w = rot @ N(xi) @ T @ d_body``."""
    ell, rot, T = element_frame(P1, P2)
    return rot @ local_shape(xi, ell)[0] @ T


def invariants_reference(P1, P2, rhoA, n_gauss=6):
    """Element invariants by an n-point Gauss–Legendre rule (exact for n >= 4)."""
    ell = np.sqrt((P2 - P1) @ (P2 - P1))
    xg, wg = np.polynomial.legendre.leggauss(n_gauss)
    Itil = np.array([[0.0, -1.0], [1.0, 0.0]])
    out = dict(scal=np.zeros(4, dtype=np.result_type(P1, rhoA)))
    out.update(IS=0, I0S=0, I0IS=0, Mff=0, St=0)
    for x, w in zip(0.5 * (xg + 1), 0.5 * wg):
        S = shape_reference(x, P1, P2)
        u0 = P1 + x * (P2 - P1)
        dm = w * rhoA * ell
        out["scal"] = out["scal"] + dm * np.array([1.0, u0[0], u0[1], u0 @ u0])
        out["IS"] = out["IS"] + dm * S
        out["I0S"] = out["I0S"] + dm * u0 @ S
        out["I0IS"] = out["I0IS"] + dm * u0 @ Itil.T @ S
        out["Mff"] = out["Mff"] + dm * S.T @ S
        out["St"] = out["St"] + dm * S.T @ Itil @ S
    return out


def stiffness_reference(P1, P2, EA_, EI_):
    """K = ∫ (EA B_a^T B_a + EI B_b^T B_b) dx' (3-point Gauss: exact for degree-2 integrands)."""
    ell, _, T = element_frame(P1, P2)
    xg, wg = np.polynomial.legendre.leggauss(3)
    K = 0.0
    for x, w in zip(0.5 * (xg + 1), 0.5 * wg):
        _, dN, ddN = local_shape(x, ell)
        Ba, Bb = dN[0] @ T, ddN[1] @ T
        K = K + w * ell * (EA_ * np.outer(Ba, Ba) + EI_ * np.outer(Bb, Bb))
    return K


# ---------------------------------------------------------------- kernel calls
def call_shape(xi, P1, P2):
    ell, c, s = kb.element_geometry(P1, P2)
    S = np.zeros((2, 6), dtype=np.result_type(P1, xi))
    kb.shape_matrix(xi, ell, c, s, S)
    return S


def call_invariants(P1, P2, rhoA):
    dt = np.result_type(P1, P2, rhoA)
    out = dict(scal=np.zeros(4, dtype=dt), IS=np.zeros((2, 6), dtype=dt),
               I0S=np.zeros(6, dtype=dt), I0IS=np.zeros(6, dtype=dt),
               Mff=np.zeros((6, 6), dtype=dt), St=np.zeros((6, 6), dtype=dt))
    kb.element_invariants(P1, P2, rhoA, out["scal"], out["IS"], out["I0S"], out["I0IS"],
                          out["Mff"], out["St"])
    return out


def call_stiffness(P1, P2, EA_, EI_):
    K = np.zeros((6, 6), dtype=np.result_type(P1, P2, EA_, EI_))
    kb.element_stiffness(P1, P2, EA_, EI_, K)
    return K


def call_stress(P1, P2, E_, c_):
    B = np.zeros((2, 2, 6), dtype=np.result_type(P1, P2, E_, c_))
    kb.element_stress_matrix(P1, P2, E_, c_, B)
    return B


def call_element_arrays(X, rhoA, EA_, EI_, E_, c_):
    """beam_element_arrays on a polyline; returns every output in one flat vector."""
    n_el = X.shape[0] - 1
    dt = np.result_type(X, rhoA)
    conn = np.stack([np.arange(n_el), np.arange(1, n_el + 1)], axis=1).astype(np.int64)
    one = np.ones(n_el, dtype=dt)
    arrs = [np.zeros(4, dtype=dt), np.zeros((n_el, 2, 6), dtype=dt), np.zeros((n_el, 6), dtype=dt),
            np.zeros((n_el, 6), dtype=dt), np.zeros((n_el, 6, 6), dtype=dt),
            np.zeros((n_el, 6, 6), dtype=dt), np.zeros((n_el, 6, 6), dtype=dt),
            np.zeros((n_el, 2, 2, 6), dtype=dt)]
    kb.beam_element_arrays(X, conn, one * rhoA, one * EA_, one * EI_, one * E_, one * c_, *arrs)
    return np.concatenate([a.ravel() for a in arrs])


# ---------------------------------------------------------------- shape functions
def test_shape_matrix_is_the_hermite_interpolant():
    ell, c, s = kb.element_geometry(X1, X2)
    t_dir, n_dir = np.array([c, s]), np.array([-s, c])
    xs = np.linspace(0.0, 1.0, 7)
    Ss = np.array([call_shape(x, X1, X2) for x in xs])  # (7, 2, 6)
    # axial component linear and transverse component cubic in xi: the least-squares fit of
    # that degree leaves only round-off (entries are O(L) = O(2)).
    ax = np.einsum("i,kij->kj", t_dir, Ss)
    tr = np.einsum("i,kij->kj", n_dir, Ss)
    for comp, deg in ((ax, 1), (tr, 3)):
        fit = np.polynomial.polynomial.polyfit(xs, comp, deg)
        resid = comp - np.polynomial.polynomial.polyval(xs, fit).T
        assert np.max(np.abs(resid)) < 1e-13
    # nodal values: w(0) = node-1 displacement, w(1) = node-2 displacement (exact arithmetic
    # on 0 and 1 up to the c^2 + s^2 = 1 round-off)
    sel1 = np.zeros((2, 6))
    sel1[:, 0:2] = np.eye(2)
    sel2 = np.zeros((2, 6))
    sel2[:, 3:5] = np.eye(2)
    np.testing.assert_allclose(call_shape(0.0, X1, X2), sel1, atol=4 * EPS)
    np.testing.assert_allclose(call_shape(1.0, X1, X2), sel2, atol=4 * EPS)
    # nodal slopes: d(n.w)/dx' at the ends is the nodal rotation; complex step in xi (exact)
    h = 1e-30
    for xi, k in ((0.0, 2), (1.0, 5)):
        slope = n_dir @ call_shape(xi + 1j * h, X1.astype(complex), X2.astype(complex)).imag / h
        np.testing.assert_allclose(slope / ell, np.eye(6)[k], atol=1e-14)


def test_shape_matrix_matches_numpy_reference():
    for xi in (0.0, 0.13, 0.5, 0.77, 1.0):
        # same polynomials evaluated in a different order: round-off of O(L) entries
        np.testing.assert_allclose(call_shape(xi, X1, X2), shape_reference(xi, X1, X2),
                                   rtol=0, atol=1e-14)


# ---------------------------------------------------------------- invariants
def test_element_invariants_match_quadrature_of_definitions():
    got = call_invariants(X1, X2, RHOA)
    ref = invariants_reference(X1, X2, RHOA)
    for key in ref:
        # both integrate the polynomial integrands exactly (4 vs 6 Gauss points): round-off
        # relative to the largest entry of each array
        scale = np.max(np.abs(ref[key]))
        np.testing.assert_allclose(got[key], ref[key], rtol=0, atol=1e-13 * scale, err_msg=key)
    # structure: M_ff symmetric positive semi-definite, S~ skew
    np.testing.assert_allclose(got["Mff"], got["Mff"].T, atol=1e-15)
    np.testing.assert_allclose(got["St"], -got["St"].T, atol=1e-15)
    # closed form of the straight segment: m = rhoA L, I_u = m (X1 + X2)/2,
    # I_00 = m (|X1|^2 + X1.X2 + |X2|^2)/3 (round-off only)
    ell = np.hypot(*(X2 - X1))
    m = RHOA * ell
    np.testing.assert_allclose(got["scal"], [m, *(m * (X1 + X2) / 2),
                                             m * (X1 @ X1 + X1 @ X2 + X2 @ X2) / 3], rtol=1e-14)


def test_element_invariants_accumulate_scalars():
    scal = np.array([1.0, 2.0, 3.0, 4.0])
    got = call_invariants(X1, X2, RHOA)["scal"]
    buf = [np.zeros((2, 6)), np.zeros(6), np.zeros(6), np.zeros((6, 6)), np.zeros((6, 6))]
    kb.element_invariants(X1, X2, RHOA, scal, *buf)
    # documented as "accumulated (added to)": one addition of O(1) numbers
    np.testing.assert_allclose(scal, [1.0, 2.0, 3.0, 4.0] + got, rtol=1e-15)


# ---------------------------------------------------------------- stiffness and stress
def test_element_stiffness_matches_strain_energy_and_rigid_modes():
    K = call_stiffness(X1, X2, EA, EI)
    ref = stiffness_reference(X1, X2, EA, EI)
    # exact integration on both sides; entries up to 12 EI/L^3 ~ 1 and EA/L ~ 1: round-off
    np.testing.assert_allclose(K, ref, rtol=0, atol=1e-14 * np.max(np.abs(ref)))
    np.testing.assert_allclose(K, K.T, atol=1e-15 * np.max(np.abs(K)))
    # rigid-body motions in the body plane (translations, rotation about the origin) are
    # strain-free: K r = 0 to round-off of the O(|K| |X|) products
    rigid = np.array([[1, 0, 0, 1, 0, 0], [0, 1, 0, 0, 1, 0],
                      [-X1[1], X1[0], 1, -X2[1], X2[0], 1]], dtype=float)
    assert np.max(np.abs(K @ rigid.T)) < 1e-13 * np.max(np.abs(K))
    # and these are the only zero-energy modes: three zero eigenvalues, three positive
    ev = np.linalg.eigvalsh(K)
    assert np.all(np.abs(ev[:3]) < 1e-13 * ev[-1]) and ev[3] > 1e-3 * ev[-1]


def test_element_stress_matrix_matches_fibre_formula():
    B = call_stress(X1, X2, E, CFIB)
    ell, _, T = element_frame(X1, X2)
    for end in (0, 1):
        _, dN, ddN = local_shape(float(end), ell)
        for fib, y in ((0, CFIB), (1, -CFIB)):
            ref = E * (dN[0] - y * ddN[1]) @ T  # sigma = E (eps - y' kappa)
            # entries of size E/L ~ 1: round-off
            np.testing.assert_allclose(B[end, fib], ref, rtol=0, atol=1e-14)
    # a pure bending deformation v = kappa0 x'^2 / 2 (element frame) gives the uniform
    # stress -E y kappa0 at both ends; a uniform stretch eps0 gives E eps0 (exact for the
    # element's polynomial spaces)
    kappa0, eps0 = 0.03, 2e-3
    _, rot, T = element_frame(X1, X2)
    d_loc = np.array([0, 0, 0, 0, 0.5 * kappa0 * ell**2, kappa0 * ell]) + np.array(
        [0, 0, 0, eps0 * ell, 0, 0])
    d_body = T.T @ d_loc  # T is orthogonal
    sig = B @ d_body
    expect = E * eps0 - E * np.array([CFIB, -CFIB]) * kappa0
    np.testing.assert_allclose(sig, np.stack([expect, expect]), rtol=1e-13)


# ---------------------------------------------------------------- complex step
def _complex(x):
    return np.asarray(x, dtype=complex)


CASES = {
    "element_geometry": lambda P1, P2, r: np.array(kb.element_geometry(P1, P2)),
    "shape_matrix": lambda P1, P2, r: call_shape(0.37 + 0 * r, P1, P2),
    "element_invariants": lambda P1, P2, r: np.concatenate(
        [v.ravel() for v in call_invariants(P1, P2, r).values()]),
    "element_stiffness": lambda P1, P2, r: call_stiffness(P1, P2, EA * r / RHOA, EI),
    "element_stress_matrix": lambda P1, P2, r: call_stress(P1, P2, E, CFIB * r / RHOA),
    "beam_element_arrays": lambda P1, P2, r: call_element_arrays(
        np.stack([P1, P2, P2 + np.array([0.7, 1.1]), P2 + np.array([1.9, 0.8])]),
        r, EA, EI, E, CFIB),
}


@pytest.mark.parametrize("name", sorted(CASES))
def test_kernel_same_values_for_float_and_complex(name):
    f = CASES[name]
    real = f(X1, X2, RHOA)
    cplx = f(_complex(X1), _complex(X2), complex(RHOA))
    assert np.iscomplexobj(cplx) and not np.iscomplexobj(real)
    # zero imaginary parts propagate exactly (products/sums with 0); the real parts use the same
    # operations, up to the complex sqrt's last bit: a few ulps of the largest entry
    assert np.all(cplx.imag == 0.0)
    np.testing.assert_allclose(cplx.real, real, rtol=0, atol=8 * EPS * np.max(np.abs(real)))


@pytest.mark.parametrize("name", sorted(CASES))
@pytest.mark.parametrize("wrt", ["X2y", "X1x", "rhoA"])
def test_kernel_complex_step_matches_central_difference(name, wrt):
    f = CASES[name]

    def g(eps):
        P1, P2, r = _complex(X1), _complex(X2), complex(RHOA)
        if wrt == "X2y":
            P2 = P2 + np.array([0.0, eps])
        elif wrt == "X1x":
            P1 = P1 + np.array([eps, 0.0])
        else:
            r = r + eps
        return f(P1, P2, r)

    d_cs = g(1e-30j).imag / 1e-30
    h = 1e-5
    d_fd = (g(h).real - g(-h).real) / (2 * h)
    scale = max(np.max(np.abs(d_cs)), np.max(np.abs(f(X1, X2, RHOA))))
    # central difference: truncation h^2 f'''/6 ~ 1e-10 (data of O(1) on an O(1) element) plus
    # cancellation eps |f| / h ~ 1e-11; the complex step is exact to round-off
    np.testing.assert_allclose(d_fd, d_cs, rtol=0, atol=1e-8 * scale)
    # and the derivative is not trivially zero for the inputs each output depends on
    if not (wrt == "rhoA" and name in ("element_geometry", "shape_matrix")):
        assert np.max(np.abs(d_cs)) > 1e-3 * scale
