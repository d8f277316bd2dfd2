"""Aerodynamics of the wing section with the morphing leading edge: lift, drag, moment,
transition and the pressure on the skin, at a :class:`~morphlab.morphing.flight.FlightCondition`.

Two tools, each for what it does well:

* **NeuralFoil** (Sharpe & Hansman 2025, arXiv:2503.16323; neural networks trained on XFoil,
  pure NumPy, smooth in its inputs) gives the viscous CL, CD, CM and the transition points.
  It takes an airfoil as 8+8 CST weights with a leading-edge term in its chord frame
  (:func:`~morphlab.morphing.profile.kulfan_fit`); this module fits them, passes the angle of
  attack and Reynolds number of that frame, and turns the coefficients back to the wing's
  frame (x along the undeformed chord, reference chord 550 mm, moments about x = c/4, y = 0).
  Its boundary-layer outputs (edge speed ``ue/V`` at 32 stations per side, the first at
  x/c = 1/64) give a viscous Cp, but too coarse for the suction peak round the nose.
* a **linear-vorticity panel method** (:mod:`~morphlab.morphing.panel`) gives the pressure
  along the whole contour, the nose resolved. It is inviscid. By default (``cp_match="skin"``)
  it runs at the angle of attack at which its Cp best fits (least squares) NeuralFoil's
  viscous Cp at the stations on the skin (x/c <= 0.26, 8 per side): the flow round the nose
  is then the viscous one where NeuralFoil sees it, and the panel method supplies the suction
  peak between and ahead of its stations. ``cp_match="lift"`` runs it at the angle where
  its lift equals NeuralFoil's viscous lift instead; at high lift, where the boundary layer
  costs much of the lift aft, that under-predicts the suction at the nose (thermalling,
  undeformed: Cp -2.8 against NeuralFoil's -3.9 at x/c = 1/64), which is why it is not the
  default.

The pressure on the skin is the gauge pressure ``p = q Cp`` [MPa]: positive pushes on the
surface (acts against the outward normal), negative (suction) pulls it outward.

Coupling with the structure: :func:`skin_loads` takes the skin's nodes and returns the nodal
pressure [MPa] of the section they shape, at the flight condition (with a target CL the angle
of attack is found again for every shape: the weight sets the lift);
:mod:`~morphlab.morphing.aeroelastic` applies it as a follower pressure on the skin (its
width is the span) and iterates flow and statics to the equilibrium. The design responses
built on :func:`analyze` are in :mod:`~morphlab.morphing.aero_response`; the time of one
analysis is in BENCHMARKS.md (case ``aero``): about 15 ms (7 ms without the panel method)
with one BLAS thread. :func:`analyze` runs with one BLAS thread
(:class:`~morphlab.jit.threads.one_blas_thread`): NeuralFoil's small matrix products and the
panel solve gain nothing from more, and on a machine whose cores are busy BLAS threads wait
for each other (a median of 176 ms at load 4 on 2 cores with NumPy's default threads).

Units: coordinates in mm, pressures in MPa (N/mm²), angles in degrees, flight data in SI
(:mod:`~morphlab.morphing.flight`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..errors import ModelError
from ..jit.threads import one_blas_thread
from .cst import CSTAirfoil
from .flight import FlightCondition
from .panel import panel_solution
from .profile import Contour, kulfan_fit, skin_curve, whole_airfoil

__all__ = ["AeroResult", "section", "analyze", "skin_pressure", "skin_loads", "MODEL_SIZES"]

FloatArray = NDArray[np.float64]

#: NeuralFoil's network sizes, smallest to largest (accuracy against XFoil grows, see its docs).
MODEL_SIZES = ("xxsmall", "xsmall", "small", "medium", "large", "xlarge", "xxlarge", "xxxlarge")


def _neuralfoil():
    """NeuralFoil, imported on first use (it loads AeroSandbox and CasADi, ~1.2 s)."""
    try:
        import neuralfoil
    except ImportError as exc:  # pragma: no cover - a dependency of morphlab
        raise ModelError("the flow analysis needs NeuralFoil: pip install neuralfoil") from exc
    return neuralfoil


@dataclass(frozen=True)
class AeroResult:
    """Flow about one wing section at one flight condition.

    Attributes
    ----------
    condition : FlightCondition
        The freestream analysed: speed, air, reference chord, incidence or target lift.
    alpha : float
        Angle of attack [deg] in the wing frame (given, or found for the target CL).
    cl, cd, cm : float
        Lift, drag and quarter-chord moment coefficients (nose-up positive) on the reference
        chord, moment about (c/4, 0) of the wing frame.
    xtr_upper, xtr_lower : float
        Transition positions, x/c in the section's own chord frame (0 at its leading edge).
    confidence : float
        NeuralFoil's ``analysis_confidence`` in [0, 1] (low: outside its training data or
        near stall).
    contour : Contour
        Spline of the analysed section [mm].
    fit_rms : float
        RMS residual of the CST fit, in y/c.
    nodes : ndarray, shape (N + 1, 2)
        Panel nodes [mm] (trailing edge, upper surface, nose, lower surface).
    s_nodes : ndarray, shape (N + 1,)
        Their parameters on :attr:`contour`.
    cp : ndarray, shape (N + 1,)
        Inviscid Cp at the nodes, at :attr:`alpha_inviscid` (NaN at the two trailing-edge
        nodes, see :meth:`~morphlab.morphing.panel.PanelSolution.cp`).
    alpha_inviscid : float
        Angle of attack [deg] of the panel solution (see ``cp_match`` of :func:`analyze`).
    cp_match_rms : float
        RMS difference of the panel Cp from NeuralFoil's viscous Cp at the stations used for
        the match (x/c <= ``match_xc``, both surfaces).
    bl_x : ndarray, shape (32,)
        NeuralFoil's boundary-layer stations, x/c in the chord frame, on each surface.
    cp_upper, cp_lower : ndarray, shape (32,)
        Viscous Cp there, ``1 - (ue/V)**2``.
    """

    condition: FlightCondition
    alpha: float
    cl: float
    cd: float
    cm: float
    xtr_upper: float
    xtr_lower: float
    confidence: float
    contour: Contour
    fit_rms: float
    nodes: FloatArray
    s_nodes: FloatArray
    cp: FloatArray
    alpha_inviscid: float
    cp_match_rms: float
    bl_x: FloatArray
    cp_upper: FloatArray
    cp_lower: FloatArray

    @property
    def cd_counts(self) -> float:
        """Drag in counts (1 count = 1e-4)."""
        return 1e4 * self.cd

    @property
    def lift_to_drag(self) -> float:
        """``cl / cd``."""
        return self.cl / self.cd

    @property
    def has_pressure(self) -> bool:
        """Whether the panel solution was computed (``analyze(..., pressure=True)``)."""
        return self.cp.size > 0

    def _need_pressure(self) -> None:
        if not self.has_pressure:
            raise ModelError("this analysis has no pressure distribution: run analyze(..., "
                             "pressure=True)")

    @property
    def cp_min(self) -> float:
        """Lowest (peak suction) inviscid Cp on the contour."""
        self._need_pressure()
        return float(np.nanmin(self.cp))

    def cp_at(self, points: ArrayLike) -> FloatArray:
        """Inviscid Cp at points on (or next to) the contour, shape (m,): each point is
        projected onto the spline and Cp is interpolated linearly in the contour parameter
        between the panel nodes."""
        self._need_pressure()
        # the trailing-edge nodes carry no Cp
        return np.interp(self.contour.locate(points), self.s_nodes[1:-1], self.cp[1:-1])

    def summary(self) -> str:
        """One line: CL, CD [counts], L/D, CM, transition, peak suction."""
        cp_min = f"{self.cp_min:.3f}" if self.has_pressure else "-"
        return (f"{self.condition.name or 'condition'}: alpha {self.alpha:.3f} deg, "
                f"CL {self.cl:.4f}, CD {self.cd_counts:.2f} counts, L/D {self.lift_to_drag:.1f}, "
                f"CM {self.cm:.4f}, x_tr/c {self.xtr_upper:.3f} upper / {self.xtr_lower:.3f} "
                f"lower, Cp_min {cp_min}, confidence {self.confidence:.2f}")


def section(skin_nodes: ArrayLike | None = None, airfoil: CSTAirfoil | None = None) -> FloatArray:
    """Coordinates of the whole section [mm] with the skin through ``skin_nodes``.

    ``skin_nodes`` (n_nodes, 2) are the model's skin nodes F -> nose -> G (e.g.
    ``res.node_positions("skin")[-1]``, ``geometry.target()``); ``None`` gives the undeformed
    section. The skin between the nodes is the exact undeformed curve plus the interpolated
    nodal displacements (:func:`~morphlab.morphing.profile.skin_curve`), joined to the fixed
    rear part (:func:`~morphlab.morphing.profile.whole_airfoil`).
    """
    skin = None if skin_nodes is None else skin_curve(skin_nodes, airfoil, n_dense=401)
    return whole_airfoil(skin, airfoil)


def _coefficients(nf_out: dict, fit, condition: FlightCondition, alpha: FloatArray) -> dict:
    """NeuralFoil's chord-frame coefficients in the wing frame (reference chord, c/4 of it)."""
    ratio = fit.chord / condition.chord
    cl = nf_out["CL"] * ratio
    cd = nf_out["CD"] * ratio
    a = np.radians(alpha)
    # force per unit span and dynamic pressure, in mm; drag along the freestream
    fx = fit.chord * (nf_out["CD"] * np.cos(a) - nf_out["CL"] * np.sin(a))
    fy = fit.chord * (nf_out["CD"] * np.sin(a) + nf_out["CL"] * np.cos(a))
    te = fit.leading_edge + fit.chord * np.array([np.cos(fit.chord_angle),
                                                  np.sin(fit.chord_angle)])
    q_pt = fit.leading_edge + 0.25 * (te - fit.leading_edge)  # NeuralFoil's moment centre
    d = q_pt - np.array([0.25 * condition.chord, 0.0])
    # counter-clockwise moment about the reference point; nose-up is clockwise
    mz = -nf_out["CM"] * fit.chord**2 + (d[0] * fy - d[1] * fx)
    return {"cl": cl, "cd": cd, "cm": -mz / condition.chord**2}


