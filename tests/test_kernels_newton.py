"""The Newton loop in one compiled call (``morphlab.kernels.newton``) against the step-by-step
loop of the solver, which chains the same kernels from Python: on both kinds of factor (dense
LU of small matrices, sparse refactorization with a kept row order) the iterates must be the
same bit for bit, and failures must stop where the step-by-step loop stops."""

import numpy as np
import pytest
from models import flexible_mechanism
from morphlab.kernels.assemble import apply_correction, step_matrix, step_residual
from morphlab.kernels.newton import (
    CONVERGED,
    NONFINITE_RESIDUAL,
    PIVOT_REFUSED,
    SINGULAR,
    newton_loop,
)
from morphlab.kernels.system import DESIGN_FIELDS

import morphlab as ml
from morphlab.compile.system import table_at, time_table
from morphlab.solve import linalg, superlu
from morphlab.solve.settings import Settings
from morphlab.solve.stepper import Stepper

TAU = superlu.PIVOT_THRESHOLD


def _one_iteration(S, z, qh, vh, args, ta, n_dof, R_hist, system, R, data, factors, length):
    """One iteration of the compiled loop (``max_iter = 1``, ``tol = inf``): ``(z, status,
    bad, hist)``."""
    hist = np.zeros((1, 2))
    z1, it, status, bad = newton_loop(
        S, z, qh, vh, *args, *ta, n_dof, R_hist, system.indices, system.indptr, False, length,
        np.inf, 1, 0, R, data, *factors, TAU, hist)
    assert it == 1
    return z1, status, bad, hist[0]


@pytest.mark.parametrize("dtype", [np.float64, np.complex128])
@pytest.mark.parametrize("kind", ["dense", "sparse"])
def test_compiled_iteration_is_the_step_by_step_sequence(monkeypatch, kind, dtype):
    """One iteration of ``newton_loop`` gives bitwise the residual, matrix, factors, iterate
    and correction of the kernels it chains, called one by one as the solver's Python loop
    does (same arithmetic, same order); it stops early, without touching what comes after, on
    a non-finite residual (no matrix) and on a factorization that fails (no solve: a singular
    dense matrix, a sparse pivot that fails the threshold). Taken at a converged step of the
    flexible four-bar with a perturbed iterate."""
    dense_max = 1000 if kind == "dense" else 0
    system = ml.compile_model(flexible_mechanism())
    settings = Settings(t_end=0.004, dt=1e-3, dense_max=dense_max)
    res = ml.simulate(system, settings=settings)
    stp = Stepper.dynamic(system, settings, scale=res.scale)
    coef = stp.step_coef
    n, n_dof, L = system.n, system.n_dof, system.length_scale
    dt = np.dtype(dtype)
    S = ml.compile.kernel_arrays(system, dt)
    ta = table_at(time_table(system, res.t, dt), 3)
    rng = np.random.default_rng(2)
    z = np.concatenate([res.a[3], res.lam[3] / res.scale]).astype(dt)
    z = z * (1.0 + 1e-3 * rng.standard_normal(n))
    qh = (res.q[3] - coef.bh2 * res.a[3]).astype(dt)
    vh = (res.v[3] - coef.gh * res.a[3]).astype(dt)
    R_hist = np.zeros(n, dtype=dt)
    args = (coef.bh2, coef.gh, stp.scale, coef.arrays.w_new, stp.b0, stp.b1)
    fac = linalg.StepFactorization(system.indices, system.indptr, n, dt, dense_max)
    data0 = np.empty(system.nnz, dtype=dt)
    step_matrix(S, z, qh, vh, *args, ta[3], data0)
    while not fac.settled:  # SuperLU chooses the orders on the first two matrices
        fac(data0)
    assert fac.dense == (kind == "dense")

    def iterate(S, qh, R, data, factors):
        return _one_iteration(S, z, qh, vh, args, ta, n_dof, R_hist, system, R, data, factors,
                              L)

    R1, data1 = np.empty(n, dtype=dt), np.empty(system.nnz, dtype=dt)
    F1 = fac.loop_arrays()
    z1, status1, bad1, (r1, err1) = iterate(S, qh, R1, data1, F1)

    R2, data2 = np.empty(n, dtype=dt), np.empty(system.nnz, dtype=dt)
    ssq2 = step_residual(S, z, qh, vh, *args, *ta, n_dof, R_hist, R2)
    step_matrix(S, z, qh, vh, *args, ta[3], data2)
    lu = fac(data2)
    z2, big2, fin2 = apply_correction(z, lu.solve(-R2), n_dof)
    factors = lu.kernel_args()[:2] if kind == "dense" else lu.kernel_args()[2:5]
    mine = F1[:2] if kind == "dense" else F1[2:5]
    assert (lu.group == "dense") == (kind == "dense") and lu.group is not None

    assert (status1, bad1) == (CONVERGED, -1) and fin2
    assert r1 == np.sqrt(ssq2) and err1 == coef.bh2 * big2 / L
    for a, b in ((R1, R2), (data1, data2), *zip(mine, factors), (z1, z2)):
        np.testing.assert_array_equal(a, b)
    assert np.abs(z1 - z).max() > 0.0

    # a NaN in the state: the residual says so and the matrix is not formed
    qbad = qh.copy()
    qbad[0] = np.nan
    data3 = np.full(system.nnz, 7.0, dtype=dt)
    z3, status3, bad3, _ = iterate(S, qbad, np.empty(n, dtype=dt), data3,
                                   fac.loop_arrays())
    assert (status3, bad3) == (NONFINITE_RESIDUAL, -1) and z3 is z
    assert np.all(data3 == 7.0)
    # all masses, stiffnesses and joints scaled to zero: the factorization reports a column
    S0 = S._replace(**{f: getattr(S, f) * 0 for f in DESIGN_FIELDS})
    z4, status4, bad4, _ = iterate(S0, qh, np.empty(n, dtype=dt),
                                   np.empty(system.nnz, dtype=dt), fac.loop_arrays())
    assert status4 == (SINGULAR if kind == "dense" else PIVOT_REFUSED)
    assert bad4 >= 0 and z4 is z
    if kind == "sparse":  # the refactorization's work column is left clean for the next one
        assert not np.any(fac.row_order.work)


