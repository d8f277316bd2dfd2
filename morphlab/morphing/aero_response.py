"""Aerodynamic design responses of the skin's shape: drag, lift-to-drag ratio, transition, ...
of the section a run's skin shapes, as functions of a :class:`morphlab.Result` that
:func:`morphlab.sensitivities` differentiates.

NeuralFoil computes in real numbers, so these responses cannot carry a complex step through
the flow. The direct method (and the whole-run complex step) hands a response the state
``q + i h dq/dp`` of each design variable; :class:`AeroResponse` reads the skin's nodes
``x + i h dx/dp`` from it and returns ``f(x) + i Df(x)[h dx/dp]``, the directional derivative
of the flow along the imaginary part taken by a central difference of two flow analyses. The
state's sensitivity stays exact (the structure's complex step or direct differentiation); only
the last link, node positions -> flow, is a difference quotient, with a step of
:data:`STEP_MM` in the largest node displacement. Each variable then costs two flow analyses
(~0.1 s together), not two whole runs.

Units: drag in counts (1e-4), transition in x/c of the section's own chord.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from ..errors import ModelError, SensitivityError
from .aero import AeroResult, analyze, section
from .flight import FlightCondition

__all__ = ["AeroResponse", "aero_responses", "QUANTITIES", "STEP_MM"]

#: Largest node displacement [mm] of the central difference along the imaginary part. The
#: drag is smooth in the shape on this scale: along the morphing path steps of 6 and 0.6
#: micrometres at the nose agree to 1e-6 relative (tests/test_aero.py), so 1 micrometre makes
#: the truncation error ~1e-7 relative and keeps the round-off of the flow analysis (the CL
#: solve converges to 1e-12) below 1e-9 counts per mm.
STEP_MM = 1e-3

#: What :class:`AeroResponse` reads from an :class:`~morphlab.morphing.aero.AeroResult`, and
#: whether it needs the panel method's pressure distribution.
QUANTITIES = {
    "drag": (lambda r: r.cd_counts, False),
    "lift_to_drag": (lambda r: r.lift_to_drag, False),
    "transition_upper": (lambda r: r.xtr_upper, False),
    "transition_lower": (lambda r: r.xtr_lower, False),
    "lift": (lambda r: r.cl, False),
    "moment": (lambda r: r.cm, False),
    "cp_min": (lambda r: r.cp_min, True),
}


class AeroResponse:
    """An aerodynamic response of the skin's shape at one time of a run: ``f(result)``.

    Parameters
    ----------
    quantity : str
        ``"drag"`` [counts], ``"lift_to_drag"``, ``"transition_upper"``,
        ``"transition_lower"`` [x/c], ``"lift"``, ``"moment"``, ``"cp_min"``.
    condition : FlightCondition
        Usually with a target ``cl`` (the sailplane's weight sets the lift; the angle of
        attack is found again for every shape).
    body : str, optional
        The skin beam; default ``"skin"``.
    time : int, optional
        Time index of the shape; default the last.
    step : float, optional
        Largest node displacement [mm] of the central difference along a complex state's
        imaginary part (module docstring); default :data:`STEP_MM`.
    **options
        Passed to :func:`~morphlab.morphing.aero.analyze` (``model_size``, ...).

    Notes
    -----
    Works with ``method="direct"``, ``"complex-step"`` and the finite differences of
    :func:`morphlab.sensitivities` (and so in :class:`morphlab.studies.Problem`); it has no
    ``vjp``, so not with the adjoint. Each complex call costs two flow analyses and the
    nominal one is kept from the last real or complex call on the same shape.
    """

    def __init__(self, quantity: str, condition: FlightCondition, *, body: str = "skin",
                 time: int = -1, step: float = STEP_MM, **options):
        if quantity not in QUANTITIES:
            raise ModelError(f"unknown aerodynamic quantity {quantity!r}; known: "
                             f"{sorted(QUANTITIES)}")
        if not isinstance(condition, FlightCondition):
            raise ModelError(f"condition must be a FlightCondition, got "
                             f"{type(condition).__name__}")
        if not (isinstance(step, float) and 0.0 < step <= 0.1):
            raise ModelError(f"step must be a float in (0, 0.1] mm, got {step!r}")
        self.quantity, self.condition, self.body, self.time = quantity, condition, body, time
        self.step = step
        self.options = {"pressure": QUANTITIES[quantity][1], **options}
        self._last: tuple[bytes, float, float] | None = None

    def _read(self, flow: AeroResult) -> float:
        return float(QUANTITIES[self.quantity][0](flow))

    def analysis(self, skin_nodes: ArrayLike, alpha_start: float | None = None) -> AeroResult:
        """The flow about the section of real skin nodes (n_nodes, 2) [mm]."""
        opts = dict(self.options)
        if alpha_start is not None and self.condition.cl is not None:
            opts["alpha_start"] = alpha_start
        return analyze(section(skin_nodes), self.condition, **opts)

    def _nominal(self, x: np.ndarray) -> tuple[float, float]:
        key = x.tobytes()
        if self._last is None or self._last[0] != key:
            r = self.analysis(x)
            self._last = (key, self._read(r), r.alpha)
        return self._last[1], self._last[2]

    def of_nodes(self, skin_nodes: ArrayLike):
        """The response of a skin given by its nodes (n_nodes, 2) [mm]: a float, or for
        complex nodes with a nonzero imaginary part ``d`` the complex ``f(x) + i Df(x)[d]``
        (module docstring)."""
        nodes = np.asarray(skin_nodes)
        if nodes.ndim != 2 or nodes.shape[1] != 2:
            raise ModelError(f"skin nodes must have shape (n_nodes, 2), got {nodes.shape}")
        x = np.ascontiguousarray(np.real(nodes), dtype=float)
        f0, alpha = self._nominal(x)
        if not np.iscomplexobj(nodes):
            return f0
        d = np.imag(nodes)
        size = float(np.max(np.abs(d)))
        if size == 0.0:
            return complex(f0, 0.0)
        if not np.isfinite(size):
            raise SensitivityError(f"aerodynamic response {self.quantity!r}: the skin's node "
                                   "sensitivities are not finite")
        t = self.step / size
        plus = self._read(self.analysis(x + t * d, alpha))
        minus = self._read(self.analysis(x - t * d, alpha))
        return complex(f0, (plus - minus) / (2.0 * t))

    def __call__(self, result):
        return self.of_nodes(result.node_positions(self.body, self.time))

    def __repr__(self) -> str:
        return f"AeroResponse({self.quantity!r}, {self.condition.name or self.condition})"


def aero_responses(condition: FlightCondition, **options) -> dict[str, AeroResponse]:
    """The design responses ``drag`` [counts], ``lift_to_drag``, ``transition_upper`` and
    ``transition_lower`` [x/c] at one flight condition (see :class:`AeroResponse`)."""
    return {q: AeroResponse(q, condition, **options)
            for q in ("drag", "lift_to_drag", "transition_upper", "transition_lower")}
