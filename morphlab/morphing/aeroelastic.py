"""Static aeroelastic equilibrium of the morphing skin: the skin loaded by the air pressure of
its own deformed shape.

Method (a fixed-point iteration of flow and structure):

1. the *vacuum* state: the static equilibrium of the mechanism at the configuration's time
   (:func:`morphlab.static`, the torque held);
2. the pressure on the skin's nodes from the flow about the section they shape
   (:func:`~morphlab.morphing.aero.skin_loads`: NeuralFoil's CL, CD, transition, the panel
   method's Cp fitted to NeuralFoil's viscous Cp on the skin; with a target CL the angle of
   attack is found again for every shape);
3. the static equilibrium under that pressure as a follower load normal to the deformed skin
   (``Model.add_pressure`` with one value per node, linear along each element, acting over
   the skin's width, the span), from the previous state;
4. 2-3 again until the skin's nodes move by less than ``tol`` [mm] between two solves.

The pressure changes little with a deflection of a tenth of a millimetre: each pass shrinks
the node change by a factor of ~40 (high speed) to ~400 (thermalling), so four or five passes
reach 1e-6 mm (``AeroelasticResult.history`` shows it).

The actuator: ``"torque"`` holds the design's torque (as the paper's model drives the crank;
in the undeformed high-speed configuration the torque is zero, so only the skin holds the
crank); ``"locked"`` holds the crank at its vacuum angle (a self-locking actuator, e.g. a
spindle or worm drive), by a drive added to the model.

Sign convention, end to end: the skin's nodes run F (upper surface) -> nose -> G (lower
surface), counter-clockwise about the section; a pressure ``p = q Cp`` [MPa] positive pushes
on the surface, into the section, which is the left normal of that node order, the positive
direction of ``add_pressure``; so the nodal values go in unchanged, and suction (p < 0) pulls
the skin outwards (``tests/test_aeroelastic.py`` checks it on the deflection).

Units: mm, N, MPa; flight data in SI (:mod:`~morphlab.morphing.flight`).
"""

from __future__ import annotations

import time as _time
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from ..errors import ConvergenceError, ModelError
from ..model import Model
from ..model.profiles import SmoothStep
from ..results.result import Result
from ..solve.settings import StaticSettings
from ..solve.statics import static
from .aero import AeroResult, skin_loads
from .flight import FlightCondition

__all__ = ["ACTUATORS", "TOL_MM", "AeroelasticResult", "equilibrium", "outward_normals",
           "warm_statics"]

FloatArray = NDArray[np.float64]

#: How the actuator holds the crank under the air load (module docstring).
ACTUATORS = ("torque", "locked")
#: Default tolerance [mm]: the largest node movement between two passes at convergence. The
#: statics converge to 1e-10 of the model size (3e-8 mm) and the flow is smooth in the shape
#: on the micrometre scale, so 1e-6 mm is reached and is far below the deflections (0.01 to
#: 0.3 mm) and the shape errors (0.02 mm) it is compared with.
TOL_MM = 1e-6


def outward_normals(nodes: np.ndarray) -> FloatArray:
    """Unit outward normals of a skin at its nodes (n_nodes, 2): the right normal of the
    central-difference tangent (one-sided at the ends) of the counter-clockwise node order
    F -> nose -> G."""
    x = np.asarray(nodes, dtype=float)
    tangent = np.gradient(x, axis=0)
    n = np.column_stack([tangent[:, 1], -tangent[:, 0]])
    return n / np.linalg.norm(n, axis=1)[:, None]


