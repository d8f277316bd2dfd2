"""Dense LU of small step matrices against NumPy, and the dense and SuperLU paths of the solver
against each other."""

import numpy as np
import pytest
from morphlab.kernels.dense import csc_to_dense, lu_factor, lu_solve

import morphlab as ml
import morphlab.factorization as factorization


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


def test_dense_and_superlu_paths_give_the_same_run(monkeypatch):
    """Both are backward-stable direct solvers of the same Newton systems: the runs agree to
    the Newton tolerance (1e-10 of the model size); measured 7e-15 mm on 40 steps."""
    system = ml.compile_model(_four_bar())
    assert system.n <= factorization.DENSE_MAX
    dense = ml.simulate(system, t_end=0.04, dt=1e-3)
    monkeypatch.setattr(factorization, "DENSE_MAX", 0)
    sparse = ml.simulate(system, t_end=0.04, dt=1e-3)
    np.testing.assert_array_equal(dense.newton_iterations, sparse.newton_iterations)
    assert np.abs(dense.q - sparse.q).max() < 1e-10 * system.length_scale


def test_compiled_newton_iteration_is_the_step_by_step_sequence():
    """``dense_newton_iteration`` (one call) must give bitwise the iterate, residual, matrix
    and factors of the kernels it chains, called one by one as the SuperLU path of the
    solver does (same arithmetic, same order); and stop early, without touching what comes
    after, on a non-finite residual (no matrix) and on an exactly singular matrix (no solve).
    Taken at a converged step of the four-bar with a perturbed iterate, real and complex."""
    from morphlab.kernels.assemble import (
        apply_correction,
        dense_newton_iteration,
        step_matrix,
        step_residual,
    )

    from morphlab.solver import Settings, Stepper, table_at, time_table

    system = ml.compile_model(_four_bar())
    res = ml.simulate(system, t_end=0.004, dt=1e-3)
    stp = Stepper(system, Settings(t_end=0.004, dt=1e-3), scale=res.scale)
    coef = stp.step_coef
    n, n_dof = system.n, system.n_dof
    for dt in (np.float64, np.complex128):
        S = ml.solver.kernel_arrays(system, dt)
        ta = table_at(time_table(system, res.t, dt), 3)
        rng = np.random.default_rng(2)
        z = np.concatenate([res.a[3], res.lam[3] / res.scale]).astype(dt)
        z = z * (1.0 + 1e-3 * rng.standard_normal(n))
        qh = (res.q[3] - coef.bh2 * res.a[3]).astype(dt)
        vh = (res.v[3] - coef.gh * res.a[3]).astype(dt)
        R_hist = np.zeros(n, dtype=dt)
        args = (coef.bh2, coef.gh, stp.scale, coef.arrays[3], stp.b0, stp.b1)

        R1, data1 = np.empty(n, dtype=dt), np.empty(system.nnz, dtype=dt)
        LU1, piv1 = np.empty((n, n), dtype=dt), np.empty(n, dtype=np.int64)
        z1, ssq1, big1, fin1, bad1 = dense_newton_iteration(
            S, z, qh, vh, *args, *ta, n_dof, R_hist, system.indices, system.indptr, R1, data1,
            LU1, piv1)

        R2, data2 = np.empty(n, dtype=dt), np.empty(system.nnz, dtype=dt)
        ssq2 = step_residual(S, z, qh, vh, *args, *ta, n_dof, R_hist, R2)
        step_matrix(S, z, qh, vh, *args, ta[3], data2)
        LU2, piv2 = np.empty((n, n), dtype=dt), np.empty(n, dtype=np.int64)
        csc_to_dense(data2, system.indices, system.indptr, LU2)
        assert lu_factor(LU2, piv2) == -1
        dz = -R2.reshape(n, 1).copy()
        lu_solve(LU2, piv2, dz)
        z2, big2, fin2 = apply_correction(z, dz[:, 0], n_dof)

        assert (bad1, fin1) == (-1, fin2) and fin2
        assert ssq1 == ssq2 and big1 == big2
        for a, b in ((R1, R2), (data1, data2), (LU1, LU2), (piv1, piv2), (z1, z2)):
            np.testing.assert_array_equal(a, b)
        assert np.abs(z1 - z).max() > 0.0

        # a NaN in the state: the residual says so and the matrix is not formed
        qbad = qh.copy()
        qbad[0] = np.nan
        data3 = np.full(system.nnz, 7.0, dtype=dt)
        z3, ssq3, _, _, bad3 = dense_newton_iteration(
            S, z, qbad, vh, *args, *ta, n_dof, R_hist, system.indices, system.indptr,
            np.empty(n, dtype=dt), data3, np.empty((n, n), dtype=dt), piv1)
        assert not np.isfinite(ssq3) and bad3 == -1 and z3 is z
        assert np.all(data3 == 7.0)
        # a singular matrix (all masses, stiffnesses and joints scaled to zero): a pivot column
        S0 = tuple(x * 0 if x.dtype == dt else x for x in S)
        z4, _, _, _, bad4 = dense_newton_iteration(
            S0, z, qh, vh, *args, *ta, n_dof, R_hist, system.indices, system.indptr,
            np.empty(n, dtype=dt), np.empty(system.nnz, dtype=dt), np.empty((n, n), dtype=dt),
            piv1)
        assert bad4 >= 0 and z4 is z
