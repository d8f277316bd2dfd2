"""How the mechanism of :mod:`morphlab.morphing` was designed (and how to redo it).

The design runs backwards from the target shape. :func:`fit_link_forces` finds the two forces
at the attachment nodes C and E whose static equilibrium of the skin alone best reproduces the
target: on the accurate skin (the study's, one chord frame per element) by Gauss–Newton on its
geometrically nonlinear statics; on the paper's single-frame skin, which with its frame held
by the clamp is exactly linear (:func:`skin_compliance`), by one linear least-squares solve.
:func:`inverse_mechanism` builds the bell crank whose static equilibrium at ``M_t`` is the
fitted shape (the links are two-force members along the fitted forces; the crank's moment
balance and the links' lengths place A, B and D), :func:`torque_angle_curve` checks that a
growing torque reaches it without snapping through, and :func:`design_report` scans candidates
and reports the margins a choice is made on. The chosen design and the reasons for it are in
:mod:`morphlab.morphing.leading_edge` ("Mechanism"); its numbers are the constants of
:mod:`morphlab.morphing.geometry`.

The statics on the paper's skin run without the kinematic accuracy check
(``kinematic_tol=None``): there the single linear frame is, on purpose, the formulation being
fitted or checked, and its kinematic error is what the study reports beside the accurate skin,
not a fault of the solve. On the accurate skin the check stays on.
"""

from __future__ import annotations

import numpy as np

from ..errors import SolverError
from ..model import Model
from ..model.profiles import Ramp
from ..solve.statics import static
from .leading_edge import (
    C_NODE,
    CRANK_SENSE,
    DEFAULTS,
    DROOP_MM,
    E_AL,
    E_NODE,
    N_ELEMENTS,
    RHO_AL,
    SPAN_MM,
    _assemble,
    _check_elements,
    _nodes,
    _skin_frames,
    mechanism_clearance,
)


# ------------------------------------------------------------------------------------- design
def _skin_only(nodes, t_w, E, skin: str = "paper") -> Model:
    """The skin alone, F clamped and G sliding, with the floating frames of ``skin``."""
    m = Model(name="skin")
    beam = m.add_beam(nodes, E=E, rho=RHO_AL, thickness=t_w, width=SPAN_MM,
                      **_skin_frames(skin), name="skin")
    m.add_fix(beam, at=nodes[0], dofs="xyr", name="F")
    m.add_fix(beam, at=nodes[-1], dofs="yr", name="G")
    return m


def skin_compliance(nodes_index=None, *, t_w: float = 2.0, E: float = E_AL,
                    n_elements: int = N_ELEMENTS):
    """Linear response of the paper's single-frame skin alone (F clamped, G sliding) to unit
    nodal forces.

    Parameters
    ----------
    nodes_index : sequence of int, optional
        Skin nodes that carry a force (default: all).
    t_w, E : float
        Wall thickness [mm] and Young's modulus [MPa].
    n_elements : int
        Skin elements.

    Returns
    -------
    G : ndarray, shape (n_nodes, 2, n_loaded, 2)
        ``G[k, :, j, c]``: displacement of node k [mm] per newton of force in direction c
        (0: x, 1: y) at loaded node j.
    S : ndarray, shape (n_elements, 2, 2, n_loaded, 2)
        Stress [MPa] per newton, layout of :meth:`morphlab.Result.stress`.

    Notes
    -----
    One :func:`morphlab.static` solve per unit load. With F clamped the single frame does not
    move, so linear FFRF is exactly linear here and superposition holds. It is also the
    tangent compliance of every skin of :data:`SKINS` in the undeformed state.
    """
    X = _nodes(_check_elements(n_elements), DROOP_MM)[0]
    idx = range(X.shape[0]) if nodes_index is None else list(nodes_index)
    G = np.zeros((X.shape[0], 2, len(idx), 2))
    S = np.zeros((n_elements, 2, 2, len(idx), 2))
    for j, node in enumerate(idx):
        for c in range(2):
            m = _skin_only(X, t_w, E)
            m.add_force("skin", at=X[node], force=(1.0 - c, float(c)), name="unit")
            r = static(m, t=1.0)
            G[:, :, j, c] = r.node_positions("skin", -1) - X
            S[..., j, c] = r.stress("skin")[-1]
    return G, S