def _evaluate(fit, condition: FlightCondition, alpha, model_size: str) -> dict:
    nf = _neuralfoil()
    alpha = np.atleast_1d(np.asarray(alpha, dtype=float))
    out = nf.get_aero_from_kulfan_parameters(
        fit.parameters, alpha=alpha - np.degrees(fit.chord_angle),
        Re=condition.reynolds * fit.chord / condition.chord, n_crit=condition.n_crit,
        model_size=model_size)
    out = {k: np.broadcast_to(np.asarray(v, dtype=float), alpha.shape) for k, v in out.items()}
    return {**out, **_coefficients(out, fit, condition, alpha)}


def _alpha_for_cl(fit, condition: FlightCondition, model_size: str,
                  start: float | None = None) -> float:
    """Angle of attack [deg] of the target CL: Newton (central-difference slope, one
    vectorised call per step) to |dCL| < 1e-12, from ``start`` or from a bracket found by a
    scan of [-8, 16] deg (also when Newton from ``start`` does not converge in 6 steps)."""
    h = 1e-3

    def newton(a: float, n_steps: int) -> float | None:
        for _ in range(n_steps):
            c3 = _evaluate(fit, condition, [a - h, a, a + h], model_size)["cl"]
            res = c3[1] - condition.cl
            if abs(res) < 1e-12:
                return float(a)
            a -= res * 2.0 * h / (c3[2] - c3[0])
        return None

    if start is not None:
        a = newton(float(start), 6)
        if a is not None:
            return a
    grid = np.linspace(-8.0, 16.0, 49)
    cl = _evaluate(fit, condition, grid, model_size)["cl"]
    above = np.nonzero(cl >= condition.cl)[0]
    if above.size == 0 or above[0] == 0:
        raise ModelError(f"target cl {condition.cl:.3f} is outside the section's range "
                         f"{cl.min():.3f} ... {cl.max():.3f} for alpha in [-8, 16] deg "
                         f"({condition.name or 'condition'}, Re {condition.reynolds:.3g})")
    k = above[0]
    a = grid[k - 1] + (condition.cl - cl[k - 1]) * (grid[k] - grid[k - 1]) / (cl[k] - cl[k - 1])
    found = newton(a, 20)
    if found is None:
        raise ModelError(f"no angle of attack found for cl {condition.cl}")
    return found


