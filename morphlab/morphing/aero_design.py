"""The mechanism designed for drag: the design problem of
:mod:`morphlab.morphing.optimization` (13 variables: six skin thickness zones, the pivot A,
the bell-crank points B and D, the torque; the KS stress below yield / 1.5 and the joints
1 mm inside the skin; the same bounds) with the section's drag at the thermalling condition
as the objective instead of the RMS shape error.

The drag is that of the realized morphed skin at the end of the run (in vacuum, as the shape
error): :class:`~morphlab.morphing.aero_response.AeroResponse`, differentiated with the
direct method (the state's sensitivity exact, the flow's by a central difference along it).
The air load moves the drag by a fraction of a count (:mod:`~morphlab.morphing.flight_loads`);
:func:`compare` checks both optima under it afterwards.

The target shape was drawn for shape, not computed for drag, so the drag optimum is free to
leave it: it trades shape error for drag until a constraint or a bound stops it.

One constraint is added to the shape-error problem's: the mechanism must be at rest when the
torque has stopped rising (:func:`hold_margin`). Without it the drag optimum is a mechanism
that snaps through during the hold: its crank turns on by 0.37 rad after the ramp, the skin
still moves by 0.7 mm per 5 ms at the end of the run, and the drag read there (130 counts)
is a snapshot of the motion, 5 mm from any equilibrium. The shape error never led there
(:func:`~morphlab.morphing.optimization.verify` checks only backward turning in the ramp).
"""

from __future__ import annotations

import warnings

import numpy as np

from ..errors import KinematicAccuracyWarning
from ..solve.settings import Settings
from ..studies.problem import Constraint, Problem
from . import optimization as opt
from .aero_response import AeroResponse
from .flight import THERMALLING, FlightCondition
from .flight_loads import configuration
from .optimization import HOLD_ROTATION_RAD, hold_rotation

__all__ = ["HOLD_ROTATION_RAD", "hold_rotation", "hold_margin", "responses", "drag_problem",
           "evaluate", "compare", "format_comparison"]

def hold_margin(result):
    """``1 - (hold_rotation / HOLD_ROTATION_RAD)**2``: 1 at rest, 0 at the limit, negative
    beyond it (a smooth constraint of order one at the start, unlike the rotation itself,
    which is ~1e-4 of the limit there). Complex-safe."""
    r = hold_rotation(result) / HOLD_ROTATION_RAD
    return 1.0 - r * r


def responses(condition: FlightCondition = THERMALLING, **options) -> dict:
    """The design problem's responses (:data:`~morphlab.morphing.optimization.RESPONSES`),
    :func:`hold_margin` and ``"drag"`` [counts] of the final skin shape at ``condition``."""
    return {**opt.RESPONSES, "hold_margin": hold_margin,
            "drag": AeroResponse("drag", condition, **options)}


def drag_problem(*, condition: FlightCondition = THERMALLING, n_elements: int = 30,
                 settings: dict | Settings | None = None, p0: dict | None = None,
                 variables=opt.VARIABLES) -> Problem:
    """Minimise the drag [counts] at ``condition`` over ``variables`` subject to
    ``ks_max_stress <= ALLOWABLE_MPA``, ``joint_clearance >= CLEARANCE_MM`` and
    ``hold_margin >= 0`` (module docstring) within
    :func:`~morphlab.morphing.optimization.bounds`, by direct sensitivities; objective and
    constraints normalized by their start values (as
    :func:`~morphlab.morphing.optimization.problem`)."""
    p0 = opt.start() if p0 is None else dict(p0)
    b = opt.bounds(p0)
    return Problem(lambda p: opt.build(p, n_elements=n_elements), p0, responses(condition),
                   "drag", constraints=[Constraint("ks_max_stress", upper=opt.ALLOWABLE_MPA),
                                        Constraint("joint_clearance", lower=opt.CLEARANCE_MM),
                                        Constraint("hold_margin", lower=0.0)],
                   bounds={k: b[k] for k in variables}, variables=list(variables),
                   settings=opt._settings(settings), method="direct", normalize=True)