def _fit_summary(c_node, e_node, f, nodes, sig, skin, iterations) -> dict:
    T = _nodes(N_ELEMENTS, DROOP_MM)[1]
    e = np.sqrt(np.sum((nodes - T) ** 2, axis=1))
    return {"c_node": c_node, "e_node": e_node, "skin": skin, "force_C": f[:2],
            "force_E": f[2:], "nodes": nodes, "rms": float(np.sqrt(np.mean(e * e))),
            "max": float(e.max()), "max_stress": float(np.max(np.abs(sig))),
            "iterations": iterations}


def fit_link_forces(c_node: int = C_NODE, e_node: int = E_NODE, *, t_w: float = 2.0,
                    E: float = E_AL, ridge: float = 1e-8, skin: str = "accurate",
                    tol: float = 1e-7, max_iter: int = 30) -> dict:
    """Two nodal forces (at C and E) whose static response best matches the target shape.

    Minimises ``sum_k |x_k(f) - T_k|² + ridge |f|²`` over the four force components ``f``
    [N], ``x_k(f)`` being the skin's node k under the forces (ridge [mm²/N²] keeps away from
    solutions that stretch the skin axially with forces of hundreds of kN, which no torque of
    10 N·m could supply).

    * ``skin="paper"`` (the linear design): the single-frame skin is exactly linear,
      ``x = X + G f`` (:func:`skin_compliance`), so this is one linear least-squares solve.
    * ``skin="accurate"`` (the nonlinear design): Gauss–Newton on the geometrically
      nonlinear statics of the skin with one chord frame per element, started from the
      linear fit; each iteration solves the statics under ``f`` (from the previous
      equilibrium) and its exact Jacobian ``dx/df`` by four complex-step statics, and
      stops when the force update is below ``tol`` times the largest force.

    Returns
    -------
    dict
        ``force_C``, ``force_E`` (2,) [N] on the skin; ``nodes`` (31, 2) the skin's nodes
        under them [mm]; ``rms``, ``max`` shape errors [mm]; ``max_stress`` [MPa];
        ``skin``; ``iterations`` (Gauss–Newton steps, 0 for the linear fit).
    """
    _skin_frames(skin)
    X, T = _nodes(N_ELEMENTS, DROOP_MM)
    G, S = skin_compliance([c_node, e_node], t_w=t_w, E=E)
    cols = G.reshape(2 * X.shape[0], 4)
    lhs = np.vstack([cols, np.sqrt(ridge) * np.eye(4)])
    rhs = np.concatenate([(T - X).ravel(), np.zeros(4)])
    f = np.linalg.lstsq(lhs, rhs, rcond=None)[0]
    if skin == "paper":
        return _fit_summary(c_node, e_node, f, X + (cols @ f).reshape(-1, 2),
                            S.reshape(-1, 4) @ f, skin, 0)
    return _fit_nonlinear(c_node, e_node, f, t_w, E, ridge, skin, tol, max_iter)


def _loaded_skin(f, c_node: int, e_node: int, t_w, E, skin: str) -> Model:
    """The skin alone under the forces ``f`` at C and E, ramped in over 0 <= t <= 1."""
    X = _nodes(N_ELEMENTS, DROOP_MM)[0]
    m = _skin_only(X, t_w, E, skin)
    m.add_force("skin", at=X[c_node], force=(f[0], f[1]), profile=Ramp(0.0, 1.0), name="C")
    m.add_force("skin", at=X[e_node], force=(f[2], f[3]), profile=Ramp(0.0, 1.0), name="E")
    return m


def _kinematic_tol(skin: str) -> float | None:
    """The statics' kinematic check for the skin ``skin``: off for the paper's single frame,
    whose linear kinematics are the very formulation being fitted or checked (its error is
    reported by the study, not warned about here); the default for the accurate skin."""
    return None if skin == "paper" else 1e-4


