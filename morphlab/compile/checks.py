"""Checks of a compiled system: initial configuration on the constraints, the rank of the
constraint Jacobian (redundant or conflicting joints), with messages naming the joints, and
the plausibility of the model's units (:func:`check_units`, run by ``simulate`` and ``static``
before they start)."""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from ..errors import ModelError, UnitsWarning, warn
from ..kernels.joints import ANGLE_LIKE
from ..model import Beam
from ..model import units as _units


def _joint_hint(system, joint_name: str) -> str:
    """Where the joint sits relative to the nodes of the beams it connects (for messages)."""
    joint = next((j for j in system.model.joints if j.name == joint_name), None)
    if joint is None or getattr(joint, "at", None) is None:
        return ""
    sides = [getattr(joint, k) for k in ("a", "b", "body") if hasattr(joint, k)]
    parts = []
    for body in sides:
        if isinstance(body, Beam):
            k, dist = body.nearest_node(joint.at)
            parts.append(f"its point is {dist:.3g} from node {k} of beam {body.name!r}")
    return ("; " + "; ".join(parts)) if parts else ""


def check_initial(system, *, positions: bool = True, velocities: bool = True) -> None:
    """The initial configuration must satisfy every constraint row (to 1e-9 of model size),
    and the initial velocities the velocity-level rows."""
    if system.n_con == 0:
        return
    phi, phid = system.constraint_violation(system.q0, system.v0, 0.0)
    tol = 1e-9 * system.length_scale
    bad = np.flatnonzero(np.abs(np.real(phi)) > tol) if positions else np.zeros(0, int)
    if bad.size:
        i = int(bad[np.argmax(np.abs(np.real(phi[bad])))])
        joint = system.con_joint[i]
        raise ModelError(
            f"initial configuration violates constraint {system.con_names[i]!r} of joint "
            f"{joint!r} by {abs(np.real(phi[i])):.6g} (tolerance {tol:.3g} = 1e-9 of the model "
            f"size){_joint_hint(system, joint)}; place joints exactly at beam nodes and at "
            "coinciding points of the bodies they connect"
        )
    if not velocities:
        return
    vscale = max(float(np.max(np.abs(np.real(system.v0)))), 1e-300)
    badv = np.flatnonzero(np.abs(np.real(phid)) > 1e-9 * vscale * max(1.0, system.length_scale))
    if badv.size:
        i = int(badv[np.argmax(np.abs(np.real(phid[badv])))])
        raise ModelError(
            f"initial velocities violate constraint {system.con_names[i]!r} of joint "
            f"{system.con_joint[i]!r} at velocity level by {abs(np.real(phid[i])):.6g}; give "
            "initial velocities consistent with the joints, or none at all (then the velocities "
            "of least kinetic energy that move the drives at their initial speed are computed)"
        )


# relative singular-value threshold of the rank test. The scaled Jacobian has O(1) entries built
# from cos/sin of the initial angles, so an exactly dependent set of rows shows singular values
# of round-off size (~1e-16); a mechanism whose constraint Jacobian is conditioned worse than
# 1e10 cannot be solved to the Newton tolerance either, so it is reported as well.
RANK_RTOL = 1e-10


