"""Sparse refactorization with SuperLU's row order (kernels.sparse_lu) against SuperLU and
dense solves, and the factorization object built on it."""

import numpy as np
import pytest
import scipy.sparse as sp
from scipy.sparse.linalg import splu

import morphlab.solve.linalg as factorization
from morphlab.kernels.sparse_lu import refactor, solve, symbolic


def _saddle_point(n_q=30, n_c=8, seed=3, dtype=np.float64):
    """A sparse saddle-point matrix like a step matrix: banded SPD-ish block, a constraint
    block J / J^T with a zero diagonal block (needs row pivoting), one badly scaled row."""
    rng = np.random.default_rng(seed)
    K = sp.diags([rng.uniform(1, 2, n_q)], [0]) * 4.0
    K = K + sp.diags([rng.normal(size=n_q - 1), rng.normal(size=n_q - 1)], [1, -1])
    K = K + sp.diags([rng.normal(size=n_q - 3)], [3])  # unsymmetric coupling
    J = sp.random(n_c, n_q, density=0.15, random_state=seed) + sp.eye(n_c, n_q)
    A = sp.bmat([[K, J.T], [J, None]], format="csc").astype(dtype)
    if dtype == np.complex128:
        A.data = A.data + 1j * rng.normal(size=A.nnz) * 0.3
    A.sort_indices()
    return A


def _as_is(nnz):
    """``gather, scale`` of :func:`refactor` for a matrix factored in its own order, unscaled."""
    return np.arange(nnz), np.ones(nnz)


def _factor(A, tau):
    lu = splu(A, permc_spec="NATURAL", diag_pivot_thresh=0.1, options=dict(SymmetricMode=True))
    pr = lu.perm_r.astype(np.int64)
    ind, ptr = A.indices.astype(np.int64), A.indptr.astype(np.int64)
    Lp, Li, Up, Ui = symbolic(A.shape[0], ind, ptr, pr)
    n = A.shape[0]
    Lx = np.empty(Li.size, A.dtype)
    Ux = np.empty(Ui.size, A.dtype)
    Ud = np.empty(n, A.dtype)
    work = np.zeros(n, A.dtype)
    bad = refactor(A.data, *_as_is(A.nnz), ind, ptr, pr, Lp, Li, Up, Ui, Lx, Ux, Ud, work, tau)
    return lu, pr, (Lp, Li, Lx, Up, Ui, Ux, Ud), bad, work


@pytest.mark.parametrize("dtype", [np.float64, np.complex128])
def test_refactor_reproduces_superlu_factors(dtype):
    """With SuperLU's row order the factors are unique (L unit lower, U upper): the same
    L and U as SuperLU's to round-off, in the pattern the symbolic pass found."""
    A = _saddle_point(dtype=dtype)
    n = A.shape[0]
    lu, pr, (Lp, Li, Lx, Up, Ui, Ux, Ud), bad, work = _factor(A, 0.0)
    assert bad == -1
    assert not np.any(work)  # the work column is returned clean
    L = (sp.csc_matrix((Lx, Li, Lp), shape=(n, n)) + sp.eye(n)).toarray()
    U = (sp.csc_matrix((Ux, Ui, Up), shape=(n, n)) + sp.diags(Ud)).toarray()
    # elimination error O(n eps |L||U|); the entries are O(1-10): 1e-12 absolute
    np.testing.assert_allclose(L, lu.L.toarray(), rtol=0, atol=1e-12)
    np.testing.assert_allclose(U, lu.U.toarray(), rtol=0, atol=1e-12)
    # the symbolic pattern holds every nonzero of SuperLU's factors and is not padded
    assert np.count_nonzero(np.tril(lu.L.toarray(), -1)) <= Li.size <= lu.L.nnz
    for j in range(n):
        assert np.all(np.diff(Li[Lp[j]:Lp[j + 1]]) > 0) and np.all(Li[Lp[j]:Lp[j + 1]] > j)
        assert np.all(np.diff(Ui[Up[j]:Up[j + 1]]) > 0) and np.all(Ui[Up[j]:Up[j + 1]] < j)


@pytest.mark.parametrize("dtype", [np.float64, np.complex128])
def test_refactor_of_a_changed_matrix_solves_it(dtype):
    """The row order of one matrix reused for a matrix with the same pattern and other values:
    the solve is backward stable (residual at round-off relative to |A| |x|)."""
    A0 = _saddle_point(dtype=dtype)
    A1 = A0.copy()
    rng = np.random.default_rng(5)
    A1.data = A1.data * (1 + 0.05 * rng.normal(size=A1.nnz))
    _, pr, _, _, _ = _factor(A0, 0.0)
    n = A1.shape[0]
    ind, ptr = A1.indices.astype(np.int64), A1.indptr.astype(np.int64)
    Lp, Li, Up, Ui = symbolic(n, ind, ptr, pr)
    Lx, Ux, Ud = (np.empty(k, dtype) for k in (Li.size, Ui.size, n))
    assert refactor(A1.data, *_as_is(A1.nnz), ind, ptr, pr, Lp, Li, Up, Ui, Lx, Ux, Ud,
                    np.zeros(n, dtype), 0.1) == -1
    b = rng.normal(size=(n, 3)).astype(dtype)
    x = np.empty_like(b)
    solve(Lp, Li, Lx, Up, Ui, Ux, Ud, np.argsort(pr), np.ones(n), np.arange(n), np.ones(n),
          b, x, np.empty_like(b))
    Ad = A1.toarray()
    res = np.abs(Ad @ x - b).max() / (np.abs(Ad).max() * np.abs(x).max())
    assert res < 1e-14
    np.testing.assert_allclose(x, np.linalg.solve(Ad, b), rtol=1e-9, atol=1e-12)


