"""The first-order reliability method (FORM): the search for the design point.

For a limit state ``g(u)`` in the independent standard normal space of
:class:`~.distributions.JointDistribution` (failure where ``g <= 0``), the design point ``u*``
is the point of the limit surface ``g = 0`` nearest the origin; ``β = α · u*`` with
``α = -∇g / |∇g|`` at ``u*``, and FORM's failure probability is ``Φ(-β)``.

:func:`search` is the improved Hasofer–Lind / Rackwitz–Fiessler iteration (iHL-RF: Zhang &
Der Kiureghian, *Finite element reliability methods for inelastic structures*, UCB/SEMM-97/05,
1997; Der Kiureghian, *First- and second-order reliability methods*, in Engineering Design
Reliability Handbook, CRC 2005, ch. 14). The HL-RF direction

    d = ((∇g · u - g) / |∇g|²) ∇g - u

is taken with an Armijo line search on the merit function ``m(u) = |u|²/2 + c |g(u)|``,
``c = 2 max(|u|, |u + d|) / |∇g|``, for which ``d`` is a descent direction (``∇m · d < 0``
while ``c > |u| / |∇g|``); so the iteration converges where plain HL-RF cycles. It stops
when ``|g| <= tol_g |g(u_0)|`` and ``|u - (α · u) α| <= tol_u max(|u|, 1)`` (the point on the
surface, aligned with its normal).

The search is a generator: it yields the points it needs and receives ``(g, ∇g)`` there (or
None for a failed run), so that the caller can evaluate the points of several searches in
one sweep.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..errors import StudyError

ARMIJO = 1e-4  # sufficient decrease of the merit function, a fraction of the first-order one
ROUND_OFF = 1e-12  # a predicted merit decrease this small (relative) is below round-off


@dataclass
class SearchOptions:
    """Stopping rules of :func:`search`.

    Attributes
    ----------
    tol_g : float
        ``|g|`` relative to its value at the start.
    tol_u : float
        Distance of ``u`` from the normal's line through the origin, relative to ``|u|``.
    max_iter : int
        HL-RF iterations.
    max_halvings : int
        Step halvings of one line search.
    mirror : bool
        Search again from the mirror image ``-u*`` of each design point, for a second failure
        mode (:mod:`.reliability`).
    """

    tol_g: float = 1e-6
    tol_u: float = 1e-6
    max_iter: int = 100
    max_halvings: int = 20
    mirror: bool = False

    def __post_init__(self):
        for name in ("tol_g", "tol_u"):
            v = getattr(self, name)
            if not (isinstance(v, float) and 0.0 < v < 1.0):
                raise StudyError(f"SearchOptions.{name} must be a float in (0, 1), got {v!r}")
        for name in ("max_iter", "max_halvings"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, int) or v < 1:
                raise StudyError(f"SearchOptions.{name} must be an integer >= 1, got {v!r}")
        if not isinstance(self.mirror, bool):
            raise StudyError(f"SearchOptions.mirror must be True or False, got {self.mirror!r}")


@dataclass
class SearchState:
    """Where a search ended: the last accepted point and what it took."""

    u: np.ndarray
    g: float = np.nan
    grad: np.ndarray = None
    g0: float = np.nan
    iterations: int = 0
    evaluations: int = 0
    converged: bool = False
    message: str = ""
    history: list = field(default_factory=list)


def search(u0: np.ndarray, options: SearchOptions):
    """The iHL-RF iteration (module docstring) as a generator: yields points ``u`` (d,),
    receives ``(g, grad_u)`` or None (a failed run); returns a :class:`SearchState`."""
    state = SearchState(np.asarray(u0, dtype=float).copy())
    out = yield state.u
    state.evaluations += 1
    if out is None:
        state.message = "the run at the start point failed"
        return state
    g, G = out
    state.g, state.grad, state.g0 = g, G, g
    scale = abs(g)
    u = state.u
    for it in range(options.max_iter + 1):
        gn = float(np.linalg.norm(G))
        state.history.append({"u": u.copy(), "g": g, "beta": _beta(u, g, G)})
        if not (np.isfinite(g) and np.all(np.isfinite(G))) or gn == 0.0:
            state.message = f"the limit state has {'no' if gn == 0 else 'a non-finite'} " \
                            f"gradient at iteration {it}"
            return state
        scale = scale if scale > 0 else gn  # started on the surface: measure g by |grad|
        alpha = -G / gn
        off_line = np.linalg.norm(u - (alpha @ u) * alpha)
        if abs(g) <= options.tol_g * scale and off_line <= options.tol_u * max(
                np.linalg.norm(u), 1.0):
            state.converged, state.message = True, f"converged in {it} iterations"
            return state
        if it == options.max_iter:
            break
        d = ((G @ u - g) / gn**2) * G - u
        c = 2.0 * max(np.linalg.norm(u), np.linalg.norm(u + d)) / gn
        merit = 0.5 * u @ u + c * abs(g)
        slope = u @ d - c * abs(g)  # directional derivative of the merit along d (< 0)
        step = 1.0
        for _ in range(options.max_halvings + 1):
            trial = u + step * d
            out = yield trial
            state.evaluations += 1
            if out is not None and np.isfinite(out[0]) and (
                    0.5 * trial @ trial + c * abs(out[0]) <= merit + ARMIJO * step * slope):
                break
            step *= 0.5
        else:
            if abs(slope) <= ROUND_OFF * max(merit, 1.0):  # nothing left above round-off
                state.converged = True
                state.message = f"converged to round-off in {it} iterations"
            else:
                state.message = f"the line search found no decrease at iteration {it}"
            return state
        u, (g, G) = trial, out
        state.u, state.g, state.grad, state.iterations = u, g, G, it + 1
    state.message = f"not converged in {options.max_iter} iterations (|g| = {abs(g):.3g})"
    return state


def _beta(u: np.ndarray, g: float, G: np.ndarray) -> float:
    """Distance of the origin from the limit surface linearised at ``u``, signed positive
    when the origin is on the safe side: ``(g - ∇g · u) / |∇g|``."""
    gn = float(np.linalg.norm(G))
    return float((g - G @ u) / gn) if gn > 0 else np.nan


def beta_of(state: SearchState) -> float:
    """The reliability index of a finished search (:func:`_beta` at its last point)."""
    return _beta(state.u, state.g, state.grad) if state.grad is not None else np.nan


def importance_factors(alpha: np.ndarray, jac_xu: np.ndarray) -> np.ndarray:
    """Importance vector ``γ`` of the variables (unit length; ``γ_i²`` sum to 1):
    ``γ = α J_ux Ŝ / |α J_ux Ŝ|`` with ``J_ux = (dx/du)⁻¹`` and ``Ŝ`` the diagonal of the
    standard deviations of the linearised variables, ``sqrt(diag(J_xu J_xuᵀ))`` (Der
    Kiureghian 2005, eq. 14.48). For independent variables it is ``α`` itself."""
    J_ux = np.linalg.inv(jac_xu)
    s_hat = np.sqrt(np.sum(jac_xu * jac_xu, axis=1))
    gamma = (alpha @ J_ux) * s_hat
    return gamma / np.linalg.norm(gamma)
