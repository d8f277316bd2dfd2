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
receiving ``C[r, 0] D0 + C[r, 1] Dq + C[r, 2] Dv`` for a (m, 3) float64 array ``C``: one row
``(1, bh2, gh)`` is the Newton matrix; the identity gives ``D0, Dq, Dv`` (the blocks the
sensitivity right-hand sides multiply) in the same pass.
"""

from typing import NamedTuple

import numpy as np


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
