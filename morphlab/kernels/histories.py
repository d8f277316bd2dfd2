"""A run's histories as the compiled loops read them (:mod:`morphlab.kernels.steps`).

Each history is a (levels, width) array: level ``k % levels`` holds time index ``k``, so a
history the run keeps in full has ``n_t`` levels and one it only steps with two.
"""

from typing import NamedTuple

import numpy as np

from . import joints, slides
from ._jit import inner
from .types import Level


class Histories(NamedTuple):
    """A run's histories: ``Q, V, A, G`` (levels, n_dof), ``L`` (levels, n_con) (module
    docstring), Newton's iterations per step ``iters`` (n_t,) int64, the ``(|R|,
    correction)`` of each iteration ``newton`` (n_t, max_iter, 2), and the largest constraint
    violation at position and velocity level ``viol`` (n_t, 2), formed step by step (when
    ``track``: a model with constraints)."""

    Q: np.ndarray
    V: np.ndarray
    A: np.ndarray
    G: np.ndarray
    L: np.ndarray
    iters: np.ndarray
    newton: np.ndarray
    viol: np.ndarray
    track: bool


@inner
def violations(M, T, H, k0, k1):
    """``max |Phi|`` and ``max |Phi'|`` (real parts) at the time indices ``k0 .. k1 - 1`` into
    ``H.viol`` (the states there must still be held)."""
    n_con = H.L.shape[1]
    phi = np.zeros(n_con, dtype=H.Q.dtype)
    phid = np.zeros(n_con, dtype=H.Q.dtype)
    for k in range(k0, k1):
        q, v = H.Q[k % H.Q.shape[0]], H.V[k % H.V.shape[0]]
        joints.values(M.rows, q, v, T.rows, k, phi, phid)
        slides.values(M.slides, q, v, T.slides, k, phi, phid)
        m0 = 0.0
        m1 = 0.0
        for i in range(n_con):
            a = abs(phi[i].real)
            b = abs(phid[i].real)
            if a > m0:
                m0 = a
            if b > m1:
                m1 = b
        H.viol[k, 0] = m0
        H.viol[k, 1] = m1


@inner
def state_at(H, k):
    """The state (:class:`~morphlab.kernels.types.Level`) and algorithmic acceleration at time
    index ``k``."""
    return (Level(H.Q[k % H.Q.shape[0]], H.V[k % H.V.shape[0]], H.A[k % H.A.shape[0]],
                  H.L[k % H.L.shape[0]]), H.G[k % H.G.shape[0]])