def _fit_nonlinear(c_node, e_node, f, t_w, E, ridge, skin, tol, max_iter) -> dict:
    T = _nodes(N_ELEMENTS, DROOP_MM)[1]
    h = 1e-20  # complex step [N]: exact to round-off at any size
    kin = _kinematic_tol(skin)
    r = static(_loaded_skin(f, c_node, e_node, t_w, E, skin), t=1.0, steps=5, kinematic_tol=kin)
    for it in range(1, max_iter + 1):
        q = r.q[-1]
        J = np.zeros((T.size, 4))
        for j in range(4):
            fj = f.astype(complex)
            fj[j] += 1j * h
            rj = static(_loaded_skin(fj, c_node, e_node, t_w, E, skin), t=1.0,
                        q_start=q.astype(complex), kinematic_tol=kin)
            J[:, j] = np.imag(rj.node_positions("skin", -1)).ravel() / h
        res = np.concatenate([(r.node_positions("skin", -1) - T).ravel(), np.sqrt(ridge) * f])
        step = np.linalg.lstsq(np.vstack([J, np.sqrt(ridge) * np.eye(4)]), res, rcond=None)[0]
        f = f - step
        r = static(_loaded_skin(f, c_node, e_node, t_w, E, skin), t=1.0, q_start=q,
                   kinematic_tol=kin)
        if np.max(np.abs(step)) < tol * np.max(np.abs(f)):
            return _fit_summary(c_node, e_node, f, r.node_positions("skin", -1),
                                r.stress("skin")[-1], skin, it)
    raise SolverError(f"fit_link_forces: Gauss-Newton on the {skin!r} skin did not converge "
                      f"in {max_iter} iterations (C = node {c_node}, E = node {e_node})")


def _rot(a: float) -> np.ndarray:
    return np.array([[np.cos(a), -np.sin(a)], [np.sin(a), np.cos(a)]])


def inverse_mechanism(fit: dict, x_A: float, delta: float, M_t: float = DEFAULTS["M_t"]) -> dict:
    """Bell crank whose equilibrium at the torque ``M_t`` is the fitted skin shape.

    Parameters
    ----------
    fit : dict
        Output of :func:`fit_link_forces`.
    x_A : float
        x of the pivot A [mm]; y_A follows from the crank's moment balance.
    delta : float
        Crank rotation from the undeformed to the morphed state [rad], counter-clockwise
        positive (a clockwise crank: negative ``delta`` and ``M_t``).
    M_t : float
        Torque on the crank [N·mm], counter-clockwise positive.

    Returns
    -------
    dict
        ``A``, ``B``, ``D`` (2,) undeformed positions [mm]; ``L_C``, ``L_E`` link lengths [mm]
        (negative: no mechanism with links inside the skin for this ``x_A``, ``delta``).

    Notes
    -----
    In the morphed state the two-force links lie along the skin forces ``F_C``, ``F_E``; the
    crank's moment balance about A, ``(C' - A) x F_C + (E' - A) x F_E = M_t`` (primes: morphed
    positions; the links' own lengths drop out), is a line for A. A link from the crank point
    P to skin node Q with morphed direction ``e`` (pointing out of the skin) has
    ``P' = Q' - L e``; rotating the crank back, ``P = A + R(-delta)(P' - A)``, and asking for
    ``|Q - P| = L`` gives ``|g|² + 2 L g.m = 0`` with ``g = Q - A - R(-delta)(Q' - A)``,
    ``m = R(-delta) e``: one linear equation for L.
    """
    X = _nodes(N_ELEMENTS, DROOP_MM)[0]
    Xf = fit["nodes"]
    c, e = fit["c_node"], fit["e_node"]
    FC, FE = fit["force_C"], fit["force_E"]
    Ft = FC + FE
    kappa = (Xf[c, 0] * FC[1] - Xf[c, 1] * FC[0] + Xf[e, 0] * FE[1] - Xf[e, 1] * FE[0]) - M_t
    A = np.array([x_A, (x_A * Ft[1] - kappa) / Ft[0]])
    R = _rot(-delta)
    out = {"A": A}
    for name, node, F in (("B", c, FC), ("D", e, FE)):
        t = X[node + 1] - X[node - 1]
        outward = np.array([t[1], -t[0]])
        e_dir = F / np.sqrt(F @ F)
        if e_dir @ outward < 0:
            e_dir = -e_dir
        g = X[node] - A - R @ (Xf[node] - A)
        m_dir = R @ e_dir
        L = -(g @ g) / (2.0 * (g @ m_dir))
        out[name] = X[node] - g - L * m_dir
        out["L_" + ("C" if name == "B" else "E")] = float(L)
    return out


