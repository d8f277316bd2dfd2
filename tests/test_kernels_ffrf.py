"""FFRF body kernels (``morphlab.kernels.ffrf``) against independent references.

The kernels form ``w_m M(q) a + w_f (K q_f + beta_d K q_f' - Q_v - Q_g)`` from the invariants
(docs/theory.md §2.5-§2.9). Here every term is rebuilt without the invariants, straight from
the kinematics of a material point ``r = R + A (u0 + S q_f)`` (Shabana, *Dynamics of Multibody
Systems*, ch. 5):

* ``M(q) = ∫ρ L^T L dV`` with ``L = dr/dq = [I, A_θ ū, A S]``, by a Gauss–Legendre rule in
  NumPy (element shape functions from the reference of ``test_kernels_beam``);
* ``Q_v = -Ṁ q̇ + ∂T/∂q`` with ``T = ½ q̇^T M(q) q̇`` (Lagrange's equations), both by complex step
  on ``q`` through that NumPy mass matrix;
* ``Q_g = -∂V/∂q`` with ``V = -∫ρ g^T r dV``, and the strain energy from the NumPy element
  stiffness;
* the Newton-matrix block of ``body_jacobian`` against complex-step columns of the residual.

The model has a rigid body and two beams (one curved, with its reference node inside the beam;
one inclined, referenced at its last node), no joints and no loads, so the body kernels are
the whole residual. Its data are O(1) in consistent units so that no term is hidden by another.
"""

import numpy as np
import pytest
import scipy.sparse as sp
from test_kernels_beam import local_shape, stiffness_reference

import morphlab as ml
from morphlab.kernels import ffrf
from morphlab.kernels.system import all_parts

H_CS = 1e-30  # complex step: no subtraction, exact to round-off for any small h
GRAVITY = np.array([0.4, -0.8])
ARC = dict(E=1.3, rho=0.9, area=1.1, second_moment=0.4, damping=0.3)
BAR = dict(E=2.1, rho=0.7, area=0.8, second_moment=0.25, damping=0.15)


def build_model():
    m = ml.Model(gravity=tuple(GRAVITY), name="ffrf-check")
    m.add_rigid_body(mass=0.6, inertia=0.35, position=(0.2, -0.4), angle=0.3, name="link")
    phi = np.linspace(0.1, 1.6, 6)
    arc = 1.5 * np.column_stack([np.cos(phi), np.sin(phi)])
    m.add_beam(arc, reference_node=2, name="arc", **ARC)
    bar = np.array([[2.0, 0.0], [2.9, 0.5], [3.7, 1.1]])
    m.add_beam(bar, reference_node=2, name="bar", **BAR)
    return m


@pytest.fixture(scope="module")
def system():
    return ml.compile_model(build_model())


@pytest.fixture(scope="module")
def state(system):
    """Random but fixed (theta, q_f, q_f', a): deformations ~0.1 of the O(1) lengths."""
    rng = np.random.default_rng(20240611)
    n = system.n_dof
    q = system.q0 + 0.1 * rng.standard_normal(n)
    for b in system.bodies.values():
        q[b.ref[2]] = rng.uniform(-np.pi, np.pi)
    return q, rng.standard_normal(n), rng.standard_normal(n)


# ---------------------------------------------------------------- NumPy reference
def _rot(th):
    c, s = np.cos(th), np.sin(th)
    return np.array([[c, -s], [s, c]])


def _beam_points(system, name):
    """Quadrature points of a beam: yields (weight*rhoA*ell, u0 (2,), S (2, 6), dofs (6,))."""
    model_beam = system.model.body(name)
    info = system.body(name)
    rhoA = model_beam.rho * model_beam.area
    xg, wg = np.polynomial.legendre.leggauss(5)  # degree-9 exact; L^T L has degree <= 6
    for k in range(info.X.shape[0] - 1):
        P1, P2 = info.X[k], info.X[k + 1]
        d = P2 - P1
        ell = np.hypot(*d)
        rot = _rot(np.arctan2(d[1], d[0]))
        T = np.zeros((6, 6))
        for j in (0, 3):
            T[j:j + 2, j:j + 2] = rot.T
            T[j + 2, j + 2] = 1.0
        dofs = np.concatenate([info.node_dofs[k], info.node_dofs[k + 1]])
        for x, w in zip(0.5 * (xg + 1), 0.5 * wg):
            S = rot @ local_shape(x, ell)[0] @ T
            yield w * rhoA * ell, P1 + x * d, S, dofs


