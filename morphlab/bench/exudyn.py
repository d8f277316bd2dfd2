"""Benchmark case ``exudyn``: the same flexible pendulum in morphlab and in Exudyn.

Exudyn (PyPI ``exudyn``, J. Gerstmayr, Univ. Innsbruck) is an open-source flexible multibody
code with a C++ core. This module models one mechanism in both codes and times them in the
same process:

* **Mechanism**: an aluminium strip 2 mm x 10 mm x 500 mm (``E = 70000`` MPa,
  ``rho = 2.7e-9`` t/mm³) pinned to the ground at one end and released from the horizontal
  under gravity, stiffness-proportional damping ``beta_d = 1e-3`` s in both codes; the same
  number of beam elements and the same time steps (0.2 s, 1000 steps), generalized-alpha with
  ``rho_inf = 0.8`` in both (Exudyn's verbose output gives ``alpha_m = 1/3``,
  ``alpha_f = 4/9``, ``beta = 0.3086``, ``gamma = 0.6111`` and its solver carries the
  algorithmic acceleration of Arnold & Brüls 2007, as morphlab's default
  ``scheme="arnold-bruls"``; Exudyn enforces the constraints at index 3, morphlab with its
  stabilized form).
* **Elements**: morphlab uses linear FFRF Euler–Bernoulli elements (body frame at the pinned
  node); Exudyn's closest planar element is ``ObjectANCFCable2D`` (absolute nodal coordinates
  with nodes ``NodePoint2DSlope1``: position and slope vector, cubic Hermite shape functions,
  Euler–Bernoulli without shear, line mass ``rho A`` without rotary inertia, like morphlab's
  element) with a nonlinear strain measure. ``ObjectBeamGeometricallyExact2D`` would add shear
  deformation and rotary inertia, so it is further from morphlab's beam. The pin is two
  ``CoordinateConstraint`` rows on the first node's position; gravity is a
  ``LoadMassProportional`` per element; damping is ``bendingDamping = beta_d EI`` and
  ``axialDamping = beta_d EA`` (the ANCF counterpart of ``D = beta_d K``).
* **Response**: the final tip y-coordinate [mm]. Its gradient with respect to the strip
  thickness ``t`` [mm] and Young's modulus ``E`` [MPa] by morphlab's direct differentiation
  (one run) and by Exudyn's ``exudyn.processing.ComputeSensitivities`` (forward differences,
  n_x + 1 runs, the Exudyn system rebuilt per design, serial).

Why the damping: undamped, the released strip vibrates ~18 periods of its first bending mode
(~91 Hz) in 0.2 s; the linear FFRF element has no geometric (centrifugal / axial-load)
stiffening, so its frequency differs slightly from the nonlinear ANCF element, the phase of
that vibration drifts, and the elastic deflection at the final time differed by ~25 % between
the codes (tip position still within 0.03 mm of 500 mm). Damping the vibration (first mode
~30 % of critical) leaves the quasi-static deflection, on which the codes agree to ~3 %.

Checks reported beside the timings (each independent of the other code):

* a rigid pendulum (``theta'' = 3 g cos(theta) / (2 L)``, scipy ``solve_ivp`` at 1e-12): the
  rigid motion both codes should reproduce up to the elastic deflection;
* a scaling law of the gradients: mass and gravity load scale with ``t``, bending stiffness with
  ``E t³``, so the bending response depends on ``E t²`` only and
  ``t dy/dt = 2 E dy/dE`` (exact up to the axial compliance, which depends on ``E`` alone).

Exudyn's Newton settings: its default relative tolerance (1e-8) stalls on this model (the
residual of the index-3 constraint rows, scaled by ``1/(beta h²)``, has a round-off floor
above it), so the absolute tolerance is 1e-7 (residual norm, SI units), well below the
residual of the first iteration (~1e-5). Timed with Exudyn's default modified Newton (its
fastest setting, Jacobian reused across steps) and with full Newton (one Jacobian per
iteration, like morphlab). Exudyn also ships ``exudynCPPfast`` (no range checks, selected
with ``sys.exudynFast = True`` before the first ``import exudyn``); the module loaded is
reported.
"""