def constraint_rank(system, q=None):
    """Numerical rank of the constraint Jacobian and the rows that are linearly dependent.

    Parameters
    ----------
    system : System
    q : (n_dof,), optional
        Configuration (default: the initial one, ``system.q0``).

    Returns
    -------
    rank : int
        Numerical rank of ``J`` (n_con, n_dof).
    dependent : (n_con,) float
        Participation of every row in the null space of ``J^T``: the norm of the row's
        components over an orthonormal basis of that null space, in [0, 1]. Rows with a value
        above ~1e-6 belong to a redundant or conflicting set; 0 for all rows when ``J`` has full
        row rank.
    sigma : (min(n_rows, n_used),) float
        Singular values, largest first, of the scaled Jacobian with the rows joining the
        floating frames of beams eliminated (below; the scaled Jacobian itself for models
        without such rows).

    Notes
    -----
    ``J`` mixes lengths and angles: translation rows have entries 1 in ``R`` and ``u, v`` and
    lengths (a lever arm) in ``theta``; rotation rows have entries 1 in ``theta`` and ``phi``.
    The test uses ``D_r J D_c`` with ``D_c = 1/L`` on rotational columns and ``D_r = L`` on
    rotation rows (``L = system.length_scale``), so every entry is O(1) whatever the units, and
    counts singular values above ``RANK_RTOL`` times the largest (Golub & Van Loan, *Matrix
    Computations*, sec. 5.4.1, numerical rank by the SVD). Only the real part is used (a
    complex-step perturbation does not change the topology). The left singular vectors of the
    zero singular values span the null space of ``J^T``: the combinations of rows that repeat
    (or, with a different right-hand side, contradict) each other.

    The three rows joining frame ``f`` of a beam to frame ``f - 1`` have the block
    ``-[[1, 0, 0], [a, 1, 0], [b, 0, 1]]`` (rows ``r, x, y``, columns ``theta, R_x, R_y``;
    ``a, b``: a lever arm) in frame ``f``'s reference coordinates and entries in frame
    ``f - 1``'s only otherwise, so these rows and columns form a square lower triangular matrix
    ``B`` with ±1 on its diagonal. Eliminating them (Gaussian elimination, which keeps the
    rank; a triangular solve with ``B^T``) leaves
    ``S = J_uo - J_uc B^-1 J_fo`` over the other rows ``u`` and columns ``o``, and ``rank J =
    n_f + rank S``; the dependent rows are those of ``S``. The SVD is then that of ``S``, with
    as many rows as the model has joints besides the frame joints: a beam with a frame per
    element costs no more than one with a single frame (a dense SVD of ``J`` grows with the
    cube of the number of frames).
    """
    n_con = system.n_con
    if n_con == 0:
        return 0, np.zeros(0), np.zeros(0)
    S, rows, n_f = _reduced_jacobian(system, q)
    if S.size == 0:  # no rows besides the frame joints, or only zero rows
        dep = np.zeros(n_con)
        dep[rows] = 1.0
        return n_f, dep, np.zeros(0)
    U, sigma, _ = np.linalg.svd(S, full_matrices=True)
    rank = _rank(sigma)
    null = U[:, rank:]
    dep = np.zeros(n_con)
    dep[rows] = np.sqrt(np.sum(null * null, axis=1))
    return n_f + rank, dep, sigma


def _rank(sigma: np.ndarray) -> int:
    """Singular values above ``RANK_RTOL`` of the largest (:func:`constraint_rank`)."""
    return int(np.sum(sigma > RANK_RTOL * sigma[0])) if sigma.size and sigma[0] > 0 else 0


def _scaled_jacobian(system, q=None):
    """``D_r J D_c`` at ``q`` (default ``q0``), a SciPy CSR matrix (:func:`constraint_rank`)."""
    q = np.real(system.q0 if q is None else np.asarray(q))
    J = system.constraint_matrix(q.astype(float), sparse=True)
    J = sp.csr_matrix((np.real(J.data), J.indices, J.indptr), shape=J.shape)
    L = system.length_scale
    rot = np.zeros(system.n_dof, dtype=bool)
    for info in system.bodies.values():
        rot[info.ref[2]] = True
        if info.frame_ref is not None:
            rot[info.frame_ref[:, 2]] = True
        if info.elements is not None:  # every frame's nodal rotations
            nd = system.arrays.elements.dofs[info.elements][:, [2, 5]].ravel()
            rot[nd[nd >= 0]] = True
    col = np.where(rot, 1.0 / L, 1.0)
    angle = np.zeros(system.n_con, dtype=bool)  # the rows measuring angles (the kinds say)
    rows = system.arrays.rows
    angle[rows.con] = ANGLE_LIKE[rows.kind]
    row = np.where(angle, L, 1.0)
    return sp.diags(row) @ J @ sp.diags(col)


def _frame_joints(system) -> tuple[np.ndarray, np.ndarray]:
    """The rows joining neighbouring frames of the beams and the reference coordinates of the
    frame each joint starts, in matching order: per joint its r, x, y rows against theta,
    R_x, R_y of its frame, which makes their block lower triangular (:func:`constraint_rank`,
    Notes)."""
    rows_of: dict[str, list[int]] = {}
    for i, joint in enumerate(system.con_joint):
        rows_of.setdefault(joint, []).append(i)
    rows, cols = [], []
    for name, info in system.bodies.items():
        if info.frame_ref is None:
            continue
        for f in range(1, info.frame_ref.shape[0]):
            r = rows_of.get(f"{name}.frame{f}", [])
            if len(r) == 3:  # built as x, y, r
                rows += [r[2], r[0], r[1]]
                cols += [info.frame_ref[f][2], info.frame_ref[f][0], info.frame_ref[f][1]]
    return np.array(rows, dtype=np.int64), np.array(cols, dtype=np.int64)