def _L_matrix(system, name, q, u0, S, dofs):
    """dr/dq (2, n_dof) of the material point (u0, S) of a beam at q."""
    info = system.body(name)
    th = q[info.ref[2]]
    A = _rot(th)
    A_th = A @ np.array([[0.0, -1.0], [1.0, 0.0]])
    keep = dofs >= 0
    u = u0 + S[:, keep] @ q[dofs[keep]]
    L = np.zeros((2, q.size), dtype=q.dtype)
    L[:, info.ref[:2]] = np.eye(2)
    L[:, info.ref[2]] = A_th @ u
    L[:, dofs[keep]] += A @ S[:, keep]
    return L, info.ref[:2], A, u


def mass_reference(system, q):
    """M(q) = Σ ∫ρ L^T L dV (n_dof, n_dof); complex q allowed (complex step)."""
    M = np.zeros((q.size, q.size), dtype=q.dtype)
    for body in system.model.bodies:
        info = system.body(body.name)
        if info.kind == "rigid":
            M[info.ref, info.ref] += [body.mass, body.mass, body.inertia]
            continue
        for dm, u0, S, dofs in _beam_points(system, body.name):
            L, *_ = _L_matrix(system, body.name, q, u0, S, dofs)
            M += dm * L.T @ L
    return M


def gravity_potential(system, q):
    """V = -Σ ∫ρ g^T r dV with r the current position of every material point."""
    V = 0.0 * q[0]
    for body in system.model.bodies:
        info = system.body(body.name)
        if info.kind == "rigid":
            V -= body.mass * GRAVITY @ q[info.ref[:2]]
            continue
        for dm, u0, S, dofs in _beam_points(system, body.name):
            _, _, A, u = _L_matrix(system, body.name, q, u0, S, dofs)
            V -= dm * GRAVITY @ (q[info.ref[:2]] + A @ u)
    return V


def stiffness_reference_global(system):
    """Assembled K (n_dof, n_dof) and damping beta_d K from the NumPy element stiffness."""
    n = system.n_dof
    K = np.zeros((n, n))
    D = np.zeros((n, n))
    for body in system.model.bodies:
        info = system.body(body.name)
        if info.kind == "rigid":
            continue
        for k in range(info.X.shape[0] - 1):
            Ke = stiffness_reference(info.X[k], info.X[k + 1], body.E * body.area,
                                     body.E * body.second_moment)
            dofs = np.concatenate([info.node_dofs[k], info.node_dofs[k + 1]])
            keep = dofs >= 0
            K[np.ix_(dofs[keep], dofs[keep])] += Ke[np.ix_(keep, keep)]
            D[np.ix_(dofs[keep], dofs[keep])] += body.damping * Ke[np.ix_(keep, keep)]
    return K, D


def cs_gradient(f, x):
    """Complex-step gradient of a scalar function (n,)."""
    g = np.zeros(x.size)
    for j in range(x.size):
        xp = x.astype(complex)
        xp[j] += 1j * H_CS
        g[j] = f(xp).imag / H_CS
    return g


def quadratic_velocity_reference(system, q, v):
    """Q_v = -Ṁ q̇ + ∂T/∂q (Lagrange), both by complex step on q."""
    Mdot_v = (mass_reference(system, q + 1j * H_CS * v) @ v).imag / H_CS
    dT_dq = cs_gradient(lambda qq: 0.5 * v @ mass_reference(system, qq) @ v, q)
    return -Mdot_v + dT_dq, np.max(np.abs(Mdot_v)) + np.max(np.abs(dT_dq))