from __future__ import annotations

import numpy as np

import morphlab as ml

from ..solve.settings import Settings
from ..studies.timing import timed

# morphlab units: mm, t, s, N, MPa
LENGTH = 500.0  # [mm]
WIDTH = 10.0  # [mm]
THICKNESS = 2.0  # [mm] (in-plane)
E_MOD = 70000.0  # [MPa]
RHO = 2.7e-9  # [t/mm^3]
GRAVITY = 9810.0  # [mm/s^2]
DAMPING = 1e-3  # stiffness-proportional damping beta_d [s]
T_END = 0.2  # [s]
N_STEPS = 1000
RHO_INF = 0.8
FD_STEP = 1e-4  # relative forward-difference step (truncation ~4e-4 relative, see notes)
EXUDYN_REL_TOL = 1e-8
EXUDYN_ABS_TOL = 1e-7
P0 = {"t": THICKNESS, "E": E_MOD}

NOTES = (
    "Same pinned aluminium strip (2 x 10 x 500 mm, released horizontally under gravity, "
    "stiffness-proportional damping 1e-3 s) in both codes, same elements and steps, "
    "generalized-alpha rho_inf=0.8 (Arnold-Bruls coefficients in both). morphlab: linear FFRF "
    "Euler-Bernoulli elements (body frame at the pin). Exudyn: ObjectANCFCable2D (ANCF, "
    "position + slope nodes, cubic Hermite, no shear, no rotary inertia, nonlinear strain "
    "measure), pin by two CoordinateConstraints (index 3). The linear FFRF element has no "
    "geometric stiffening and no foreshortening, so the elastic deflection differs by a few "
    "% (the rigid motion, ~300 mm, agrees to ~0.01 mm); the gradients of the final tip y "
    "depend only on the elastic part, so they differ by the same few %. Each code's "
    "gradients satisfy the scaling law t dy/dt = 2 E dy/dE (bending response depends on "
    "E t^2). Exudyn timed with its default modified Newton (Jacobian reused) and with full "
    "Newton; absolute Newton tolerance 1e-7 because the default relative 1e-8 stalls at the "
    "round-off floor of the index-3 constraint rows. Exudyn finite differences: "
    "exudyn.processing.ComputeSensitivities, forward, relative step 1e-4, serial, system "
    "rebuilt per design. Times are wall seconds in one process, median of repeats after a "
    "warm-up; per step = run time / steps."
)


def _per_step(s: dict, n_steps: int) -> dict:
    return {"median": s["median"] / n_steps, "min": s["min"] / n_steps,
            "max": s["max"] / n_steps, "runs": s["runs"]}


# ------------------------------------------------------------------------------ morphlab side
def build(p: dict, n_elements: int = 8) -> ml.Model:
    """The pendulum as a morphlab model (complex-safe in ``p``).

    Parameters
    ----------
    p : dict
        ``"t"``: in-plane thickness [mm], ``"E"``: Young's modulus [MPa].
    n_elements : int
        Number of beam elements.
    """
    m = ml.Model(gravity=(0.0, -GRAVITY), name="strip pendulum")
    x = np.linspace(0.0, LENGTH, n_elements + 1)
    nodes = np.stack([x, np.zeros_like(x)], axis=1)
    # the formulation this case documents and times: one linear frame at the pinned node
    beam = m.add_beam(nodes, E=p["E"], rho=RHO, thickness=p["t"], width=WIDTH,
                      damping=DAMPING, frames=1, reference="first", name="strip")
    m.add_revolute(m.ground, beam, at=(0.0, 0.0), name="pin")
    return m


def tip_y(result):
    """Response: y-coordinate of the free end at the final time [mm] (complex-safe)."""
    return result.node_positions("strip", -1)[-1, 1]


def morphlab_tip(result) -> np.ndarray:
    """Final tip position (x, y) [mm] of a morphlab result."""
    return np.real(result.node_positions("strip", -1)[-1])