def _runs(monkeypatch, system, **kw):
    """The same run with the compiled loop and with every iteration in Python; the number of
    row orders SuperLU chose in each."""
    orders = []
    choose = superlu.NaturalOrderLU.__call__

    def counted(self, data):
        orders[-1] += 1
        return choose(self, data)

    monkeypatch.setattr(superlu.NaturalOrderLU, "__call__", counted)
    out = []
    for compiled in (True, False):
        orders.append(0)
        out.append(ml.simulate(system, compiled_newton=compiled, **kw))
    return out, orders


def test_compiled_loop_gives_the_run_of_the_python_loop(monkeypatch):
    """The morphing leading edge with a 60-element skin (213 unknowns: sparse): with the
    compiled loop and with every iteration from Python the run is the same bit for bit, with
    as many iterations and factorizations. SuperLU renews the row order during this run (a
    pivot fails the threshold inside the compiled loop, which hands the iteration back to
    Python), the same in both. The mechanism is the study's former design (E = node 22,
    x_A = 102 mm), kept here because its run exercises those renewals; the current design's
    run keeps its first order."""
    from morphlab import morphing as mo

    former = {"x_A": 102.0, "y_A": -0.25, "x_B": 99.29, "y_B": -8.25, "x_D": 108.85,
              "y_D": -5.88}
    system = ml.compile_model(mo._assemble(former, 60, drive=False, nodes=(4, 22),
                                           skin="accurate", sense=1))
    (fast, slow), orders = _runs(monkeypatch, system, **mo.SETTINGS)
    assert orders[0] == orders[1] >= 2  # the order of the second matrix, then renewals
    for name in ("q", "v", "a", "lam", "newton_iterations"):
        np.testing.assert_array_equal(getattr(fast, name), getattr(slow, name))
    assert fast.n_factorizations == slow.n_factorizations


def test_compiled_dense_loop_gives_the_run_of_the_python_loop(monkeypatch):
    """The same on dense factors (the flexible four-bar, 35 unknowns, factored dense)."""
    system = ml.compile_model(flexible_mechanism())
    (fast, slow), _ = _runs(monkeypatch, system, t_end=0.02, dt=1e-3, dense_max=1000)
    for name in ("q", "lam", "newton_iterations"):
        np.testing.assert_array_equal(getattr(fast, name), getattr(slow, name))
    assert fast.n_factorizations == slow.n_factorizations