def torque_angle_curve(p: dict | None = None, delta_max: float = 0.8, steps: int = 32, *,
                       nodes: tuple[int, int] = (C_NODE, E_NODE), skin: str = "accurate",
                       sense: int = CRANK_SENSE):
    """Static torque needed to hold the crank at each angle up to ``delta_max`` [rad].

    Returns ``(delta (steps + 1,), M (steps + 1,) [N·mm], result)``; the crank angle is
    prescribed by a drive and ``M`` is minus its multiplier. The mechanism follows a growing
    torque without snapping only where ``M`` rises. ``nodes``: C and E (30-element mesh);
    ``skin``: the skin's frames (:data:`SKINS`); ``sense``: the crank turns by ``sense``
    times the angle and ``M`` is the torque in that sense.
    """
    r = static(_assemble(p, N_ELEMENTS, drive=True, nodes=nodes, skin=skin, sense=sense),
               t=delta_max, steps=steps, kinematic_tol=_kinematic_tol(skin))
    i = r.system.con_names.index("drive.r")
    return r.t, -sense * np.real(r.lam[:, i]), r


def _path_exponents(delta, M, res, M_t: float) -> dict:
    """How the shape error and the largest stress change with the torque where a torque path
    passes ``M_t`` (central differences in the crank angle): ``stress_exponent`` d ln(sigma_max)
    / d ln(M) (above 1: the stress grows faster than the torque) and ``error_slope``
    M d(e_rms)/dM [mm] (positive: more torque overshoots the target)."""
    T = _nodes(N_ELEMENTS, DROOP_MM)[1]
    k = int(np.argmin(np.abs(M[1:-1] - M_t))) + 1
    pos = np.real(res.node_positions("skin"))[k - 1:k + 2]
    e = np.sqrt(np.mean(np.sum((pos - T) ** 2, axis=2), axis=1))
    sig = np.max(np.abs(np.real(res.stress("skin"))[k - 1:k + 2]), axis=(1, 2, 3))
    dM = (M[k + 1] - M[k - 1]) / (delta[k + 1] - delta[k - 1])
    de = (e[2] - e[0]) / (delta[k + 1] - delta[k - 1])
    ds = (sig[2] - sig[0]) / (delta[k + 1] - delta[k - 1])
    return {"stress_exponent": float(ds / dM * M[k] / sig[1]),
            "error_slope": float(de / dM * M[k]), "path_rms": float(e[1]),
            "path_stress": float(sig[1])}


