"""Dense LU of small step matrices against NumPy, and the dense and SuperLU paths of the solver
against each other (the compiled Newton loop on both: ``test_kernels_newton``)."""

import numpy as np
import pytest

import morphlab as ml
from morphlab.kernels.dense import csc_to_dense, lu_factor, lu_solve, lu_solve_transposed


@pytest.mark.parametrize("dtype", [np.float64, np.complex128])
def test_lu_solves_like_numpy_with_pivoting(dtype):
    rng = np.random.default_rng(7)
    n = 12
    A = rng.normal(size=(n, n)).astype(dtype)
    if dtype == np.complex128:
        A = A + 1j * rng.normal(size=(n, n))
    A[0, 0] = 0.0  # a zero first pivot: needs a row interchange
    A[:4, :4] *= 1e-6  # a badly scaled block (saddle-point-like)
    b = rng.normal(size=(n, 3)).astype(dtype)
    LU = A.copy()
    piv = np.empty(n, dtype=np.int64)
    assert lu_factor(LU, piv) == -1
    x = b.copy()
    lu_solve(LU, piv, x)
    ref = np.linalg.solve(A, b)
    # backward-stable: residual at round-off relative to |A| |x|
    res = np.abs(A @ x - b).max() / (np.abs(A).max() * np.abs(x).max())
    assert res < 1e-14
    np.testing.assert_allclose(x, ref, rtol=1e-8)
    # the transposed solve with the same factors (the adjoint sweep): A^T y = b
    y = b.copy()
    lu_solve_transposed(LU, piv, y)
    res = np.abs(A.T @ y - b).max() / (np.abs(A).max() * np.abs(y).max())
    assert res < 1e-14
    np.testing.assert_allclose(y, np.linalg.solve(A.T, b), rtol=1e-8)


def test_exactly_singular_matrix_is_reported():
    A = np.array([[1.0, 2.0, 0.0], [2.0, 4.0, 0.0], [0.0, 0.0, 1.0]])
    assert lu_factor(A.copy(), np.empty(3, dtype=np.int64)) == 1


def test_csc_scatter():
    import scipy.sparse as sp

    M = sp.random(9, 9, density=0.3, random_state=1, format="csc")
    out = np.empty((9, 9))
    csc_to_dense(M.data, M.indices.astype(np.int64), M.indptr.astype(np.int64), out)
    np.testing.assert_array_equal(out, M.toarray())


def _four_bar():
    m = ml.Model(gravity=(0.0, -9810.0))
    crank = m.add_rigid_body(mass=1e-4, inertia=0.1, position=(0.0, 10.0), angle=np.pi / 2,
                             name="crank")
    nodes = np.linspace([0.0, 20.0], [60.0, 26.0], 5)
    coupler = m.add_beam(nodes, E=70000.0, rho=2.7e-9, thickness=2.0, width=10.0,
                         damping=1e-4, name="coupler")
    rocker = m.add_rigid_body(mass=1e-4, inertia=0.1, position=(62.0, 13.0), name="rocker")
    m.add_revolute(m.ground, crank, at=(0.0, 0.0), name="A")
    m.add_revolute(crank, coupler, at=(0.0, 20.0), name="B")
    m.add_revolute(coupler, rocker, at=(60.0, 26.0), name="C")
    m.add_revolute(rocker, m.ground, at=(64.0, 0.0), name="D")
    m.add_torque(crank, 50.0, profile=ml.SmoothStep(0.0, 0.02), name="Mt")
    return m


def test_dense_and_sparse_paths_give_the_same_run():
    """Both are backward-stable direct solvers of the same Newton systems: the runs agree to
    the Newton tolerance (1e-10 of the model size); measured 7e-15 mm on 40 steps. (29
    unknowns: sparse by default, ``dense_max`` forces either.)"""
    system = ml.compile_model(_four_bar())
    dense = ml.simulate(system, t_end=0.04, dt=1e-3, dense_max=system.n)
    sparse = ml.simulate(system, t_end=0.04, dt=1e-3, dense_max=0)
    np.testing.assert_array_equal(dense.newton_iterations, sparse.newton_iterations)
    assert np.abs(dense.q - sparse.q).max() < 1e-10 * system.length_scale