# ---------------------------------------------------------------- kernel calls
def residual(system, q, v, a, wm, wf, gravity=GRAVITY, stiffness=True):
    """body_residual on the System arrays (complex when any state is complex)."""
    dt = np.result_type(q, v, a, float)
    S = ml.compile.kernel_arrays(system, dt)._replace(gravity=np.asarray(gravity, dtype=dt))
    if not stiffness:
        S = S._replace(elem_K=np.zeros_like(S.elem_K))
    R = np.zeros(system.n_dof, dtype=dt)
    ffrf.body_residual(S, q.astype(dt), v.astype(dt), a.astype(dt), wm, wf, all_parts(S), R)
    return R


def jacobian(system, q, v, a, cm, cf, bh2, gh):
    """body_jacobian scattered into the compiled CSC pattern, as a dense (n_dof, n_dof)."""
    data = np.zeros(system.nnz)
    S = ml.compile.kernel_arrays(system, float)._replace(gravity=GRAVITY.copy())
    ffrf.body_jacobian(S, q, v, a, cm, cf, ((1.0, bh2, gh),), data.reshape(1, -1))
    n = system.n
    return sp.csc_matrix((data, system.indices, system.indptr), shape=(n, n)).toarray()


# ---------------------------------------------------------------- tests
def test_mass_matrix_equals_quadrature_of_LtL(system, state):
    q, _, _ = state
    n = system.n_dof
    zero = np.zeros(n)
    # columns M(q) e_j from the inertia term alone (w_m = 1, w_f = 0)
    M = np.column_stack([residual(system, q, zero, np.eye(n)[j], 1.0, 0.0) for j in range(n)])
    ref = mass_reference(system, q)
    # both sides integrate polynomials exactly (the kernel from the invariants, the reference
    # point by point): only round-off of sums of O(max M) terms remains
    scale = np.max(np.abs(ref))
    np.testing.assert_allclose(M, ref, rtol=0, atol=1e-13 * scale)
    assert np.max(np.abs(M - M.T)) < 1e-14 * scale
    # the state is really deformed and rotated: the configuration-dependent blocks matter
    M_undeformed = mass_reference(system, system.q0)
    assert np.max(np.abs(ref - M_undeformed)) > 1e-2 * scale


def test_quadratic_velocity_equals_lagrange_terms(system, state):
    q, v, _ = state
    zero = np.zeros(system.n_dof)
    # force part without gravity and stiffness: R = -Q_v
    Qv = -residual(system, q, v, zero, 0.0, 1.0, gravity=np.zeros(2), stiffness=False)
    ref, scale = quadratic_velocity_reference(system, q, v)
    # complex-step derivatives are exact to round-off; the sums carry O(eps * scale)
    np.testing.assert_allclose(Qv, ref, rtol=0, atol=1e-12 * scale)
    assert np.max(np.abs(ref)) > 1e-2 * scale  # not a vacuous comparison


def test_full_body_residual(system, state):
    q, v, a = state
    wm, wf = 0.63, 0.47
    R = residual(system, q, v, a, wm, wf)
    K, D = stiffness_reference_global(system)
    Qv, scale_v = quadratic_velocity_reference(system, q, v)
    Qg = -cs_gradient(lambda qq: gravity_potential(system, qq), q)
    elastic = K @ (q - system.q0) + D @ v  # q_f = q - q0 on flex DOFs (q0 = 0 there)
    ref = wm * mass_reference(system, q) @ a + wf * (elastic - Qv - Qg)
    scale = max(np.max(np.abs(ref)), scale_v, np.max(np.abs(K)) * np.max(np.abs(q)))
    # exact integration and complex-step derivatives: round-off of the largest terms
    np.testing.assert_allclose(R, ref, rtol=0, atol=1e-12 * scale)