# ------------------------------------------------------------------------------- Exudyn side
def exudyn_system(p: dict, n_elements: int = 8):
    """The pendulum as an Exudyn system, in SI units (m, kg, s, N, Pa).

    Returns
    -------
    (SystemContainer, MainSystem, int)
        The container (keeps the system alive), the assembled system and the tip node index.
    """
    import exudyn as exu
    from exudyn.itemInterface import (
        CoordinateConstraint,
        LoadMassProportional,
        MarkerBodyMass,
        MarkerNodeCoordinate,
        NodePoint2DSlope1,
        NodePointGround,
        ObjectANCFCable2D,
    )

    length = LENGTH * 1e-3  # m
    t = float(p["t"]) * 1e-3  # m
    b = WIDTH * 1e-3  # m
    e_mod = float(p["E"]) * 1e6  # Pa
    rho = RHO * 1e12  # kg/m^3
    area, inertia = b * t, b * t**3 / 12.0
    le = length / n_elements

    sc = exu.SystemContainer()
    mbs = sc.AddSystem()
    nodes = [mbs.AddNode(NodePoint2DSlope1(referenceCoordinates=[i * le, 0.0, 1.0, 0.0]))
             for i in range(n_elements + 1)]
    for i in range(n_elements):
        obj = mbs.AddObject(ObjectANCFCable2D(
            nodeNumbers=[nodes[i], nodes[i + 1]], length=le, massPerLength=rho * area,
            bendingStiffness=e_mod * inertia, axialStiffness=e_mod * area,
            bendingDamping=DAMPING * e_mod * inertia, axialDamping=DAMPING * e_mod * area))
        marker = mbs.AddMarker(MarkerBodyMass(bodyNumber=obj))
        mbs.AddLoad(LoadMassProportional(markerNumber=marker,
                                         loadVector=[0.0, -GRAVITY * 1e-3, 0.0]))
    ground = mbs.AddNode(NodePointGround(referenceCoordinates=[0.0, 0.0, 0.0]))
    m_ground = mbs.AddMarker(MarkerNodeCoordinate(nodeNumber=ground, coordinate=0))
    for c in (0, 1):  # pin: x and y of the first node fixed, its slope free
        m_node = mbs.AddMarker(MarkerNodeCoordinate(nodeNumber=nodes[0], coordinate=c))
        mbs.AddObject(CoordinateConstraint(markerNumbers=[m_ground, m_node]))
    mbs.Assemble()
    return sc, mbs, nodes[-1]


def exudyn_settings(t_end: float = T_END, n_steps: int = N_STEPS,
                    modified_newton: bool = True):
    """Exudyn simulation settings: generalized-alpha, fixed steps, no output files."""
    import exudyn as exu

    s = exu.SimulationSettings()
    ti = s.timeIntegration
    ti.endTime = t_end
    ti.numberOfSteps = n_steps
    ti.adaptiveStep = False  # exactly n_steps steps (a failed Newton raises)
    ti.verboseMode = 0
    ti.generalizedAlpha.spectralRadius = RHO_INF
    ti.newton.useModifiedNewton = modified_newton
    ti.newton.relativeTolerance = EXUDYN_REL_TOL
    ti.newton.absoluteTolerance = EXUDYN_ABS_TOL
    s.solution.file.write = False
    s.solution.sensors.active = False
    return s


def exudyn_solve(mbs, settings) -> dict:
    """Solve and return the solver's counters (Newton iterations and Jacobian updates)."""
    if not mbs.SolveDynamic(settings):
        raise RuntimeError("Exudyn SolveDynamic failed")
    it = mbs.sys["dynamicSolver"].it
    return {"newton_iterations": int(it.newtonStepsCount),
            "jacobians": int(it.newtonJacobiCount)}


def exudyn_tip_position(mbs, tip_node) -> np.ndarray:
    """Current tip position (x, y) [mm]."""
    import exudyn as exu

    return 1e3 * np.asarray(mbs.GetNodeOutput(tip_node, exu.OutputVariableType.Position))[:2]


def exudyn_tip(p: dict, n_elements: int = 8, t_end: float = T_END, n_steps: int = N_STEPS,
               modified_newton: bool = True) -> np.ndarray:
    """Build, solve and return the final tip position (x, y) [mm]."""
    _sc, mbs, tip = exudyn_system(p, n_elements)
    exudyn_solve(mbs, exudyn_settings(t_end, n_steps, modified_newton))
    return exudyn_tip_position(mbs, tip)