def _match_skin(panels, s_in, s_st, target, alpha0: float) -> float:
    """Angle of attack [deg] whose panel Cp (nodes at parameters ``s_in``, the trailing edge
    left out) best fits ``target`` at the parameters ``s_st``: Gauss-Newton on the
    least-squares residual, from ``alpha0``."""
    a = np.radians(alpha0)
    for _ in range(100):
        g = (np.cos(a) * panels.gamma0 + np.sin(a) * panels.gamma90)[1:-1]
        dg = (-np.sin(a) * panels.gamma0 + np.cos(a) * panels.gamma90)[1:-1]
        r = np.interp(s_st, s_in, 1.0 - g * g) - target
        jac = np.interp(s_st, s_in, -2.0 * g * dg)
        step = np.dot(jac, r) / np.dot(jac, jac)
        a -= step
        if abs(step) < 1e-14:
            return float(np.degrees(a))
    raise ModelError(f"the panel solution's fit to the viscous Cp did not converge (last step "
                     f"{step:.2e} rad); use cp_match='lift'")


@one_blas_thread()
def analyze(coordinates: ArrayLike, condition: FlightCondition, *, model_size: str = "xlarge",
            n_panels: int = 240, cp_match: str = "skin", match_xc: float = 0.26,
            pressure: bool = True, alpha_start: float | None = None) -> AeroResult:
    """Flow about a wing section at a flight condition.

    Parameters
    ----------
    coordinates : array_like, shape (m, 2)
        The whole section [mm], Selig order (trailing edge upper -> nose -> trailing edge
        lower), e.g. from :func:`section`; any smooth polyline of >= 9 points.
    condition : FlightCondition
        Freestream, with the angle of attack or the target lift coefficient.
    model_size : str, optional
        NeuralFoil network (:data:`MODEL_SIZES`); default "xlarge".
    n_panels : int, optional
        Panels of the inviscid pressure distribution (even, >= 16); default 240.
    cp_match : {"skin", "lift"}, optional
        Angle of attack of the inviscid pressure distribution: the best fit to NeuralFoil's
        viscous Cp at its stations with x/c <= ``match_xc`` ("skin", default), or equal lift
        ("lift"); see the module's notes.
    match_xc : float, optional
        Extent of the fit in x/c; default 0.26, the skin's (the spar at 0.25 c).
    pressure : bool, optional
        Solve the panel method (default). ``False`` gives NeuralFoil's outputs only (CL, CD,
        CM, transition, viscous Cp at its stations) in about half the time; the panel fields
        of the result are then empty and :attr:`AeroResult.alpha_inviscid` is NaN.
    alpha_start : float, optional
        Start [deg] of the Newton search for a target CL (e.g. the angle of a nearby shape);
        without it, or when Newton does not converge from it, a scan brackets the angle.
        The angle found is the same either way (to the 1e-12 tolerance on CL).

    Returns
    -------
    AeroResult

    Raises
    ------
    ModelError
        For bad coordinates or options, or a target CL the section cannot reach.
    """
    if model_size not in MODEL_SIZES:
        raise ModelError(f"model_size must be one of {MODEL_SIZES}, got {model_size!r}")
    if cp_match not in ("skin", "lift"):
        raise ModelError(f"cp_match must be 'skin' or 'lift', got {cp_match!r}")
    if not 0.05 <= match_xc <= 1.0:
        raise ModelError(f"match_xc must lie in [0.05, 1], got {match_xc!r}")
    if not isinstance(condition, FlightCondition):
        raise ModelError(f"condition must be a FlightCondition, got {type(condition).__name__}")
    contour = Contour(coordinates)
    fit = kulfan_fit(contour)
    alpha = (float(condition.alpha) if condition.alpha is not None
             else _alpha_for_cl(fit, condition, model_size, alpha_start))
    out = _evaluate(fit, condition, alpha, model_size)
    cl = float(out["cl"][0])
    nf = _neuralfoil()
    bl_x = np.asarray(nf.bl_x_points, dtype=float)
    cp_u = 1.0 - np.array([out[f"upper_bl_ue/vinf_{i}"][0] for i in range(bl_x.size)]) ** 2
    cp_l = 1.0 - np.array([out[f"lower_bl_ue/vinf_{i}"][0] for i in range(bl_x.size)]) ** 2
    common = dict(condition=condition, alpha=alpha, cl=cl, cd=float(out["cd"][0]),
                  cm=float(out["cm"][0]), xtr_upper=float(out["Top_Xtr"][0]),
                  xtr_lower=float(out["Bot_Xtr"][0]),
                  confidence=float(out["analysis_confidence"][0]), contour=contour,
                  fit_rms=fit.rms, bl_x=bl_x, cp_upper=cp_u, cp_lower=cp_l)
    if not pressure:
        empty = np.empty(0)
        return AeroResult(nodes=np.empty((0, 2)), s_nodes=empty, cp=empty,
                          alpha_inviscid=float("nan"), cp_match_rms=float("nan"), **common)
    s_nodes = contour.panel_parameters(n_panels)
    nodes = contour(s_nodes)
    panels = panel_solution(nodes, chord=condition.chord)
    # NeuralFoil's stations on the skin (both surfaces) and its viscous Cp there
    sel = bl_x <= match_xc
    s_st = np.concatenate([contour.at_x(bl_x[sel], True), contour.at_x(bl_x[sel], False)])
    cp_st = np.concatenate([cp_u[sel], cp_l[sel]])
    alpha_inv = panels.alpha_for_cl(cl)
    if cp_match == "skin":
        alpha_inv = _match_skin(panels, s_nodes[1:-1], s_st, cp_st, alpha_inv)
    cp = panels.cp(alpha_inv)
    miss = np.interp(s_st, s_nodes[1:-1], cp[1:-1]) - cp_st
    return AeroResult(nodes=nodes, s_nodes=s_nodes, cp=cp, alpha_inviscid=alpha_inv,
                      cp_match_rms=float(np.sqrt(np.mean(miss * miss))), **common)