@dataclass
class AeroelasticResult:
    """A static aeroelastic equilibrium (:func:`equilibrium`).

    Attributes
    ----------
    condition : FlightCondition
    actuator : str
        ``"torque"`` or ``"locked"``.
    body : str
        The skin beam.
    vacuum, loaded : Result
        Static equilibria without and with the air load (``loaded``: the last solve, from the
        previous pass's state; its last time is the equilibrium).
    pressure : ndarray, shape (n_nodes,)
        Nodal pressure [MPa] applied in the last solve (positive pushes into the section).
    pressure_residual : float
        Largest difference [MPa] of the pressure of the final shape from ``pressure``.
    flow, flow_vacuum : AeroResult
        Flow about the loaded and the vacuum shape.
    history : list of dict
        One entry per pass: ``node_change_mm`` (largest node movement since the previous
        solve), ``pressure_change_mpa`` (largest change of the nodal pressure it caused),
        ``newton_iterations``, ``cd_counts``.
    tol : float
        Convergence tolerance [mm].
    width : ndarray, shape (n_elements,)
        The width [mm] the pressure acts on (the span).
    timing : dict
        Wall seconds: ``"static"``, ``"flow"``, ``"total"``.
    """

    condition: FlightCondition
    actuator: str
    body: str
    vacuum: Result
    loaded: Result
    pressure: FloatArray
    pressure_residual: float
    flow: AeroResult
    flow_vacuum: AeroResult
    history: list
    tol: float
    width: FloatArray
    timing: dict = field(default_factory=dict)

    @property
    def nodes_vacuum(self) -> FloatArray:
        """Skin nodes without air load, (n_nodes, 2) [mm]."""
        return np.real(self.vacuum.node_positions(self.body, -1))

    @property
    def nodes_loaded(self) -> FloatArray:
        """Skin nodes under the air load, (n_nodes, 2) [mm]."""
        return np.real(self.loaded.node_positions(self.body, -1))

    @property
    def iterations(self) -> int:
        """Passes (loaded solves) to convergence."""
        return len(self.history)

    @property
    def deflection(self) -> FloatArray:
        """Distance of each node under load from its vacuum position, (n_nodes,) [mm]."""
        return np.linalg.norm(self.nodes_loaded - self.nodes_vacuum, axis=1)

    @property
    def deflection_normal(self) -> FloatArray:
        """Deflection along the vacuum skin's outward normal (positive outwards), (n_nodes,)
        [mm]."""
        d = self.nodes_loaded - self.nodes_vacuum
        return np.sum(d * outward_normals(self.nodes_vacuum), axis=1)

    @property
    def deflection_max(self) -> float:
        """Largest node deflection [mm]."""
        return float(np.max(self.deflection))

    @property
    def deflection_rms(self) -> float:
        """Root mean square of the node deflections [mm]."""
        return float(np.sqrt(np.mean(self.deflection**2)))

    @property
    def drag_change_counts(self) -> float:
        """CD under load minus CD in vacuum [counts]."""
        return self.flow.cd_counts - self.flow_vacuum.cd_counts

    @property
    def air_force(self) -> FloatArray:
        """Resultant of the applied pressure on the loaded skin [N], (2,): the nodal values
        linear along the straight chords between the nodes, times the width (an independent
        check of the reactions: it differs from the load on the curved elements by the
        chords' sag)."""
        x = self.nodes_loaded
        seg = np.diff(x, axis=0)
        left = np.column_stack([-seg[:, 1], seg[:, 0]])  # left normal times the length
        pm = 0.5 * (self.pressure[1:] + self.pressure[:-1]) * self.width
        return np.sum(pm[:, None] * left, axis=0)

    def summary(self) -> str:
        """A few lines: configuration, convergence, deflection, drag."""
        c = self.condition
        steps = ", ".join(f"{h['node_change_mm']:.1e}" for h in self.history)
        return (f"{c.name or 'condition'} ({c.speed * 3.6:.0f} km/h, q {c.dynamic_pressure:.0f} "
                f"Pa, Re {c.reynolds:.3g}, CL {self.flow.cl:.3f}), actuator {self.actuator}: "
                f"converged in {self.iterations} passes (node change per pass [mm]: {steps}; "
                f"tol {self.tol:g} mm)\n"
                f"  deflection under the air load: max {self.deflection_max:.4f} mm, RMS "
                f"{self.deflection_rms:.4f} mm; CD {self.flow_vacuum.cd_counts:.2f} -> "
                f"{self.flow.cd_counts:.2f} counts ({self.drag_change_counts:+.2f}); line load "
                f"{1e3 * self.pressure.min():.2f} ... {1e3 * self.pressure.max():.2f} N/mm per m")