def exudyn_gradient(p0: dict, n_elements: int = 8, t_end: float = T_END,
                    n_steps: int = N_STEPS, step: float = FD_STEP,
                    modified_newton: bool = True) -> tuple[float, dict]:
    """Forward-difference gradient of the final tip y by ``exudyn.processing``.

    Returns
    -------
    (float, dict)
        Tip y at ``p0`` [mm] and ``{name: dy/dp}`` in mm per unit of ``p`` (mm, MPa).
    """
    from exudyn.processing import ComputeSensitivities

    def response(p):
        q = {k: p[k] for k in p0}
        return [exudyn_tip(q, n_elements, t_end, n_steps, modified_newton)[1]]

    params = {k: (float(v), step, 0) for k, v in p0.items()}  # (value, rel. step, 0 = forward)
    _plist, ref, _values, sens = ComputeSensitivities(
        response, params, useMultiProcessing=False, showProgress=False)
    return float(np.ravel(ref)[0]), {k: float(sens[i][0]) for i, k in enumerate(p0)}


# ------------------------------------------------------------------------------- reference
def rigid_tip(t_end: float = T_END) -> np.ndarray:
    """Tip (x, y) [mm] of the rigid strip: ``theta'' = 3 g cos(theta) / (2 L)`` from rest at
    the horizontal (theta measured downwards), scipy ``solve_ivp`` with tolerances 1e-12."""
    from scipy.integrate import solve_ivp

    k = 1.5 * GRAVITY / LENGTH
    sol = solve_ivp(lambda _t, y: [y[1], k * np.cos(y[0])], (0.0, t_end), [0.0, 0.0],
                    method="DOP853", rtol=1e-12, atol=1e-12)
    th = sol.y[0, -1]
    return np.array([LENGTH * np.cos(th), -LENGTH * np.sin(th)])


def scaling_ratio(grad: dict, p: dict = P0) -> float:
    """``t dy/dt / (2 E dy/dE)``: 1 when the response depends on ``E t²`` only."""
    return grad["t"] * p["t"] / (2.0 * p["E"] * grad["E"])


# ------------------------------------------------------------------------------- the case
def _agreement(system, mbs, tip, settings: Settings, n_steps: int) -> tuple[dict, tuple]:
    """Final tip positions of both codes, of the rigid pendulum, and their differences; with
    Exudyn's Newton counts and tip of this first solve (to check that re-solves repeat it)."""
    res = ml.simulate(system, settings=settings)
    ex_counts = exudyn_solve(mbs, exudyn_settings(settings.t_end, n_steps, True))
    tip_ml, tip_ex = morphlab_tip(res), exudyn_tip_position(mbs, tip)
    tip_rigid = rigid_tip(settings.t_end)
    el_ml, el_ex = tip_ml - tip_rigid, tip_ex - tip_rigid
    agreement = {
        "tip_morphlab_mm": tip_ml.tolist(), "tip_exudyn_mm": tip_ex.tolist(),
        "tip_rigid_pendulum_mm": tip_rigid.tolist(),
        "tip_difference_mm": float(np.linalg.norm(tip_ml - tip_ex)),
        "tip_difference_over_length": float(np.linalg.norm(tip_ml - tip_ex) / LENGTH),
        "tip_difference_over_tip_travel": float(np.linalg.norm(tip_ml - tip_ex)
                                                / np.linalg.norm(tip_rigid
                                                                 - [LENGTH, 0.0])),
        "elastic_tip_offset_morphlab_mm": el_ml.tolist(),
        "elastic_tip_offset_exudyn_mm": el_ex.tolist(),
        "elastic_offset_relative_difference": float(np.linalg.norm(el_ml - el_ex)
                                                    / np.linalg.norm(el_ex)),
    }
    return agreement, (ex_counts, tip_ex)