def _eliminate_frames(system, q=None) -> tuple:
    """``(S, rows, cols, n_f)``: the scaled Jacobian with its ``n_f`` frame-joint rows
    eliminated against the frames' reference coordinates (:func:`constraint_rank`, Notes), a
    dense ``S`` over the other ``rows`` and ``cols``. Without frame joints, or should their
    block not be invertible, ``S`` is the whole scaled Jacobian."""
    Js = _scaled_jacobian(system, q)
    F, C = _frame_joints(system)
    n_con, n_dof = Js.shape
    if F.size:
        U, O = np.setdiff1d(np.arange(n_con), F), np.setdiff1d(np.arange(n_dof), C)
        JF, JU = Js[F], Js[U]
        B = JF[:, C].tocsr()
        # lower triangular with a diagonal of +-1, as built; else the whole Jacobian below
        if sp.triu(B, 1).nnz == 0 and np.all(np.abs(B.diagonal()) > 0.5):
            # B^T Y^T = J_uc^T: a triangular solve, no factorization
            Yt = (spla.spsolve_triangular(B.T.tocsr(), JU[:, C].T.toarray(), lower=False)
                  if U.size else np.zeros((C.size, 0)))
            S = JU[:, O].toarray() - (JF[:, O].T @ Yt).T
            if np.all(np.isfinite(S)):
                return S, U, O, int(F.size)
    return Js.toarray(), np.arange(n_con), np.arange(n_dof), 0


def _reduced_jacobian(system, q=None) -> tuple[np.ndarray, np.ndarray, int]:
    """``(S, rows, n_f)`` of :func:`_eliminate_frames`, ``S`` over its nonzero columns."""
    S, rows, _, n_f = _eliminate_frames(system, q)
    return S[:, np.flatnonzero(np.any(S != 0.0, axis=0))], rows, n_f


def check_rank(system) -> None:
    """Redundant or conflicting constraints: a rank-deficient Jacobian at ``q0``.

    A singular constraint Jacobian makes the saddle-point matrix singular (the multipliers of
    the dependent rows are not determined), whether the rows repeat each other (a Fix and a
    Drive on the same rotation, two revolutes at one point, a closed loop that is over-
    constrained in the plane) or the mechanism starts at a dead point.
    """
    n_con = system.n_con
    if n_con == 0:
        return
    # the common case, full row rank, from the singular values alone (a third of the cost of
    # the singular vectors); the vectors, which name the dependent rows, only when it is not
    S, rows, n_f = _reduced_jacobian(system)
    sigma = np.linalg.svd(S, compute_uv=False) if S.size else np.zeros(0)
    if S.shape[1] >= rows.size and n_f + _rank(sigma) == n_con:
        return
    rank, dep, _ = constraint_rank(system)
    if rank == n_con:
        return
    rows = np.flatnonzero(dep > 1e-6)
    rows = rows[np.argsort(-dep[rows], kind="stable")]
    names = [system.con_names[i] for i in rows]
    joints = list(dict.fromkeys(system.con_joint[i] for i in rows))
    shown = ", ".join(repr(n) for n in names[:12]) + (", ..." if len(names) > 12 else "")
    raise ModelError(
        f"model {system.model.name!r}: redundant or conflicting constraints at the initial "
        f"configuration: the constraint Jacobian has rank {rank} for {n_con} rows, so "
        f"{n_con - rank} row(s) repeat the others. Linearly dependent rows: {shown} (joints "
        f"{', '.join(repr(j) for j in joints)}). Remove the extra constraint (for example a Fix "
        "'r' and a Drive on the same rotation, two joints at the same point, a fix with more "
        "letters than needed), or move the mechanism out of a dead-point (singular) initial "
        "position."
    )



def check_units(system, t_end: float | None = None) -> list[str]:
    """Plausibility of a model's units (:func:`morphlab.model.units.plausibility`: its
    materials, gravity, rigid-body masses and angles), run by ``simulate`` and ``static``
    before they start: a :class:`~morphlab.errors.UnitsWarning` at the user's line for each
    finding, or a :class:`ModelError` where the model declares its units and a value lies far
    outside them. Returns the messages."""
    found = _units.plausibility(system.model, t_end, system.length_scale)
    for text in found:
        warn(UnitsWarning(text))
    return found
