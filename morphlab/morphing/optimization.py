"""The morphing leading edge as a design problem: what its sensitivities are for.

Thirteen variables: the skin wall thickness in :data:`ZONES` zones of equal element count
along the arc (``t0`` at the clamp F ... ``t5`` at the sliding end G), the pivot A, the
bell-crank points B and D, and the torque ``M_t``. The objective is the RMS shape error at the
morphed state (:data:`~morphlab.morphing.leading_edge.rms_error`); the constraints are the
KS skin stress below the allowable (yield / 1.5, :data:`ALLOWABLE_MPA`) and the mechanism
staying inside the skin: the joints A, B and D at least :data:`CLEARANCE_MM` from the skin
contour at every time step (:func:`joint_clearance`, complex-safe, so the direct method
differentiates it by complex step like the other responses).

What the gradient constraints do not see is checked on the optimum by an independent
re-simulation (:func:`verify`): links crossing the skin (:func:`~morphlab.morphing.
leading_edge.mechanism_clearance`) and a monotone crank rotation while the torque ramps up (no
snap-through).

Tolerances of manufacture for the uncertainty study (standard deviations,
:data:`TOLERANCES`): pivot and link points 0.1 mm, thickness 0.05 mm, Young's modulus 3 %,
torque 5 %. As a reliability problem (:func:`reliability`), normal scatter of these 14
variables about a design and two failure events: the KS skin stress above
:data:`ALLOWABLE_MPA` and the largest node error above :data:`MAX_ERROR_MM`.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import NamedTuple

import numpy as np

from ..errors import ModelError
from ..model import Model
from ..solve.settings import Settings
from ..studies.problem import Constraint, Problem
from . import leading_edge as le
from .optimizers import COMPARED, compare_optimizers, reached  # noqa: F401

#: Thickness zones along the skin arc.
ZONES = 6
#: Thickness variables, clamp F first.
THICKNESS = tuple(f"t{k}" for k in range(ZONES))
#: Mechanism variables: pivot A, bell-crank points B, D [mm], torque [N·mm].
MECHANISM = ("x_A", "y_A", "x_B", "y_B", "x_D", "y_D", "M_t")
VARIABLES = THICKNESS + MECHANISM
#: Allowable stress: yield over a safety factor 1.5 [MPa].
ALLOWABLE_MPA = le.YIELD_MPA / 1.5
#: Least distance of the joints A, B, D from the skin contour [mm].
CLEARANCE_MM = 1.0
#: Largest node error accepted at the morphed state in the reliability problem [mm].
MAX_ERROR_MM = 1.0
#: Standard deviations of manufacture (variable units; ``E`` is the skin's modulus).
TOLERANCES = {**{t: 0.05 for t in THICKNESS}, "x_A": 0.1, "y_A": 0.1, "x_B": 0.1, "y_B": 0.1,
              "x_D": 0.1, "y_D": 0.1, "E": 0.03 * le.E_AL, "M_t": 0.05 * le.DEFAULTS["M_t"]}


def start() -> dict:
    """The default design (the study's mechanism, uniform thickness) in the variables of
    :func:`build`, with the modulus ``E``."""
    p = {t: le.DEFAULTS["t_w"] for t in THICKNESS}
    p.update({k: {**le.DEFAULTS, **le.GEOMETRY}[k] for k in MECHANISM})
    p["E"] = le.DEFAULTS["E"]
    return p


def bounds(p0: dict | None = None) -> dict:
    """Bounds of the variables: thickness 1.5–2.5 mm, points ±1 mm around ``p0`` (default
    :func:`start`), torque 0.8–1.25 times its value. The mechanism is a near-toggle linkage:
    its output moves by ~0.1 mm per 0.01 mm of a point, and steps of several mm take it past
    its toggle (the run fails), so the box is the trust region of the design study."""
    p0 = start() if p0 is None else p0
    out = {t: (1.5, 2.5) for t in THICKNESS}
    out.update({k: (p0[k] - 1.0, p0[k] + 1.0) for k in MECHANISM[:-1]})
    out["M_t"] = (0.8 * p0["M_t"], 1.25 * p0["M_t"])
    return out


def zones(n_elements: int) -> list[np.ndarray]:
    """The element indices of each thickness zone (equal counts, F first)."""
    if n_elements < ZONES:
        raise ModelError(f"n_elements must be at least {ZONES} (one per zone), got "
                         f"{n_elements}")
    return np.array_split(np.arange(n_elements), ZONES)


def build(p: dict, *, n_elements: int = le.N_ELEMENTS) -> Model:
    """The leading edge of :func:`~morphlab.morphing.leading_edge.build` with a thickness per
    zone. ``p`` holds ``t0 .. t5`` [mm] and any of the leading edge's variables (``M_t``,
    ``x_A`` ... ``y_D``, ``E``); values may be complex (complex step)."""
    missing = [t for t in THICKNESS if t not in p]
    if missing:
        raise ModelError(f"design lacks the thickness zones {missing} (variables: "
                         f"{list(VARIABLES)})")
    parts = zones(n_elements)
    t = np.empty(n_elements, dtype=np.result_type(*(type(p[k]) for k in THICKNESS), float))
    for k, g in zip(THICKNESS, parts):
        t[g] = p[k]
    q = {k: v for k, v in p.items() if k not in THICKNESS}
    q["t_w"] = t
    return le.build(q, n_elements=n_elements)


def _joint_point(model: Model, name: str) -> np.ndarray:
    for j in model.joints:
        if j.name == name:
            return np.asarray(j.at)
    raise ModelError(f"model has no joint {name!r}")


def _segment_distance(P, a, b):
    """Distance of points ``P`` (n_t, 2) from segments ``a_i - b_i`` (n_t, m, 2), the
    projection parameter clipped by its real part (complex-safe), (n_t, m)."""
    d = b - a
    w = P[:, None, :] - a
    s = np.sum(w * d, axis=2) / np.sum(d * d, axis=2)
    s = np.where(np.real(s) < 0.0, 0.0, np.where(np.real(s) > 1.0, 1.0, s))
    e = w - s[..., None] * d
    return np.sqrt(np.sum(e * e, axis=2))


def _inside(P, S) -> np.ndarray:
    """Even-odd test of points ``P`` (n_t, 2) in the closed polygons ``S`` (n_t, m, 2) (real
    parts), (n_t,) bool."""
    P, S = np.real(P), np.real(S)
    a, b = S, np.roll(S, -1, axis=1)
    y = P[:, None, 1]
    cross = (a[..., 1] > y) != (b[..., 1] > y)
    x = a[..., 0] + (y - a[..., 1]) * (b[..., 0] - a[..., 0]) / np.where(
        b[..., 1] == a[..., 1], 1.0, b[..., 1] - a[..., 1])
    return np.sum(cross & (P[:, None, 0] < x), axis=1) % 2 == 1


def clearances(result) -> dict:
    """Signed distance [mm] of the joints A, B, D from the skin contour (closed by the segment
    G -> F; positive inside) at every time step: ``{"A": (n_t,), "B": ..., "D": ...}``,
    complex for a complex-step result."""
    model = result.system.model
    S = result.node_positions("skin")
    closed = np.concatenate([S, S[:, :1]], axis=1)
    out = {}
    for name, body in (("A", "crank"), ("B", "crank"), ("D", "arm")):
        P = result.point_positions(body, _joint_point(model, name))
        d = _segment_distance(P, closed[:, :-1], closed[:, 1:])
        k = np.argmin(np.real(d), axis=1)
        dist = d[np.arange(d.shape[0]), k]
        out[name] = np.where(_inside(P, S), dist, -dist)
    return out


def joint_clearance(result):
    """The least signed distance [mm] of A, B, D from the skin over the run: the exact
    minimum, the joint and time picked by the real part (its derivative is theirs, exact where
    the minimiser is unique). Complex-safe."""
    c = np.stack(list(clearances(result).values()))
    i, k = np.unravel_index(np.argmin(np.real(c)), c.shape)
    return c[i, k]


#: The responses of the design problem.
RESPONSES = {"rms_error": le.rms_error, "ks_max_stress": le.ks_max_stress,
             "max_error": le.max_error, "joint_clearance": joint_clearance}


def _settings(settings) -> Settings:
    """The runs' options as Settings: the study's by default, a dict or a Settings."""
    if isinstance(settings, Settings):
        return settings
    if settings is None:
        return le.SETTINGS
    return settings if isinstance(settings, Settings) else Settings.of(**dict(settings))


def problem(*, n_elements: int = le.N_ELEMENTS, settings: dict | Settings | None = None,
            p0: dict | None = None, variables=VARIABLES, method: str = "direct") -> Problem:
    """The design problem (module docstring): minimise ``rms_error`` over ``variables``
    subject to ``ks_max_stress <= ALLOWABLE_MPA`` and ``joint_clearance >= CLEARANCE_MM``,
    within :func:`bounds`; objective and constraints normalized by their start values."""
    p0 = start() if p0 is None else dict(p0)
    b = bounds(p0)
    return Problem(lambda p: build(p, n_elements=n_elements), p0, RESPONSES, "rms_error",
                   constraints=[Constraint("ks_max_stress", upper=ALLOWABLE_MPA),
                                Constraint("joint_clearance", lower=CLEARANCE_MM)],
                   bounds={k: b[k] for k in variables}, variables=list(variables),
                   settings=_settings(settings),
                   method=method, normalize=True)


#: Largest crank rotation [rad] accepted while the torque is held (after its ramp). A design
#: that follows the torque quasi-statically lags by ~0.0006 rad (start design and shape-error
#: optimum: 0.00061 and 0.00062 rad at dt = 0.5 ms); a snap-through turns by tenths of a rad.
HOLD_ROTATION_RAD = 0.005


def hold_rotation(result):
    """Crank rotation [rad] from the end of the torque's ramp to the end of the run
    (complex-safe)."""
    from .leading_edge import T_RAMP_S

    _, theta = result.reference("crank")
    k = int(np.argmin(np.abs(np.real(result.t) - T_RAMP_S)))
    return theta[-1] - theta[k]


def verify(p: dict, *, n_elements: int = le.N_ELEMENTS,
           settings: dict | Settings | None = None) -> dict:
    """Re-simulate design ``p`` on its own (no optimizer cache) and check what the gradient
    constraints do not see: responses, joint clearance, links crossing the skin, the crank
    rotation being monotone while the torque ramps up and the crank at rest while the torque
    is held (no snap-through, during the ramp or after it).

    Returns a dict with the responses, ``"crossings"``, ``"crank_reversal"`` (largest
    backward rotation of the crank during the ramp [rad]), ``"hold_rotation"`` (its rotation
    after the ramp [rad], at most :data:`HOLD_ROTATION_RAD`), and ``"ok"``.
    """
    from ..solve.timeloop import simulate

    res = simulate(build(p, n_elements=n_elements), settings=_settings(settings))
    values = {k: float(np.real(f(res))) for k, f in RESPONSES.items()}
    links = le.mechanism_clearance(res, {k: v for k, v in p.items()
                                         if k in le.GEOMETRY or k in ("x_A", "y_A")})
    ramp = res.t <= le.T_RAMP_S
    _, theta = res.reference("crank")
    steps = np.diff(np.real(theta[ramp]))
    turning = np.sign(np.sum(steps)) or 1.0
    reversal = float(max(0.0, -np.min(turning * steps))) if steps.size else 0.0
    hold = abs(float(np.real(hold_rotation(res))))
    ok = (res.status in ("ok", "warning") and values["ks_max_stress"] <= ALLOWABLE_MPA * 1.0001
          and values["joint_clearance"] >= CLEARANCE_MM * 0.9999 and links["crossings"] == 0
          and reversal == 0.0 and hold <= HOLD_ROTATION_RAD)
    return {**values, "crossings": links["crossings"], "crank_reversal": reversal,
            "hold_rotation": hold, "status": res.status, "ok": bool(ok)}


def tolerances_fosm(p: dict, *, n_elements: int = le.N_ELEMENTS,
                    settings: dict | Settings | None = None):
    """First-order second-moment propagation of :data:`TOLERANCES` at design ``p``: one
    direct sensitivity run over the 14 scattered variables (:func:`morphlab.studies.fosm`),
    with the probability of the KS stress exceeding :data:`ALLOWABLE_MPA` and of the joint
    clearance falling below :data:`CLEARANCE_MM`. Returns ``(UncertaintyResult,
    SensitivityResult)``."""
    from ..sensitivity.api import sensitivities
    from ..studies.uncertainty import fosm

    names = list(TOLERANCES)
    sens = sensitivities(lambda q: build(q, n_elements=n_elements), p, RESPONSES,
                         variables=names, method="direct", settings=_settings(settings))
    unc = fosm(sens, std=TOLERANCES, allowables={"ks_max_stress": (None, ALLOWABLE_MPA),
                                                 "joint_clearance": (CLEARANCE_MM, None)})
    return unc, sens


def tolerances_monte_carlo(p: dict, n: int, *, seed: int = 0, executor=None,
                           n_elements: int = le.N_ELEMENTS,
                           settings: dict | Settings | None = None,
                           progress: bool | Callable[[int, int], object] = False):
    """Monte Carlo check of :func:`tolerances_fosm`: ``n`` designs drawn from independent
    normal distributions of :data:`TOLERANCES` about ``p``, run through
    :func:`morphlab.studies.sweep` (a local process pool by default; any executor, e.g. a
    Dask client's). Returns ``(stats, table)``: per response the sample ``mean`` and ``std``
    with 95 % BCa bootstrap intervals (``mean_ci``, ``std_ci``: they hold for skewed
    responses, unlike a chi-square interval; :mod:`morphlab.studies.statistics`), the
    fraction beyond the allowables, and the :class:`~morphlab.studies.SweepResult`.
    ``progress``: a progress bar of the ``n`` runs, or ``progress(n_done, n_total)``
    (:func:`~morphlab.studies.sweep`)."""
    from ..studies import SimulationTask, monte_carlo, normal, sweep
    from ..studies.statistics import mean_std

    designs = monte_carlo({k: normal(p[k], s) for k, s in TOLERANCES.items()}, n, seed=seed)
    for k, v in p.items():
        if k not in designs:
            designs[k] = np.full(n, float(v))
    task = SimulationTask(_Zoned(n_elements), RESPONSES, _settings(settings))
    table = sweep(task, designs, executor=executor, progress=progress)
    out = {"n": int(np.sum(table.ok)), "failed": int(np.sum(~table.ok))}
    for k in RESPONSES:
        out[k] = mean_std(table.values[k][table.ok], 0.95, seed=seed)
    out["ks_max_stress"]["beyond_allowable"] = float(np.mean(
        table.values["ks_max_stress"][table.ok] > ALLOWABLE_MPA))
    out["joint_clearance"]["beyond_allowable"] = float(np.mean(
        table.values["joint_clearance"][table.ok] < CLEARANCE_MM))
    return out, table


def tolerance_distribution(p: dict):
    """The manufacturing scatter about design ``p``: independent normal variables of
    :data:`TOLERANCES` (a :class:`~morphlab.studies.JointDistribution`)."""
    from scipy import stats

    from ..studies import JointDistribution

    missing = [k for k in TOLERANCES if k not in p]
    if missing:
        raise ModelError(f"design lacks the scattered variables {missing}")
    return JointDistribution({k: stats.norm(float(p[k]), s) for k, s in TOLERANCES.items()})


#: Responses of the reliability problem.
RELIABILITY_RESPONSES = {"ks_max_stress": le.ks_max_stress, "max_error": le.max_error}


class ReliabilityProblem(NamedTuple):
    """What :func:`morphlab.studies.propagate` (or ``form``, ``importance_sampling``) takes
    for the reliability problem: ``propagate(rp.task, rp.distributions, method,
    allowables=rp.allowables, fixed=rp.fixed, ...)``."""

    task: object
    distributions: object
    fixed: dict
    allowables: dict


def reliability_problem(p: dict, *, stress_allowable: float = ALLOWABLE_MPA,
                        error_limit: float = MAX_ERROR_MM, n_elements: int = le.N_ELEMENTS,
                        settings: dict | Settings | None = None) -> ReliabilityProblem:
    """The manufacturing tolerances about design ``p`` as a reliability problem: the task
    (KS stress [MPa] and largest node error [mm], with direct gradients by the 14 variables
    of :data:`TOLERANCES`), their distribution (:func:`tolerance_distribution`), the other
    variables held at ``p`` and the failure events ``KS stress > stress_allowable`` and
    ``max_error > error_limit``."""
    from ..studies import SimulationTask

    task = SimulationTask(_Zoned(n_elements), RELIABILITY_RESPONSES, _settings(settings),
                          gradients=list(TOLERANCES))
    return ReliabilityProblem(task, tolerance_distribution(p),
                              {k: float(v) for k, v in p.items() if k not in TOLERANCES},
                              {"ks_max_stress": (None, float(stress_allowable)),
                               "max_error": (None, float(error_limit))})


def reliability(p: dict, method: str = "form", *, stress_allowable: float = ALLOWABLE_MPA,
                error_limit: float = MAX_ERROR_MM, n: int | None = None, seed: int = 0,
                executor=None, n_elements: int = le.N_ELEMENTS,
                settings: dict | Settings | None = None, mirror: bool = True):
    """``P(KS stress > stress_allowable)`` and ``P(max node error > error_limit)`` under the
    manufacturing tolerances about design ``p`` (:func:`reliability_problem`), by
    :func:`morphlab.studies.propagate`.

    Parameters
    ----------
    p : dict
        The design (:func:`start` or an optimum), with ``E``.
    method : {"form", "importance-sampling", "monte-carlo", "fosm"}
        FORM with exact (direct) gradients over the 14 variables; importance sampling
        around its design points (``n`` draws per failure event); plain Monte Carlo (``n``
        samples, ``sampling="mc"``, so the exceedance intervals are exact binomial ones);
        FOSM's normal approximation.
    stress_allowable : float
        [MPa].
    error_limit : float
        [mm].
    n, seed, executor :
        As for :func:`~morphlab.studies.propagate`.
    n_elements, settings :
        The model's skin mesh and the runs' options (default the study's).
    mirror : bool
        Search a second design point of each event from the mirror image of the first (the
        node error grows whichever way the mechanism misses: two failure modes).

    Returns
    -------
    ReliabilityResult, SampleResult or UncertaintyResult
    """
    from ..studies import SearchOptions, propagate

    rp = reliability_problem(p, stress_allowable=stress_allowable, error_limit=error_limit,
                             n_elements=n_elements, settings=settings)
    return propagate(rp.task, rp.distributions, method, allowables=rp.allowables,
                     fixed=rp.fixed, n=n, sampling="mc", seed=seed, executor=executor,
                     form_options=SearchOptions(mirror=mirror))


class _Zoned:
    """``build`` with a fixed mesh, picklable for process pools and Dask workers."""

    def __init__(self, n_elements: int):
        self.n_elements = n_elements

    def __call__(self, p: dict) -> Model:
        return build(p, n_elements=self.n_elements)
