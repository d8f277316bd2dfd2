"""Complex runs factor the real step matrix (docs/theory.md §6.7).

A complex run (the whole-run complex step, a complex-step statics) takes an iteration beyond
convergence, evaluates its residual in complex arithmetic and iterates with the primal's matrix
at the real part of the iterate. Its factor solves a complex right-hand side as real columns,
through the real kernels. The derivative is then exact, which the tests here check against the
exact direct method and against central differences of the statics.
"""

import numpy as np
import pytest
import scipy.sparse as sp
from test_kernels_sparse_lu import _saddle_point
from test_sensitivity_direct import EXACT, RUN, responses_for

import morphlab as ml
import morphlab.solve.linalg as linalg
import morphlab.solve.newton as newton
from morphlab.compile import compile_model
from morphlab.compile.system import real_parts


def _spy(monkeypatch, module, name, seen):
    """Replace ``module.name`` by a wrapper that records the dtypes of its array arguments."""
    kernel = getattr(module, name)

    def spy(*args):
        seen.extend(a.dtype for a in args if isinstance(a, np.ndarray) and a.dtype.kind in "fc")
        return kernel(*args)

    monkeypatch.setattr(module, name, spy)


@pytest.mark.parametrize("dense_max", [1000, 0])
def test_a_real_factor_solves_complex_right_hand_sides_as_real_columns(monkeypatch, dense_max):
    """Dense and sparse (compiled refactorization) factors: ``solve`` and ``solve_transposed``
    of complex right-hand sides, one and several, equal the dense complex solve to round-off
    (1e-9 relative, as for real ones in test_kernels_sparse_lu.py), and the kernels they call
    see real arrays only: no kernel of mixed types is compiled."""
    A = _saddle_point()
    n = A.shape[0]
    fac = linalg.StepFactorization(A.indices.astype(np.int64), A.indptr.astype(np.int64), n,
                                   np.float64, dense_max=dense_max)
    for s in (1.0, 1.01, 1.02):  # sparse: SuperLU twice, then the compiled refactorization
        lu = fac(A.data * s)
    assert lu.compiled
    seen = []
    for name in ("lu_solve", "lu_solve_transposed", "sparse_solve", "sparse_solve_transposed"):
        _spy(monkeypatch, linalg, name, seen)
    Ad = sp.csc_matrix((A.data * 1.02, A.indices, A.indptr), shape=(n, n)).toarray()
    rng = np.random.default_rng(7)
    B = rng.normal(size=(n, 3)) + 1j * rng.normal(size=(n, 3))
    for rhs in (B, B[:, 0], B[:, :2] * 1e-30):  # several, one, a complex step's size
        x, xt = lu.solve(rhs), lu.solve_transposed(rhs)
        assert x.dtype == xt.dtype == np.complex128 and x.shape == xt.shape == rhs.shape
        scale = np.max(np.abs(rhs))
        np.testing.assert_allclose(x, np.linalg.solve(Ad, rhs), rtol=1e-9, atol=1e-12 * scale)
        np.testing.assert_allclose(xt, np.linalg.solve(Ad.T, rhs), rtol=1e-9,
                                   atol=1e-12 * scale)
    assert seen and all(dt == np.float64 for dt in seen), set(seen)


def test_real_parts_keeps_the_real_systems_types():
    """The real parts of a complex system's kernel arrays have the real system's dtypes and
    layouts, field for field (so the real kernels' cached signatures serve), and its values to
    round-off (the complex build forms the real parts in another order of operations: 1 ulp
    measured, 1e-14 relative asserted)."""
    build, p0, _ = responses_for("mechanism")
    real = compile_model(build(p0))
    cplx = compile_model(build({k: v + 1e-30j for k, v in p0.items()}))
    assert cplx.dtype == np.complex128
    got = real_parts(cplx.arrays)

    def leaves(tree):
        if isinstance(tree, tuple):
            for t in tree:
                yield from leaves(t)
        else:
            yield tree

    pairs = list(zip(leaves(got), leaves(real.arrays), strict=True))
    assert any(isinstance(a, np.ndarray) and a.dtype == np.float64 for a, _ in pairs)
    for a, b in pairs:
        if isinstance(b, np.ndarray):
            assert a.dtype == b.dtype and a.shape == b.shape and a.flags.c_contiguous
            np.testing.assert_allclose(a, b, rtol=1e-14, atol=0)
        else:
            assert a == b


