"""Consistent initial velocities from the drives and constraints at ``t = 0``.

A drive whose angle has a nonzero rate at ``t = 0`` (a drive by speed, or ``Linear``) asks for
moving bodies from the start. When the model gives no initial velocity at all, the velocities
are the solution of the velocity-level constraints ``Phi_q q' = -Phi_t`` of least kinetic
energy: the saddle-point system

    [ M    Phi_q^T ] [ q' ]   [    0   ]
    [ Phi_q   0    ] [ mu ] = [ -Phi_t ]

(``docs/theory.md``: the constraint rows are those of the step matrix, eq. 30-33, weighted for
``a``). The unknowns are first the reference coordinates of the bodies only (the frames move as
rigid bodies, the beams start undeformed in rate), which is exactly solvable whenever the
constraints allow a rigid motion; otherwise every coordinate takes part. The solve is linear
algebra on the system's arrays, so a complex-step perturbation of a drive's speed or of the
geometry carries through to ``v0`` (the initial sensitivities ``dv0`` of a sensitivity run).
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from ..kernels import assemble as kassemble
from ..kernels.ffrf import scratch
from ..kernels.types import Level, Weights
from .system import time_table

# weights of the step-matrix kernel for [M J^T; J 0]: inertia, multipliers, constraint rows
_SADDLE_WEIGHTS = Weights(1.0, 1.0, 0.0, 1.0, 0.0, 1.0, 0.0, 0.0)


def needs_initial_velocities(system) -> bool:
    """No initial velocity given anywhere, but a drive moving at ``t = 0`` (``Phi_t != 0``).

    At ``q' = 0`` the velocity-level violation of a row is minus its target's rate
    (``kernels/joints.py: values``, ``kernels/slides.py: values``), so the rates of the time
    values at ``t = 0`` decide, read without a kernel: the perturbed designs of a sensitivity
    run (complex numbers for a complex step) compile no constraint kernels for it. A rate that
    is zero in its real part and not in its imaginary part (a drive's speed of zero as the
    design variable) asks for the velocities: their derivatives are not zero."""
    if system.n_con == 0 or np.any(system.v0 != 0):
        return False
    T = time_table(system, np.zeros(1))
    return any(table is not None and bool(np.any(table.cd[:, 0] != 0))
               for table in (T.rows, T.slides))


def _saddle_matrix(system) -> sp.csc_matrix:
    dt = system.dtype
    n = system.n
    data = np.zeros((1, system.nnz), dtype=dt)
    zero = np.zeros(system.n_dof, dtype=dt)
    x = Level(system.q0, zero, zero, np.zeros(system.n_con, dtype=dt))
    kassemble.matrix(system.arrays, x, _SADDLE_WEIGHTS, time_table(system, np.zeros(1)), 0, 0,
                     np.array([[1.0, 0.0, 0.0]]), data, scratch(system.count("flex"), zero))
    return sp.csc_matrix((data[0], system.indices, system.indptr), shape=(n, n))


def initial_velocities(system) -> np.ndarray:
    """Velocities ``(n_dof,)`` of least kinetic energy satisfying the velocity-level
    constraints at ``t = 0`` (see the module docstring); same dtype as the system."""
    n_dof = system.n_dof
    _, phid = system.constraint_violation(system.q0, np.zeros_like(system.q0), 0.0)
    A = _saddle_matrix(system)
    rhs = np.concatenate([np.zeros(n_dof, dtype=system.dtype), -phid])
    ref = np.sort(system.arrays.bodies.ref.reshape(-1))
    J_ref = A[n_dof:, :][:, ref].toarray()
    # the rank is decided on real parts: a complex-step perturbation takes the same branch
    if np.linalg.matrix_rank(np.real(J_ref)) == system.n_con:
        keep = np.concatenate([ref, n_dof + np.arange(system.n_con)])
        z = np.linalg.solve(A[keep, :][:, keep].toarray(), rhs[keep])
        v = np.zeros(n_dof, dtype=system.dtype)
        v[ref] = z[: ref.size]
        return v
    return spla.spsolve(A.tocsc(), rhs)[:n_dof].astype(system.dtype)
