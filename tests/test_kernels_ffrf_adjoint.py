"""The bodies' data gradient (``morphlab/kernels/ffrf_adjoint.py``) against the residual.

The bodies' residual share is linear in their linear design data ``D`` (invariants and element
matrices, damping and gravity held), so ``μ^T R(x; Z) = <G(x, μ), Z>`` holds for every ``Z``
exactly, with ``R(x; Z)`` the residual kernel the time loop runs, evaluated with ``Z`` in place
of the data; the stiffness's part of ``<G, Z>`` is the per-variable share ``stiffness_share``
(here one variable whose derivatives are ``Z``'s stiffness entries). The test draws ``Z``, the
state, the weights and several ``μ`` at random (every term of every row then matters, and none
cancels by symmetry) on a closed loop of rigid bodies and a damped flexible coupler under
gravity, with one frame per element and with two frames of three elements (rigid–flexible
coupling over several elements), and asks for the identity to round-off: 1e-12 of the sum of the
absolute terms."""

import numpy as np
import pytest
from models import flexible_mechanism
from numba import njit

from morphlab.compile import compile_model
from morphlab.compile.design import layout, views
from morphlab.kernels import ffrf
from morphlab.kernels.ffrf_adjoint import FIELDS, STIFFNESS, data_gradient, stiffness_share
from morphlab.kernels.schema import DESIGN, KINDS
from morphlab.kernels.types import Level, Weights

BODY_KINDS = ("bodies", "flex", "elements")


@njit
def _residual_and_gradient(B, Fx, E, g, x, w, bodies, elems, flex_on, R, W, mu, G, GO, K,
                           grad):
    ffrf.residual(B, Fx, E, g, x, w, bodies, elems, flex_on, R, W)
    data_gradient(B, Fx, E, g, x, w, mu, G, GO, W.loc)
    stiffness_share(B, Fx, E, x, w, mu, K[0], K[1], K[2], K[3], grad, W.loc)


@pytest.mark.parametrize("frames", [None, 2], ids=["frame-per-element", "two-frames"])
def test_data_gradient_is_the_transpose_of_the_residual(frames):
    rng = np.random.default_rng(7)
    kw = {} if frames is None else {"frames": frames}
    s = compile_model(flexible_mechanism(**kw))
    A = s.arrays
    n, m = s.n_dof, 3
    linear = {(k, f.name) for k in BODY_KINDS for f in KINDS[k].by_role(DESIGN) if f.linear}
    Z = np.zeros(s.design.size)
    for sl in layout(A)[1:]:
        if (sl.kind, sl.field) in linear:
            Z[sl.start:sl.start + sl.n * sl.size] = rng.standard_normal(sl.n * sl.size)
    MZ = views(A, Z, linear)
    x = Level(*(rng.standard_normal(k) for k in (n, n, n, s.n_con)))
    w = Weights(*(rng.uniform(0.5, 2.0, 8)))
    mu = rng.standard_normal((n + s.n_con, m))
    GD = np.zeros((s.design.size, m))
    starts = {(sl.kind, sl.field): sl.start for sl in layout(A)}
    GO = np.array([starts[f] for f in FIELDS], dtype=np.int64)
    k = next(sl for sl in layout(A) if (sl.kind, sl.field) == STIFFNESS)
    nk = k.n * k.size
    K = (np.array([0, k.n]), np.array([0]), np.arange(k.n),
         Z[k.start:k.start + nk].reshape(k.n, 36).copy())
    grad = np.zeros((1, m))
    n_b, n_f, n_e = (getattr(A, k)[0].shape[0] for k in BODY_KINDS)
    R = np.zeros(n + s.n_con)
    W = ffrf.scratch(n_f, np.zeros(1))
    _residual_and_gradient(MZ.bodies, MZ.flex, MZ.elements, A.gravity, x, w,
                           np.arange(n_b), np.arange(n_e), np.ones(n_f, np.bool_), R, W, mu, GD, GO,
                           K, grad)
    assert np.all(W.loc == 0.0) and np.all(W.q == 0.0)  # the scratch is zero again
    for r in range(m):
        lhs = mu[:, r] @ R
        rhs = GD[:, r] @ Z - grad[0, r]
        scale = np.abs(mu[:, r]) @ np.abs(R) + np.abs(GD[:, r]) @ np.abs(Z) + abs(grad[0, r])
        assert abs(lhs - rhs) <= 1e-12 * scale, (r, lhs, rhs)
    # the stress maps, the damping and the stiffness are not in G: their rows stay zero
    for sl in layout(A)[1:]:
        if (sl.kind, sl.field) not in linear or sl.field in ("B", "K"):
            assert not GD[sl.start:sl.start + sl.n * sl.size].any(), sl
