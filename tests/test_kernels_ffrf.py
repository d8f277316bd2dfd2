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
* the bodies' block of the step matrix against complex-step columns of the residual.

The model has a rigid body and two beams (one curved, with its reference node inside the beam;
one inclined, referenced at its last node), no joints and no loads, so the body kernels are
the whole residual. Its data are O(1) in consistent units so that no term is hidden by another.
"""

import numpy as np
import pytest
import scipy.sparse as sp
from test_kernels_beam import local_shape, stiffness_reference

import morphlab as ml
from morphlab.compile.system import time_table
from morphlab.kernels import assemble, ffrf
from morphlab.kernels.system import KIND_NAMES, Parts, all_parts
from morphlab.kernels.types import Level, Weights

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
def arrays(system, dt, gravity=GRAVITY, stiffness=True):
    """The system's arrays in ``dt`` with the test's gravity (and, without ``stiffness``, the
    element stiffness zeroed); new tuples, the system's own are untouched."""
    M = system.arrays_as(dt)._replace(gravity=np.asarray(gravity, dtype=dt))
    if not stiffness:
        M = M._replace(elements=M.elements._replace(K=np.zeros_like(M.elements.K)))
    return M


def body_residual(system, M, q, v, a, wm, wf, parts=None, W=None):
    """The whole-system residual kernel over ``parts`` (default all); with no joints and no
    loads in the model, the body kernels are all of it. Weights: inertia ``wm``, forces
    ``wf``, no multiplier or constraint terms. ``W``: the bodies' scratch (default fresh)."""
    dt = M.gravity.dtype
    n_dof = system.n_dof
    x = Level(q.astype(dt), v.astype(dt), a.astype(dt), np.zeros(system.n_con, dtype=dt))
    w = Weights(wm, 0.0, wf, 0.0, 0.0, 1.0, 0.0, 0.0)
    T = time_table(system, np.zeros(1), dt)
    P = all_parts(M) if parts is None else parts
    W = ffrf.scratch(system.count("flex"), x.q) if W is None else W
    R = np.zeros(system.n, dtype=dt)
    assemble.residual(M, x, w, T, np.int64(0), np.int64(0), P, np.int64(n_dof), R, W)
    return R[:n_dof]


def residual(system, q, v, a, wm, wf, gravity=GRAVITY, stiffness=True):
    """The body residual on the System arrays (complex when any state is complex)."""
    dt = np.result_type(q, v, a, float)
    return body_residual(system, arrays(system, dt, gravity, stiffness), q, v, a, wm, wf)


def jacobian(system, q, v, a, cm, cf, bh2, gh):
    """The step-matrix kernel (Newton row ``(1, bh2, gh)``) scattered into the compiled CSC
    pattern, as a dense (n_dof, n_dof)."""
    M = arrays(system, float)
    x = Level(q, v, a, np.zeros(system.n_con))
    w = Weights(cm, 0.0, cf, 0.0, 0.0, 1.0, 0.0, 0.0)
    T = time_table(system, np.zeros(1))
    data = np.zeros((1, system.nnz))
    assemble.matrix(M, x, w, T, np.int64(0), np.int64(0), np.array([[1.0, bh2, gh]]), data,
                    ffrf.scratch(system.count("flex"), q))
    n = system.n
    return sp.csc_matrix((data[0], system.indices, system.indptr), shape=(n, n)).toarray()


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


def _parts(bodies, elems, flex) -> Parts:
    """:class:`Parts` covering the bodies ``bodies``, elements ``elems`` and coordinates with
    ``flex`` set, and no item of any other kind."""
    sel = {"bodies": bodies, "elements": elems}
    counts = [len(sel.get(k, ())) for k in KIND_NAMES]
    off = np.concatenate([[0], np.cumsum(counts)]).astype(np.int64)
    idx = np.concatenate([np.asarray(sel.get(k, ()), dtype=np.int64) for k in KIND_NAMES])
    return Parts(off, idx, flex)