def skin_pressure(result: AeroResult, points: ArrayLike) -> FloatArray:
    """Pressure on the skin at given points [MPa].

    Parameters
    ----------
    result : AeroResult
        Flow about the section the points lie on.
    points : array_like, shape (m, 2)
        Points on the skin [mm], e.g. its nodes ordered from F round the nose to G.

    Returns
    -------
    ndarray, shape (m,)
        Gauge pressure ``p = q Cp`` [MPa = N/mm²] (q of the flight condition, Cp of the
        panel solution matched to the viscous one, :meth:`AeroResult.cp_at`). Positive p
        pushes on the surface, i.e. acts against its outward normal; suction is negative.
        Times the span (1000 mm) it is the line load on the beam [N/mm]. The skin runs
        counter-clockwise (F -> nose -> G), so its outward normal is the right-hand normal of
        the element direction (node k -> k + 1) and a positive p acts along the left-hand
        one, into the section.
    """
    return result.condition.q_mpa * result.cp_at(points)


def skin_loads(skin_nodes: ArrayLike, condition: FlightCondition,
               airfoil: CSTAirfoil | None = None, **options) -> tuple[FloatArray, AeroResult]:
    """Pressure at the skin nodes of a (deformed) skin: the step of an aeroelastic iteration.

    Parameters
    ----------
    skin_nodes : array_like, shape (n_nodes, 2)
        Skin nodes F -> nose -> G [mm] (real part taken).
    condition : FlightCondition
    airfoil : CSTAirfoil, optional
        Undeformed section (default the study's).
    **options
        Passed to :func:`analyze` (``model_size``, ``n_panels``).

    Returns
    -------
    p : ndarray, shape (n_nodes,)
        Nodal pressure [MPa], sign as in :func:`skin_pressure`.
    result : AeroResult
    """
    nodes = np.real(np.asarray(skin_nodes, dtype=complex)).astype(float)
    res = analyze(section(nodes, airfoil), condition, **options)
    return skin_pressure(res, nodes), res


def __getattr__(name: str):
    # the design responses live in .aero_response (which imports this module)
    if name in ("AeroResponse", "aero_responses"):
        from . import aero_response

        return getattr(aero_response, name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