def _primal_timings(system, mbs, tip, first: tuple, n_elements: int, settings: Settings,
                    n_steps: int, repeats: int) -> dict:
    """Run times of both codes, solve only and with the model built, full and modified
    Newton; ``first``: Exudyn's counts and tip of the first solve (:func:`_agreement`)."""
    t_end = settings.t_end
    t_ml, res = timed(lambda: ml.simulate(system, settings=settings), repeats)
    t_ml_b, _ = timed(lambda: ml.simulate(build(P0, n_elements), settings=settings),
                        repeats)
    # like for like with Exudyn's default: the factorization kept over iterations and steps
    t_ml_mod, res_mod = timed(lambda: ml.simulate(system, settings=settings, newton="modified"),
                              repeats)
    ex_mod = exudyn_settings(t_end, n_steps, True)
    ex_full = exudyn_settings(t_end, n_steps, False)
    t_ex_mod, c_mod = timed(lambda: exudyn_solve(mbs, ex_mod), repeats)
    tip_again = exudyn_tip_position(mbs, tip)
    t_ex_full, c_full = timed(lambda: exudyn_solve(mbs, ex_full), repeats)
    t_ex_b, _ = timed(lambda: exudyn_tip(P0, n_elements, t_end, n_steps, True), repeats)
    per = float(n_steps)
    primal = {
        "morphlab": {"run_s": t_ml, "per_step_s": _per_step(t_ml, n_steps),
                     "with_build_s": t_ml_b,
                     "newton_iterations_per_step": float(np.mean(res.newton_iterations[1:]))},
        "morphlab_modified_newton": {
            "run_s": t_ml_mod, "per_step_s": _per_step(t_ml_mod, n_steps),
            "factorizations_per_step": res_mod.n_factorizations / per},
        "exudyn_modified_newton": {
            "run_s": t_ex_mod, "per_step_s": _per_step(t_ex_mod, n_steps), "with_build_s": t_ex_b,
            "newton_iterations_per_step": c_mod["newton_iterations"] / per,
            "jacobians_per_step": c_mod["jacobians"] / per},
        "exudyn_full_newton": {
            "run_s": t_ex_full, "per_step_s": _per_step(t_ex_full, n_steps),
            "newton_iterations_per_step": c_full["newton_iterations"] / per,
            "jacobians_per_step": c_full["jacobians"] / per},
    }
    primal["ratios"] = {
        "morphlab_over_exudyn_modified_newton": t_ml["median"] / t_ex_mod["median"],
        "morphlab_over_exudyn_full_newton": t_ml["median"] / t_ex_full["median"],
        "morphlab_modified_over_exudyn_modified_newton": (t_ml_mod["median"]
                                                          / t_ex_mod["median"]),
    }
    # the timed re-solves of the same Exudyn system start again from the initial state
    ex_counts, tip_ex = first
    primal["exudyn_resolve_repeatable"] = bool(
        ex_counts == c_mod and np.array_equal(tip_again, tip_ex))
    return primal