# coefficient sets (cm, cf, bh2, gh) that isolate each part of the Newton matrix, and a mixed one
JAC_CASES = {
    "mass": (1.0, 0.0, 0.0, 0.0),
    "mass+d(Ma)/dq": (1.0, 0.0, 1.0, 0.0),
    "dF/dq": (0.0, 1.0, 1.0, 0.0),
    "dF/dqd": (0.0, 1.0, 0.0, 1.0),
    "mixed": (0.6, 0.55, 0.7, 1.3),
}


@pytest.mark.parametrize("case", list(JAC_CASES))
def test_body_jacobian_equals_complex_step_columns(system, state, case):
    cm, cf, bh2, gh = JAC_CASES[case]
    q, v, a = state
    # predictors chosen so that q, q' at the evaluation point are the random state
    q_pred, v_pred = q - bh2 * a, v - gh * a
    J = jacobian(system, q, v, a, cm, cf, bh2, gh)
    n = system.n_dof
    ref = np.zeros((n, n))
    for j in range(n):
        ac = a.astype(complex)
        ac[j] += 1j * H_CS
        ref[:, j] = residual(system, q_pred + bh2 * ac, v_pred + gh * ac, ac, cm, cf).imag / H_CS
    scale = np.max(np.abs(ref))
    # complex step is exact to round-off; entries below 1e-12 of the largest are pure
    # round-off of sums and compared absolutely, the others to 1e-10 relative
    big = np.abs(ref) > 1e-12 * scale
    np.testing.assert_allclose(J[big], ref[big], rtol=1e-10)
    np.testing.assert_allclose(J[~big], ref[~big], rtol=0, atol=1e-12 * scale)
    # a dense comparison: an entry missing from the compiled pattern would show up as a zero
    assert np.count_nonzero(big) > 3 * n  # many coupled entries, not just a diagonal


def test_part_residual_equals_the_residual_over_the_same_parts(system, state):
    """body_part_residual (a pseudo-load's few parts, on reused scratch) gives body_residual's
    numbers over the same parts bit for bit, leaves its scratch zero, and so does not leak one
    call's products into the next. Parts as a design variable forms them: some elements,
    their bodies and coordinates, and the masked coordinates of a body whose invariants
    changed; complex data as in a complex step (a real state)."""
    from morphlab.kernels.direct import part_scratch
    from morphlab.kernels.system import Parts

    q, v, a = state
    S = ml.compile.kernel_arrays(system, complex)
    S = S._replace(elem_K=S.elem_K * (1 + 1e-3j), elem_M=S.elem_M * (1 - 2e-3j),
                   flex_IS=S.flex_IS * (1 + 1e-3j), gravity=GRAVITY.astype(complex))
    R0 = np.zeros(system.n_dof, dtype=complex)
    W = part_scratch(S, q, R0)
    rng = np.random.default_rng(7)
    n_elem, n_flex = S.elem_fdof.shape[0], S.flex_dof.shape[0]
    empty = np.zeros(0, np.int64)
    for trial in range(12):
        elems = np.sort(rng.choice(n_elem, size=1 + trial % 3, replace=False))
        flex = np.zeros(n_flex, dtype=bool)
        fd = S.elem_fdof[elems].ravel()
        flex[fd[fd >= 0]] = True
        flex[rng.random(n_flex) < 0.2] = True
        owner = np.repeat(np.arange(S.body_ref.shape[0]), np.diff(S.flex_off))
        bodies = np.unique(np.concatenate([S.elem_body[elems], owner[flex], [0]]))
        parts = Parts(bodies.astype(np.int64), elems.astype(np.int64), flex, empty, empty,
                      empty, empty)
        R_full = np.zeros(system.n_dof, dtype=complex)
        R_part = np.zeros(system.n_dof, dtype=complex)
        ffrf.body_residual(S, q, v, a, 0.7, 0.9, parts, R_full)
        ffrf.body_part_residual(S, q, v, a, 0.7, 0.9, parts, R_part, W)
        assert np.array_equal(R_part, R_full), trial
        assert not W.q.any() and not W.p.any(), trial