def test_a_complex_run_fills_and_factors_real_matrices(monkeypatch):
    """The whole-run complex step of the mechanism (sparse factors): every fill and every
    factorization is real, and its gradients equal the exact direct method's to 1e-8 of each
    response's largest (the tolerance of tests/test_sensitivity_direct.py against the complex
    step with complex matrices: both are exact, the difference is the Newton tolerance's
    residue)."""
    build, p0, resp = responses_for("mechanism")
    fills, factored = [], []
    matrix = newton.matrix

    def spy_matrix(M, x, w, T, t, k, C, data, W):
        fills.append((data.dtype, x.q.dtype, M.gravity.dtype))
        return matrix(M, x, w, T, t, k, C, data, W)

    call = linalg.StepFactorization.__call__

    def spy_factor(self, data):
        factored.append(data.dtype)
        return call(self, data)

    monkeypatch.setattr(newton, "matrix", spy_matrix)
    monkeypatch.setattr(linalg.StepFactorization, "__call__", spy_factor)
    cs = ml.sensitivities(build, p0, resp, method="complex-step", dense_max=0, **RUN)
    assert fills and factored
    assert all(d == np.float64 for f in fills for d in f), set(fills)
    assert all(d == np.float64 for d in factored)
    monkeypatch.undo()
    ref = ml.sensitivities(build, p0, resp, method=EXACT, dense_max=0, **RUN)
    for r in resp:
        scale = max(abs(g) for g in ref.gradients[r].values())
        assert scale > 0
        for v in p0:
            assert abs(cs.gradients[r][v] - ref.gradients[r][v]) <= 1e-8 * scale, (r, v)


def test_every_complex_run_polishes_and_fills_real_matrices():
    """The real matrix rests on the iteration beyond convergence (module docstring): a complex
    solver takes at least one (a complex-step statics asks for none) and fills real matrices
    with a real scratch of its own; a real solver fills in its own dtype and polishes only as
    asked."""
    build, p0, _ = responses_for("pendulum")
    real = compile_model(build(p0))
    cplx = compile_model(build({k: v + 1e-30j for k, v in p0.items()}))
    kw = dict(tol=1e-10, max_iter=10, dense_max=100)
    for polish in (0, 1, 2):
        solver = newton.NewtonSolver(cplx, cplx.dtype, polish=polish, **kw)
        assert solver.polish == max(polish, 1)
        assert solver.data.dtype == np.float64 and solver.W_fill is not solver.W
        solver = newton.NewtonSolver(real, real.dtype, polish=polish, **kw)
        assert solver.polish == polish
        assert solver.data.dtype == np.float64 and solver.W_fill is solver.W


def test_complex_step_statics_from_an_equilibrium_gives_the_derivative(monkeypatch):
    """The morphing fit's Jacobian at its first Gauss–Newton iteration (the skin under the
    linear fit's forces, complex-step statics from that equilibrium, as
    ``morphing.design._fit_nonlinear`` takes it) against central differences of the statics
    (steps 0.01 N on forces of 1-2 kN, statics to 1e-13: truncation and noise far below the
    1e-6 asserted; an exact Jacobian agrees to 6e-10). The complex statics fill real
    matrices only, as every complex run does."""
    from morphlab.morphing import design as md
    from morphlab.morphing import leading_edge as mo

    lin = md.fit_link_forces(mo.C_NODE, mo.E_NODE, skin="paper")
    f = np.concatenate([lin["force_C"], lin["force_E"]])
    kin = md._kinematic_tol("accurate")

    def skin(g):
        return md._loaded_skin(g, mo.C_NODE, mo.E_NODE, 2.0, mo.E_AL, "accurate")

    q = ml.static(skin(f), t=1.0, steps=5, kinematic_tol=kin).q[-1]
    fills = []
    matrix = newton.matrix

    def spy_matrix(M, x, w, T, t, k, C, data, W):
        fills.append((data.dtype, x.q.dtype))
        return matrix(M, x, w, T, t, k, C, data, W)

    cs, fd = np.zeros((62, 4)), np.zeros((62, 4))
    for j in range(4):
        fj = f.astype(complex)
        fj[j] += 1e-20j
        monkeypatch.setattr(newton, "matrix", spy_matrix)
        r = ml.static(skin(fj), t=1.0, q_start=q.astype(complex), kinematic_tol=kin)
        monkeypatch.undo()
        cs[:, j] = np.imag(r.node_positions("skin", -1)).ravel() / 1e-20
        d = np.zeros(4)
        d[j] = 1e-2
        plus, minus = (ml.static(skin(f + s * d), t=1.0, q_start=q, kinematic_tol=kin,
                                 tol=1e-13).node_positions("skin", -1) for s in (1.0, -1.0))
        fd[:, j] = (plus - minus).ravel() / 2e-2
    assert np.max(np.abs(cs - fd)) <= 1e-6 * np.max(np.abs(fd))
    assert fills and all(d == np.float64 for f in fills for d in f), set(fills)
