"""Small named tuples every kernel of the residual and the step matrix reads.

* :class:`Level`: the state at one time level, ``q, v, a`` (n_dof,) and ``lam`` (n_con,), all
  of one dtype (float64, or complex128 in a complex-step run);
* :class:`Weights`: the weights of one time level's share of the residual and the run's
  constants of the constraint rows (``docs/theory.md`` §5): the inertia ``wm``, multiplier
  ``wl`` and force ``wf`` terms of the equation rows, the acceleration ``wcm`` and right-hand
  side ``wcf`` terms of the constraint rows, the row scale ``scale`` and the stabilization
  ``b0``, ``b1``.

A share of the residual is then::

    equation rows    wm M a + wl J^T lam + wf (K q + D q' - Q_v - Q_g - Q_ext + Q_s)
    constraint rows  scale (wcm J a - wcf F_c)

and the step matrix is its derivative ``D0 + bh2 Dq + gh Dv`` along ``a`` (``q = q_hat + bh2
a``, ``q' = v_hat + gh a``). The matrix kernels fill ``m`` outputs at once, output ``r``
receiving ``C[r, 0] D0 + C[r, 1] Dq + C[r, 2] Dv`` for a (m, 3) float64 array ``C`` of one
row or of three whose last two are ``(0, 1, 0)`` and ``(0, 0, 1)``: output 0 any combination
(``(1, bh2, gh)`` the Newton matrix, ``(1, 0, 0)`` ``D0``), outputs 1 and 2, where present,
``Dq`` and ``Dv`` (the blocks the sensitivity right-hand sides multiply), in the same pass.
The kernels of the bodies and the constraint rows, which add most of the entries, rely on
that form (:func:`add_split`: one product and one test per entry, not three products);
:func:`~morphlab.kernels.assemble.matrix` refuses another.
"""

from typing import NamedTuple

import numpy as np

from ._jit import inner


@inner(forceinline=True)
def add_split(out, C, p, x0, xq, xv):
    """Add an entry ``(x0, xq, xv)`` of ``(D0, Dq, Dv)`` at position ``p`` of the outputs
    ``out`` (m, nnz) of the coefficients ``C`` (1 or 3, 3) (module docstring): ``C[0, 0] x0 +
    C[0, 1] xq + C[0, 2] xv`` to output 0, ``xq`` to output 1 and ``xv`` to output 2 where
    present (one test for both: with a second test per entry the bodies' fill took twice
    as long)."""
    out[0, p] += C[0, 0] * x0 + C[0, 1] * xq + C[0, 2] * xv
    if C.shape[0] > 1:
        out[1, p] += xq
        out[2, p] += xv


class Level(NamedTuple):
    """A state at one time level (module docstring)."""

    q: np.ndarray
    v: np.ndarray
    a: np.ndarray
    lam: np.ndarray


class Weights(NamedTuple):
    """Weights of one time level's residual share (module docstring)."""

    wm: float
    wl: float
    wf: float
    wcm: float
    wcf: float
    scale: float
    b0: float
    b1: float
