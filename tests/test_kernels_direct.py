"""The direct-differentiation kernels against independent NumPy/SciPy evaluations.

``store`` must apply the primal's Newmark update (``morphlab.solve.scheme``) to
sensitivity columns, and the CSC ``residual`` must be ``b - A x`` (or ``b - A^T x``) for a CSC
matrix; both are checked on random data for both schemes' coefficients (exact arithmetic up to
round-off: 1e-14).
The pseudo-loads themselves are verified end to end against whole-run complex step in
tests/test_sensitivity_direct.py.
"""

import numpy as np
import pytest
import scipy.sparse as sp
from numba import njit

from morphlab.kernels.csc import residual, subtract_product, subtract_products_transposed
from morphlab.kernels.direct import store
from morphlab.solve.scheme import (
    INITIAL,
    GeneralizedAlpha,
    kernel_scheme,
    newmark_predict,
    newmark_update,
    step_coefficients,
)


@pytest.mark.parametrize("scheme", ["arnold-bruls", "paper"])
def test_update_is_the_primal_newmark_update(scheme):
    rng = np.random.default_rng(3)
    coef = step_coefficients(scheme, GeneralizedAlpha(0.7), 1e-3)
    n_t, n_dof, n_con, n_x = 4, 7, 3, 5
    hist = [rng.normal(size=(n_t, n_dof, n_x)) for _ in range(4)]
    hist.append(rng.normal(size=(n_t, n_con, n_x)))
    # kernel layout (n_x, n_t, width); compared below in the (n_t, width, n_x) of hist
    DQ, DV, DA, DG, DLAM = (np.ascontiguousarray(np.moveaxis(h, -1, 0)) for h in hist)
    x = rng.normal(size=(n_dof + n_con, n_x))
    scale = 3.5
    store(DQ, DV, DA, DG, DLAM, _scheme(coef, scale), x, 2)
    DQ, DV, DA, DG, DLAM = (np.moveaxis(h, 0, -1) for h in (DQ, DV, DA, DG, DLAM))
    q, v, a, g, _ = (h[1] for h in hist)
    qh, vh = newmark_predict(coef, q, v, a, g)
    q1, v1, g1 = newmark_update(coef, qh, vh, x[:n_dof], a, g)
    for got, want in ((DQ[2], q1), (DV[2], v1), (DG[2], g1), (DA[2], x[:n_dof]),
                      (DLAM[2], scale * x[n_dof:])):
        np.testing.assert_allclose(got, want, rtol=1e-14, atol=1e-14)
    # other entries untouched
    np.testing.assert_array_equal(DQ[3], hist[0][3])
    np.testing.assert_array_equal(DQ[1], hist[0][1])


def test_initial_entry_sets_accelerations_and_multipliers_only():
    rng = np.random.default_rng(4)
    n_dof, n_con, n_x = 5, 2, 3
    DQ, DV, DA, DG = (np.zeros((n_x, 2, n_dof)) for _ in range(4))
    DLAM = np.zeros((n_x, 2, n_con))
    DQ[:, 0] = rng.normal(size=(n_x, n_dof))
    q0 = DQ[:, 0].copy()
    x = rng.normal(size=(n_dof + n_con, n_x))
    store(DQ, DV, DA, DG, DLAM, _scheme(INITIAL, 2.0), x, 0)
    np.testing.assert_array_equal(DA[:, 0], x[:n_dof].T)
    np.testing.assert_array_equal(DG[:, 0], x[:n_dof].T)
    np.testing.assert_array_equal(DLAM[:, 0], 2.0 * x[n_dof:].T)
    np.testing.assert_array_equal(DQ[:, 0], q0)
    assert not DV.any()