def evaluate(p: dict, *, condition: FlightCondition = THERMALLING,
             settings: dict | Settings | None = None, loads: bool = True) -> dict:
    """A design as the comparison reads it: :func:`~morphlab.morphing.optimization.verify`
    (an independent re-simulation: responses, links crossing the skin, snap-through in the
    ramp, ``ok``), the drag [counts] of its final shape, :func:`hold_rotation`, how far the
    final state lies from the static equilibrium next to it (``settled_mm``: the largest
    node distance; round-off for a mechanism at rest) and, with ``loads``, the aeroelastic
    equilibrium at the thermalling condition (torque held): drag and deflection under the
    air load."""
    from ..solve.statics import static
    from ..solve.timeloop import simulate

    out = opt.verify(p, settings=settings)
    st = opt._settings(settings)
    res = simulate(opt.build(p), settings=st)
    out["drag"] = AeroResponse("drag", condition)(res)
    out["hold_rotation"] = float(np.real(hold_rotation(res)))
    rest = static(opt.build(p), t=st.t_end, q_start=res.q[-1], kinematic_tol=None)
    out["settled_mm"] = float(np.max(np.linalg.norm(np.real(
        rest.node_positions("skin", -1) - res.node_positions("skin", -1)), axis=1)))
    if loads:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", KinematicAccuracyWarning)
            eq = configuration("thermalling", p, build=opt.build, q_start=rest.q[-1])
        out["drag_loaded"] = eq.flow.cd_counts
        out["deflection_max_mm"] = eq.deflection_max
        out["deflection_rms_mm"] = eq.deflection_rms
    return out


def compare(*, settings: dict | Settings | None = None, maxiter: int = 60,
            max_runs: int | None = None, progress=False, shape_optimum=None) -> dict:
    """The shape-error optimum and the drag optimum of the same problem, side by side.

    Parameters
    ----------
    settings : dict or Settings, optional
        Options of the runs (default the study's).
    maxiter : int
        SLSQP iterations of each optimization.
    max_runs : int, optional
        Budget of runs of each.
    progress : bool or callable
        Passed to :func:`morphlab.studies.optimize`.
    shape_optimum : OptimizationResult, optional
        A shape-error optimum already computed (e.g. notebook 05's); default: computed here.

    Returns
    -------
    dict
        ``"start"``, ``"shape"``, ``"drag"``: :func:`evaluate` of the start design and of the
        two optima (with the ``"design"``); ``"results"``: the two OptimizationResults.
    """
    from ..studies.optimize import optimize

    options = {"ftol": 1e-7, "maxiter": maxiter}
    if shape_optimum is None:
        shape_optimum = optimize(opt.problem(settings=settings), "SLSQP", options=options,
                                 max_runs=max_runs, progress=progress)
    drag_optimum = optimize(drag_problem(settings=settings), "SLSQP", options=options,
                            max_runs=max_runs, progress=progress)
    out = {"results": {"shape": shape_optimum, "drag": drag_optimum}}
    for key, p in (("start", opt.start()), ("shape", shape_optimum.design),
                   ("drag", drag_optimum.design)):
        out[key] = {**evaluate(p, settings=settings), "design": dict(p)}
    return out


def format_comparison(c: dict) -> str:
    """The comparison of :func:`compare` as a text table."""
    keys = [("rms_error", "RMS shape error [mm]", "{:.4f}"),
            ("max_error", "max shape error [mm]", "{:.4f}"),
            ("ks_max_stress", "KS stress [MPa]", "{:.1f}"),
            ("joint_clearance", "joint clearance [mm]", "{:.2f}"),
            ("drag", "CD in vacuum [counts]", "{:.2f}"),
            ("drag_loaded", "CD under load [counts]", "{:.2f}"),
            ("hold_rotation", "crank turn in hold [rad]", "{:.2g}"),
            ("settled_mm", "end state to statics [mm]", "{:.1e}"),
            ("deflection_max_mm", "deflection max [mm]", "{:.4f}"),
            ("ok", "verify() ok", "{}")]
    cols = ("start", "shape", "drag")
    lines = [f"{'':26s}" + "".join(f"{h:>16s}" for h in ("start", "shape optimum",
                                                          "drag optimum"))]
    for k, title, fmt in keys:
        cells = [fmt.format(c[col][k]) if k in c[col] else "-" for col in cols]
        lines.append(f"{title:26s}" + "".join(f"{v:>16s}" for v in cells))
    return "\n".join(lines)