def test_a_pivot_below_the_threshold_is_reported():
    """A row order chosen for one matrix, a later matrix whose pivot in column 0 became small
    against the entry below it: the threshold test names that column, and tau = 0 still
    accepts it (nonzero); an exactly zero pivot fails even with tau = 0."""
    A = sp.csc_matrix(np.array([[4.0, 1.0, 0.0], [1.0, 3.0, 1.0], [0.0, 1.0, 2.0]]))
    A.sort_indices()
    pr = np.arange(3, dtype=np.int64)
    ind, ptr = A.indices.astype(np.int64), A.indptr.astype(np.int64)
    Lp, Li, Up, Ui = symbolic(3, ind, ptr, pr)
    bufs = lambda: (np.empty(Li.size), np.empty(Ui.size), np.empty(3), np.zeros(3))  # noqa: E731
    small = A.copy()
    small.data[0] = 0.05  # pivot 0.05 against 1.0 below it
    assert refactor(small.data, *_as_is(7), ind, ptr, pr, Lp, Li, Up, Ui, *bufs(), 0.1) == 0
    assert refactor(small.data, *_as_is(7), ind, ptr, pr, Lp, Li, Up, Ui, *bufs(), 0.0) == -1
    zero = A.copy()
    zero.data[0] = 0.0
    work = np.zeros(3)
    assert refactor(zero.data, *_as_is(7), ind, ptr, pr, Lp, Li, Up, Ui, *bufs()[:3], work,
                    0.0) == 0
    assert not np.any(work)  # clean after a failure too


def test_step_factorization_renews_the_row_order_when_a_pivot_fails():
    """StepFactorization: SuperLU factors the first matrix (fill-reducing order) and the
    second (row order), the compiled refactorization every later one while the pivots pass the
    threshold; a matrix that makes a pivot fail goes back to SuperLU for a new row order and
    is refactored with it (a compiled factor, which the sensitivity methods solve with), and
    the next matrix reuses that order. Every solution is exact to round-off."""
    A = _saddle_point()
    n = A.shape[0]
    fac = factorization.StepFactorization(A.indices.astype(np.int64),
                                          A.indptr.astype(np.int64), n, np.float64, dense_max=0)
    rng = np.random.default_rng(11)
    b = rng.normal(size=n)
    B = rng.normal(size=(n, 4)) + 1j * rng.normal(size=(n, 4))

    def check(data, compiled, orders):
        """``compiled``: the refactorization or SuperLU's own; ``solve`` and
        ``solve_transposed`` both exact to round-off."""
        lu = fac(data)
        assert lu.compiled == compiled and fac.n_orders == orders
        Ad = sp.csc_matrix((data, A.indices, A.indptr), shape=(n, n)).toarray()
        np.testing.assert_allclose(lu.solve(b), np.linalg.solve(Ad, b), rtol=1e-9, atol=1e-12)
        # several right-hand sides, complex ones through a real factorization
        np.testing.assert_allclose(lu.solve(B), np.linalg.solve(Ad, B), rtol=1e-9, atol=1e-12)
        np.testing.assert_allclose(lu.solve_transposed(B), np.linalg.solve(Ad.T, B), rtol=1e-9,
                                   atol=1e-12)
        # the transposed solve takes a few right-hand sides in pairs (an odd count's last one
        # alone, one alone too), more in one pass
        wide = np.hstack([B, B[:, :2] * 1j])
        for rhs in (B[:, :3], b, wide):
            np.testing.assert_allclose(lu.solve_transposed(rhs), np.linalg.solve(Ad.T, rhs),
                                       rtol=1e-9, atol=1e-12)
        return lu

    superlu, compiled = False, True
    check(A.data, superlu, 0)
    check(A.data * 1.01, superlu, 1)
    first_order = check(A.data * 1.02, compiled, 1).order  # a uniform scaling keeps every ratio
    # make the first pivot tiny: column q[0] of A is factored first, its pivot is the entry
    # in the row that SuperLU's row order put first
    q = fac._order[0]
    j0, i0 = q[0], q[np.argsort(fac.row_order.perm_r)[0]]
    entries = range(A.indptr[j0], A.indptr[j0 + 1])
    assert len(entries) > 1  # something left in the column to pivot on
    changed = A.data.copy()
    for k in entries:
        if A.indices[k] == i0:
            changed[k] *= 1e-6
    renewed = check(changed, compiled, 2).order
    assert renewed is not first_order and renewed is fac.row_order
    assert not np.array_equal(renewed.perm_r, first_order.perm_r)  # really another row order
    assert check(changed * 1.01, compiled, 2).order is renewed