def test_part_residual_equals_the_residual_over_the_same_parts(system, state):
    """The residual over a pseudo-load's few parts (on reused scratch) gives, bit for bit, the
    residual over every part of the same data with everything outside those parts zeroed
    (the premise of the linear path of the pseudo-loads: the data a variable does not change
    have zero derivative), leaves its scratch zero, and so does not leak one call's products
    into the next (a fresh scratch gives the same numbers). Parts as a design variable forms
    them: some elements, their bodies and all their coordinates, and the masked coordinates
    of a body whose invariants changed; complex data as in a complex step (a real state)."""
    q, v, a = state
    S = arrays(system, complex)
    S = S._replace(elements=S.elements._replace(K=S.elements.K * (1 + 1e-3j),
                                                M=S.elements.M * (1 - 2e-3j)),
                   flex=S.flex._replace(IS=S.flex.IS * (1 + 1e-3j)))
    B, Fx, E = S.bodies, S.flex, S.elements
    W = ffrf.scratch(system.count("flex"), q.astype(complex))
    rng = np.random.default_rng(7)
    n_elem, n_flex, n_body = E.fdof.shape[0], Fx.dof.shape[0], B.ref.shape[0]
    owner = np.repeat(np.arange(n_body), B.flex[:, 1] - B.flex[:, 0])
    for trial in range(12):
        elems = np.sort(rng.choice(n_elem, size=1 + trial % 3, replace=False))
        flex = np.zeros(n_flex, dtype=bool)
        fd = E.fdof[elems].ravel()
        flex[fd[fd >= 0]] = True
        flex[rng.random(n_flex) < 0.2] = True
        bodies = np.unique(np.concatenate([E.body[elems], owner[flex], [0]]))
        R_part = body_residual(system, S, q, v, a, 0.7, 0.9, _parts(bodies, elems, flex), W)
        assert not W.q.any() and not W.p.any(), trial
        R_fresh = body_residual(system, S, q, v, a, 0.7, 0.9, _parts(bodies, elems, flex))
        assert np.array_equal(R_part, R_fresh), trial
        # the reference: every part, with the linear data outside the parts zeroed
        out_b = np.setdiff1d(np.arange(n_body), bodies)
        out_e = np.setdiff1d(np.arange(n_elem), elems)
        Z = S._replace(
            bodies=B._replace(scal=np.where(np.isin(np.arange(n_body), out_b)[:, None], 0,
                                            B.scal)),
            flex=Fx._replace(IS=np.where(flex[:, None], Fx.IS, 0), I0S=np.where(flex, Fx.I0S, 0),
                             I0IS=np.where(flex, Fx.I0IS, 0)),
            elements=E._replace(**{f: np.where(np.isin(np.arange(n_elem), out_e)[:, None, None],
                                               0, getattr(E, f)) for f in ("M", "St", "K")}))
        R_full = body_residual(system, Z, q, v, a, 0.7, 0.9)
        assert np.array_equal(R_part, R_full), trial
        assert np.abs(R_part).max() > 1e-3 * np.abs(body_residual(system, S, q, v, a, 0.7,
                                                                   0.9)).max(), trial


@pytest.mark.parametrize("C", [np.eye(3)[:2], np.eye(3)[[0, 2, 1]], np.ones((3, 3)),
                               np.eye(4)[:, :3]],
                         ids=["two rows", "rows swapped", "combinations", "four rows"])
def test_step_matrix_refuses_coefficients_of_another_form(system, state, C):
    """The fill writes ``Dq``, ``Dv`` to outputs 1 and 2 without reading ``C``'s last rows
    (``kernels.types``): a ``C`` of another form is refused, not filled wrongly."""
    q, v, a = state
    M = arrays(system, float)
    x = Level(q, v, a, np.zeros(system.n_con))
    w = Weights(1.0, 0.0, 1.0, 0.0, 0.0, 1.0, 0.0, 0.0)
    data = np.zeros((C.shape[0], system.nnz))
    with pytest.raises(ValueError, match="one row, or three"):
        assemble.matrix(M, x, w, time_table(system, np.zeros(1)), np.int64(0), np.int64(0), C,
                        data, ffrf.scratch(system.count("flex"), q))