def _sensitivities(n_elements: int, settings: Settings, n_steps: int, repeats: int,
                   primal: dict) -> dict:
    """Gradients of the final tip y to t and E: morphlab direct and forward differences,
    Exudyn forward differences; their agreement, the scaling law and the run times."""
    build_n = _Builder(n_elements)
    resp = {"tip_y": tip_y}
    t_dir, sens = timed(lambda: ml.sensitivities(build_n, P0, resp, method="direct",
                                                 settings=settings), repeats)
    t_fd_ml, sens_fd = timed(lambda: ml.sensitivities(
        build_n, P0, resp, method=ml.FiniteDifference("forward", FD_STEP), settings=settings),
        max(1, repeats // 2))
    t_fd_ex, (y_ex, grad_ex) = timed(
        lambda: exudyn_gradient(P0, n_elements, settings.t_end, n_steps),
        max(1, repeats // 2))
    g_dir = {k: float(v) for k, v in sens.gradients["tip_y"].items()}
    g_fd_ml = {k: float(v) for k, v in sens_fd.gradients["tip_y"].items()}
    return {
        "response": "final tip y [mm]", "variables": {"t": "thickness [mm]", "E": "E [MPa]"},
        "values_mm": {"morphlab": float(np.real(sens.values["tip_y"])), "exudyn": y_ex},
        "gradient": {"morphlab_direct": g_dir, "morphlab_forward_difference": g_fd_ml,
                     "exudyn_forward_difference": grad_ex},
        "relative_difference_exudyn_fd_vs_morphlab_direct": {
            k: abs(grad_ex[k] - g_dir[k]) / abs(g_dir[k]) for k in g_dir},
        "relative_difference_morphlab_fd_vs_direct": {
            k: abs(g_fd_ml[k] - g_dir[k]) / abs(g_dir[k]) for k in g_dir},
        "scaling_law_t_dydt_over_2E_dydE": {"morphlab_direct": scaling_ratio(g_dir),
                                            "exudyn_forward_difference":
                                                scaling_ratio(grad_ex)},
        "fd_relative_step": FD_STEP,
        "timing_s": {"morphlab_direct": t_dir, "morphlab_forward_difference": t_fd_ml,
                     "exudyn_forward_difference": t_fd_ex},
        "ratios": {
            "exudyn_fd_over_morphlab_direct": t_fd_ex["median"] / t_dir["median"],
            "morphlab_direct_over_morphlab_primal": (
                t_dir["median"] / primal["morphlab"]["with_build_s"]["median"]),
            "exudyn_fd_over_exudyn_primal": (
                t_fd_ex["median"] / primal["exudyn_modified_newton"]["with_build_s"]["median"]),
        },
    }


def compare(repeats: int, n_elements: int, t_end: float = T_END,
            n_steps: int = N_STEPS) -> dict:
    """Agreement, primal timings and sensitivities for one mesh, in this order (the timed
    Exudyn re-solves are checked against the first solve)."""
    dt = t_end / n_steps
    settings = Settings.of(None, t_end=t_end, dt=dt, rho_inf=RHO_INF)
    system = ml.compile_model(build(P0, n_elements))
    _sc, mbs, tip = exudyn_system(P0, n_elements)  # _sc owns mbs: kept alive to the end
    agreement, first = _agreement(system, mbs, tip, settings, n_steps)
    primal = _primal_timings(system, mbs, tip, first, n_elements, settings, n_steps, repeats)
    return {"n_elements": n_elements, "steps": n_steps, "t_end": t_end, "dt": dt,
            "agreement": agreement, "primal": primal,
            "sensitivities": _sensitivities(n_elements, settings, n_steps, repeats, primal)}


class _Builder:
    """``build`` with a fixed number of elements (a named callable for the sensitivities)."""

    def __init__(self, n_elements: int):
        self.n_elements = n_elements

    def __call__(self, p):
        return build(p, self.n_elements)


def run(repeats: int, quick: bool, *, elements=None, t_end: float = T_END,
        n_steps: int = N_STEPS) -> dict:
    """The ``exudyn`` benchmark case.

    Parameters
    ----------
    repeats : int
        Timed runs per figure (after one warm-up run); finite-difference figures use
        ``max(1, repeats // 2)``.
    quick : bool
        One mesh (8 elements) instead of 8 and 16.
    elements : sequence of int, optional
        Override the meshes.
    t_end, n_steps : float, int
        Time span [s] and number of steps (both codes).

    Returns
    -------
    dict
        ``{"exudyn": {...versions...}, "model": {...}, "rows": [compare(...) per mesh],
        "notes": str}``.
    """
    import exudyn

    meshes = list(elements) if elements is not None else ([8] if quick else [8, 16])
    rows = [compare(repeats, n, t_end, n_steps) for n in meshes]
    return {
        "exudyn": {"version": exudyn.__version__,
                   "compiled_module": getattr(exudyn, "_compiledModuleName", "unknown"),
                   "element": "ObjectANCFCable2D", "solver": "GeneralizedAlpha",
                   "newton_relative_tolerance": EXUDYN_REL_TOL,
                   "newton_absolute_tolerance": EXUDYN_ABS_TOL},
        "model": {"length_mm": LENGTH, "width_mm": WIDTH, "thickness_mm": THICKNESS,
                  "E_MPa": E_MOD, "rho_t_per_mm3": RHO, "gravity_mm_s2": GRAVITY,
                  "damping_s": DAMPING, "rho_inf": RHO_INF},
        "rows": rows,
        "notes": NOTES,
    }