def test_scaling_keeps_the_fill_of_the_initial_matrix_of_a_fine_skin(monkeypatch):
    """The initial-acceleration matrix (mass and constraint blocks) of a skin of 2000 elements
    (0.1 mm each): beam-node rotations have diagonal masses ~l^3 against couplings ~l^2, so
    without scaling SuperLU's threshold test rejects most diagonal pivots and the row
    interchanges fill L + U with 1.5 M nonzeros (25x the matrix). Factored as ``D A D``
    (column_scaling) the fill is 0.12 M, 2x the matrix, as for every skin up to 1500
    elements with or without scaling. 4x asserted; the unscaled factorization, the same call
    with ``column_scaling`` returning ones, is shown to exceed 10x. Both solve the system to a
    componentwise backward error (|A x - b| against |A| |x| + |b|) measured 1.1e-11 scaled,
    6e-15 unscaled and 7e-13 with SciPy's default splu; the scaled threshold pivoting trades
    some accuracy in the rows of the tiny rotational masses for the fill. 1e-10 asserted
    (the normwise backward error, what a stable LU guarantees, is ~1e-23)."""
    import morphlab as ml
    from morphlab import morphing as mo
    from morphlab.compile.system import time_table
    from morphlab.solve import superlu
    from morphlab.solve.settings import Settings
    from morphlab.solve.stepper import Stepper

    # the paper's single-frame skin: the matrix whose fill this test measured
    system = ml.compile_model(mo.build(mo.DEFAULTS, n_elements=2000, skin="paper"))
    st = Stepper.dynamic(system, Settings.of(mo.SETTINGS, dense_max=0),
                         time_table(system, np.zeros(1)))
    p = st.problem(system.q0, system.v0, st.init_coef, None, st.T, 0, 0.0, 0)
    fill = np.zeros((1, system.nnz))
    p.fill(np.zeros(st.n), fill, st.newton.W)
    data = fill[0]
    A = factorization.csc_matrix(data, system.indices, system.indptr, system.n)
    fills = []
    for scaled in (True, False):
        if not scaled:
            monkeypatch.setattr(superlu, "column_scaling", lambda d, p: np.ones(p.size - 1))
        fac = factorization.StepFactorization(system.indices, system.indptr, system.n,
                                              np.float64, dense_max=0)
        lu = fac(data)
        fills.append(lu.lu.nnz / data.size)
        b = np.ones(system.n)
        x = lu.solve(b)
        assert np.max(np.abs(A @ x - b) / (abs(A) @ np.abs(x) + 1.0)) < 1e-10
    assert fills[0] < 4.0 < 10.0 < fills[1], fills


def test_kept_factors_take_rows_of_chunks_and_solve_as_before(monkeypatch):
    """Compiled refactorizations in a row take consecutive rows of one chunk of factor values
    (a chunk of three factors here: rows 0, 1, 2 of three chunks for seven factors), each
    factor its own row, and each still solves its own matrix after later ones are formed
    (exact to round-off): a later factorization never writes into a kept factor."""
    A = _saddle_point()
    n = A.shape[0]
    fac = factorization.StepFactorization(A.indices.astype(np.int64),
                                          A.indptr.astype(np.int64), n, np.float64, dense_max=0)
    fac(A.data)
    fac(A.data * 1.01)  # SuperLU twice: the row order is chosen
    per = fac.row_order
    _, Li, _, Ui = per.ready().patterns
    monkeypatch.setattr(factorization, "CHUNK_BYTES", 3 * 8 * (Li.size + Ui.size + n))
    per._chunk = None
    scales = 1.02 + 0.01 * np.arange(7)
    lus = [fac(A.data * s) for s in scales]
    assert all(lu.compiled and lu.order is per for lu in lus)
    assert [lu.row for lu in lus] == [0, 1, 2, 0, 1, 2, 0]
    chunks = [lu.Lx.base for lu in lus]
    assert len({id(c) for c in chunks}) == 3  # 3 + 3 + 1 rows
    for k, lu in enumerate(lus):
        for name in ("Lx", "Ux", "Ud"):
            a = getattr(lu, name)
            np.testing.assert_array_equal(a, a.base[lu.row])  # row ``row`` of its chunk
        assert (lu.Lx.base is lus[k - 1].Lx.base) == (k % 3 != 0)
    rng = np.random.default_rng(5)
    b = rng.normal(size=n)
    for s, lu in zip(scales, lus):
        Ad = sp.csc_matrix((A.data * s, A.indices, A.indptr), shape=(n, n)).toarray()
        np.testing.assert_allclose(lu.solve(b), np.linalg.solve(Ad, b), rtol=1e-9, atol=1e-12)