def _lock(model: Model, crank: str, angle: float, t: float) -> None:
    """Hold ``crank`` at ``angle`` [rad] from its initial angle at time ``t`` (a drive that
    turns it there smoothly from 0, so the initial configuration stays consistent)."""
    if t > 0.0 and angle != 0.0:
        model.add_drive(crank, angle=angle * SmoothStep(0.0, t), name="lock")
    elif abs(angle) <= 1e-9:  # at t = 0 only round-off turns the crank
        model.add_drive(crank, angle=0.0, name="lock")
    else:
        raise ModelError(f"cannot lock crank {crank!r} at {angle:.4g} rad at t = 0: the "
                         "vacuum state at t = 0 should be the initial one")


def equilibrium(build: Callable[[], Model], condition: FlightCondition, *,
                settings: StaticSettings | Mapping | None = None, actuator: str = "torque",
                crank: str = "crank", body: str = "skin", tol: float = TOL_MM,
                max_iter: int = 20, relaxation: float = 1.0, airfoil=None, q_start=None,
                **flow_options) -> AeroelasticResult:
    """Static aeroelastic equilibrium of a skin (module docstring).

    Parameters
    ----------
    build : callable
        ``build() -> Model``: a new model of the mechanism each call (the air load is added
        to it), e.g. ``lambda: morphing.build(p)``. Its beam ``body`` runs F -> nose -> G.
    condition : FlightCondition
        The freestream (target CL or angle of attack).
    settings : StaticSettings or dict, optional
        Options of the vacuum equilibrium (:func:`morphlab.static`): ``t`` is the time at
        which the torque is evaluated (the configuration), ``steps`` its continuation
        steps. The loaded solves use the same options with one step from the previous state.
    actuator : {"torque", "locked"}
        How the crank is held under the air load (module docstring).
    crank : str
        The crank body (for ``actuator="locked"``).
    body : str
        The skin beam.
    tol : float
        Convergence tolerance [mm] on the largest node movement between two passes.
    max_iter : int
        Largest number of passes.
    relaxation : float
        Under-relaxation of the pressure, ``p <- p + relaxation (p_new - p)``, in (0, 1].
    airfoil : CSTAirfoil, optional
        The undeformed section (default the study's).
    q_start : (n_dof,), optional
        Start of the vacuum equilibrium's Newton iterations (e.g. the last state of a
        dynamic run of the same model, with ``settings`` of one step): for a mechanism whose
        torque path has a limit point, which load control cannot pass.
    **flow_options
        Passed to :func:`~morphlab.morphing.aero.analyze` (``model_size``, ``n_panels``).

    Returns
    -------
    AeroelasticResult

    Raises
    ------
    ConvergenceError
        No convergence in ``max_iter`` passes; ``result`` is the last loaded solve and
        ``aeroelastic`` the partial :class:`AeroelasticResult`.
    ModelError
        Bad options.
    """
    if actuator not in ACTUATORS:
        raise ModelError(f"actuator must be one of {ACTUATORS}, got {actuator!r}")
    if not isinstance(condition, FlightCondition):
        raise ModelError(f"condition must be a FlightCondition, got {type(condition).__name__}")
    if not (isinstance(tol, float) and tol > 0.0):
        raise ModelError(f"tol must be a positive float [mm], got {tol!r}")
    if not (isinstance(max_iter, int) and max_iter >= 1):
        raise ModelError(f"max_iter must be an integer >= 1, got {max_iter!r}")
    if not 0.0 < relaxation <= 1.0:
        raise ModelError(f"relaxation must lie in (0, 1], got {relaxation!r}")
    if isinstance(settings, Mapping):
        settings = StaticSettings.of(None, **settings)
    st = StaticSettings.of(settings)
    t_start = _time.perf_counter()
    clock = {"static": 0.0, "flow": 0.0}

    def timed(key, fn, *args, **kwargs):
        t0 = _time.perf_counter()
        out = fn(*args, **kwargs)
        clock[key] += _time.perf_counter() - t0
        return out

    model = build()
    width = None
    vacuum = timed("static", static, model, settings=st, q_start=q_start)
    x = np.real(vacuum.node_positions(body, -1))
    angle = 0.0
    if actuator == "locked":
        _, theta = vacuum.reference(crank)
        angle = float(np.real(theta[-1] - theta[0]))
    p_new, flow_vac = timed("flow", skin_loads, x, condition, airfoil, **flow_options)
    alpha = flow_vac.alpha
    q, p, flow, history = vacuum.q[-1], p_new, flow_vac, []
    loaded = vacuum
    one_step = StaticSettings.of(st, steps=1)
    for _ in range(max_iter):
        model = build()
        if actuator == "locked":
            _lock(model, crank, angle, float(st.t))
        item = model.add_pressure("air", body, p)
        width = np.asarray(item.width, dtype=float)
        loaded = timed("static", static, model, settings=one_step, q_start=q)
        q = loaded.q[-1]
        x_new = np.real(loaded.node_positions(body, -1))
        change = float(np.max(np.linalg.norm(x_new - x, axis=1)))
        p_new, flow = timed("flow", skin_loads, x_new, condition, airfoil,
                            alpha_start=alpha, **flow_options)
        history.append({"node_change_mm": change,
                        "pressure_change_mpa": float(np.max(np.abs(p_new - p))),
                        "newton_iterations": int(loaded.newton_iterations[-1]),
                        "cd_counts": flow.cd_counts})
        x = x_new
        if change < tol:
            break
        p = p + relaxation * (p_new - p)
    clock["total"] = _time.perf_counter() - t_start
    out = AeroelasticResult(condition=condition, actuator=actuator, body=body, vacuum=vacuum,
                            loaded=loaded, pressure=p, pressure_residual=float(np.max(np.abs(
                                p_new - p))), flow=flow, flow_vacuum=flow_vac,
                            history=history, tol=tol, width=width, timing=clock)
    if history[-1]["node_change_mm"] >= tol:
        err = ConvergenceError(
            f"aeroelastic equilibrium ({condition.name or 'condition'}, actuator {actuator}) "
            f"not converged in {max_iter} passes: the nodes still moved by "
            f"{history[-1]['node_change_mm']:.3g} mm (tol {tol:g} mm); try relaxation < 1",
            residual=history[-1]["node_change_mm"], result=loaded)
        err.aeroelastic = out
        raise err
    return out


def warm_statics(build: Callable[[], Model], *, body: str = "skin", crank: str = "crank") -> None:
    """Compile the kernels of :func:`equilibrium`'s static solves without a flow analysis:
    the skin in vacuum, and under a uniform suction with the crank free and locked (the item
    kinds of its loaded solves; a few Newton iterations at ``t = 0`` each).

    Parameters
    ----------
    build : callable
        ``build() -> Model``, as for :func:`equilibrium`.
    body, crank : str
        The skin beam and the crank body, as for :func:`equilibrium`.
    """
    settings = StaticSettings(t=0.0, steps=1, kinematic_tol=None)
    vacuum = static(build(), settings=settings)
    n_nodes = len(np.real(vacuum.node_positions(body, -1)))
    for actuator in ACTUATORS:
        model = build()
        if actuator == "locked":
            _lock(model, crank, 0.0, 0.0)
        model.add_pressure("air", body, np.full(n_nodes, -1.0e-4))  # 0.1 kPa of suction
        static(model, settings=settings, q_start=vacuum.q[-1])