def design_report(pairs=((C_NODE, E_NODE),), x_A_values=(104.5,),
                  deltas=(0.55, 0.575, 0.6, 0.625), *, skin: str = "accurate",
                  overshoot: float = 0.0,
                  sense: int = CRANK_SENSE,
                  min_joint_clearance: float = 5.0, min_arm: float = 8.0,
                  min_link: float = 20.0, min_slope: float = 0.4, select="stress_exponent",
                  verbose: bool = False) -> dict:
    """Reproduce the mechanism design (:mod:`morphlab.morphing.leading_edge`, "Mechanism").

    With its defaults it scans the crank rotations around the study's design at its pivot
    ``x_A`` and selects, among the accepted ones, the study's: the largest stress exponent.

    Parameters
    ----------
    pairs : sequence of (int, int)
        (C node, E node) pairs.
    x_A_values : sequence of float
        Pivot x positions [mm].
    deltas : sequence of float
        Crank rotations [rad] from the undeformed to the fitted state.
    skin : {"paper", "accurate"}
        The skin the forces are fitted on and the torque path is checked on: the linear
        design on the paper's single frame, or the nonlinear one on the accurate skin.
    sense : {1, -1}
        The crank turns counter-clockwise (1) or clockwise (-1) under the torque.
    overshoot : float
        The nominal torque ``M_t`` exceeds the torque that holds the fitted shape by this
        fraction: the crank is designed for ``M_t / (1 + overshoot)``, so at ``M_t`` it has
        turned a little past the best shape.
    min_joint_clearance, min_arm, min_link : float
        Acceptance limits [mm]: A, B, D inside the skin by this much at all times; crank arms
        |AB|, |AD| and links at least this long.
    min_slope : float
        Acceptance limit on the weakest slope of the torque path up to the design angle,
        relative to its mean slope ``M_t / delta`` (margin against snap-through).
    select : str or callable
        Which accepted candidate is ``"best"``: the largest value of this candidate key
        (``"stress_exponent"``: the stress grows fastest with the torque, the study's
        choice; ``"overload"``: the shape moves least under an overload) or of
        ``select(candidate)``.
    verbose : bool
        Print every accepted candidate.

    Returns
    -------
    dict
        ``"best"`` or None; ``"candidates"``: all accepted ones. A candidate holds the
        rounded design ``p`` (0.01 mm), the fit, link lengths, arms, clearances, slopes,
        ``overload`` (the torque, in units of ``M_t``, that turns the crank 30 % beyond its
        design angle) and the exponents of the path at ``M_t`` (:func:`_path_exponents`).
    """
    accepted = []
    M_t = DEFAULTS["M_t"]
    M_design = M_t / (1.0 + overshoot)
    n_path = 39  # 30 steps up to delta, 9 beyond (to 1.3 delta)
    for c, e in pairs:
        fit = fit_link_forces(c, e, skin=skin)
        for x_A in x_A_values:
            for delta in deltas:
                cand = _candidate(fit, x_A, delta, M_design, skin, sense, n_path, min_link,
                                  min_arm, min_slope, min_joint_clearance)
                if cand is None:
                    continue
                accepted.append(cand)
                if verbose:
                    print({k: (round(v, 3) if isinstance(v, float) else v)
                           for k, v in cand.items() if k != "p"})
    key = select if callable(select) else (lambda cand: cand[select])
    best = max(accepted, key=key) if accepted else None
    return {"best": best, "candidates": accepted}


def _candidate(fit, x_A, delta, M_design, skin, sense, n_path, min_link, min_arm, min_slope,
               min_joint_clearance):
    c, e = fit["c_node"], fit["e_node"]
    mech = inverse_mechanism(fit, x_A, sense * delta, sense * M_design)
    A, B, D = mech["A"], mech["B"], mech["D"]
    arm_B = float(np.sqrt(np.sum((B - A) ** 2)))
    arm_D = float(np.sqrt(np.sum((D - A) ** 2)))
    if min(mech["L_C"], mech["L_E"]) < min_link or min(arm_B, arm_D) < min_arm:
        return None
    p = {"x_A": round(float(A[0]), 2), "y_A": round(float(A[1]), 2),
         "x_B": round(float(B[0]), 2), "y_B": round(float(B[1]), 2),
         "x_D": round(float(D[0]), 2), "y_D": round(float(D[1]), 2)}
    try:
        delta_k, M, res = torque_angle_curve(p, 1.3 * delta, n_path, nodes=(c, e), skin=skin,
                                             sense=sense)
    except SolverError:  # no static path: rejected
        return None
    slope = np.diff(M[:31]) / np.diff(delta_k[:31]) / (M_design / delta)
    if slope.min() < min_slope or np.any(np.diff(M) <= 0.0):
        return None
    clear = mechanism_clearance(res, p, nodes=(c, e))
    if clear["joints"] < min_joint_clearance or clear["crossings"] or clear["links"] <= 0.0:
        return None
    return {"c_node": c, "e_node": e, "x_A": float(x_A), "delta": float(delta),
            "sense": sense, "p": p,
            "fit_rms": fit["rms"], "fit_max": fit["max"], "fit_stress": fit["max_stress"],
            "L_C": mech["L_C"], "L_E": mech["L_E"], "arm_B": arm_B, "arm_D": arm_D,
            "min_slope": float(slope.min()), "torque_at_delta": float(M[30]),
            "overload": float(M[-1] / M_design),
            **_path_exponents(delta_k, M, res, DEFAULTS["M_t"]),
            **{f"clear_{k}": v for k, v in clear.items()}}