@pytest.mark.parametrize("m", [2, 6])
@pytest.mark.parametrize("transposed", [False, True])
def test_csc_residual_is_b_minus_Ax(transposed, m):
    """The CSC loops read and write the right ends of each entry: against SciPy's product
    with a nonsymmetric matrix, so that ``A`` and ``A^T`` differ (round-off of 40-term sums);
    the transposed sums in registers (``m`` 2) and in ``r`` (6)."""
    rng = np.random.default_rng(5)
    A = sp.random(40, 40, density=0.15, random_state=6, format="csc") + sp.eye(40)
    A = A.tocsc()
    assert abs(A - A.T).max() > 0.1
    x = rng.normal(size=(40, m))
    b = rng.normal(size=(40, m))
    r = np.empty_like(b)
    expected = b - (A.T @ x if transposed else A @ x)
    rr, bb = residual(A.data, A.indices.astype(np.int64), A.indptr.astype(np.int64), x, b, r,
                      transposed)
    np.testing.assert_allclose(r, expected, rtol=1e-13, atol=1e-13)
    assert rr == pytest.approx(np.linalg.norm(expected), rel=1e-13)
    assert bb == pytest.approx(np.linalg.norm(b), rel=1e-13)


@njit
def _products(A1, A2, indices, indptr, n_cols, x, out1, out2, paired):
    if paired:
        subtract_products_transposed(A1, A2, indices, indptr, n_cols, x, out1, out2)
    else:
        subtract_product(A1, indices, indptr, n_cols, x, out1, True)
        subtract_product(A2, indices, indptr, n_cols, x, out2, True)


@pytest.mark.parametrize("m", [1, 3, 7])
def test_paired_transposed_products_equal_the_single_ones(m):
    """The adjoint's two products with one pattern in one pass: bit for bit the single
    products (the same terms in the same order), and ``out[:n_cols] -= A[:, :n_cols]^T x``
    against SciPy (a nonsymmetric matrix, fewer columns than rows), for right-hand sides
    summed in registers (1, 3) and in ``out`` (7)."""
    rng = np.random.default_rng(9)
    A = (sp.random(40, 40, density=0.15, random_state=7, format="csc") + sp.eye(40)).tocsc()
    A2 = A.copy()
    A2.data = rng.normal(size=A.nnz)
    ind, ptr = A.indices.astype(np.int64), A.indptr.astype(np.int64)
    x = rng.normal(size=(40, m))
    start = rng.normal(size=(40, m))
    n_cols = 31
    outs = {}
    for paired in (False, True):
        o1, o2 = start.copy(), start.copy()
        _products(A.data, A2.data, ind, ptr, n_cols, x, o1, o2, paired)
        outs[paired] = (o1, o2)
    np.testing.assert_array_equal(outs[True][0], outs[False][0])
    np.testing.assert_array_equal(outs[True][1], outs[False][1])
    for M, o in zip((A, A2), outs[True]):
        expected = start.copy()
        expected[:n_cols] -= M[:, :n_cols].T @ x
        np.testing.assert_allclose(o, expected, rtol=1e-13, atol=1e-13)


def test_two_level_buffer_of_the_algorithmic_acceleration():
    """DG with two levels (what a direct run keeps) gives the same update as a full history."""
    rng = np.random.default_rng(8)
    coef = step_coefficients("arnold-bruls", GeneralizedAlpha(0.8), 1e-3)
    n_t, n_dof, n_con, n_x = 5, 6, 2, 3
    full = [rng.normal(size=(n_x, n_t, n_dof)) for _ in range(4)]
    full.append(rng.normal(size=(n_x, n_t, n_con)))
    ring = [h.copy() for h in full]
    ring[3] = np.ascontiguousarray(np.stack([full[3][:, 4], full[3][:, 3]], axis=1))
    # levels 4, 3 stored at 4 % 2, 3 % 2
    x = rng.normal(size=(n_dof + n_con, n_x))
    store(*full, _scheme(coef, 1.5), x, 4)
    store(*ring, _scheme(coef, 1.5), x, 4)
    np.testing.assert_array_equal(ring[3][:, 0], full[3][:, 4])  # new level written at 4 % 2
    np.testing.assert_array_equal(ring[0][:, 4], full[0][:, 4])
    np.testing.assert_array_equal(ring[1][:, 4], full[1][:, 4])


def _scheme(coef, scale):
    """The kernels' scheme of ``coef`` with the constraint scale ``scale``."""
    return kernel_scheme(coef, scale, 0.0, 0.0)
