"""Gradients of responses with respect to what they read: the discrete adjoint's input.

A response ``f(result) -> scalar`` that can be differentiated by the adjoint method also has a
``vjp(result) -> ResponseVJP`` method: its value and the derivatives ``∂f/∂q_n``, ``∂f/∂q'_n``,
``∂f/∂q''_n``, ``∂f/∂λ_n`` at every time index ``n`` it reads (``at(n)``), and the derivatives
with respect to the compiled system data it reads directly (``data``, e.g. the stress maps
``elem_B`` or a beam's node positions in its frame). The sensitivity code maps the data
derivatives to the design variables with the derivatives of that data (``docs/theory.md`` §7).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from ..errors import SensitivityError

#: The histories a response can read, in the order of a state.
HISTORY_NAMES = ("q", "v", "a", "lam")


class ResponseVJP:
    """The gradient of one response (module docstring).

    Parameters
    ----------
    value : float
        The response's value.
    terms : dict[int, dict[str, ndarray]], optional
        ``terms[n][name]``: ``∂f/∂name_n`` at time index ``n`` (``name`` in
        :data:`HISTORY_NAMES`; (n_dof,) or (n_con,)); times not listed contribute nothing.
    stream : callable, optional
        ``stream(n) -> dict[str, ndarray]`` for responses that read every time: computed on
        demand, so the adjoint sweep never holds a whole history of gradients.
    data : dict[str, ndarray], optional
        ``∂f/∂D`` for system data ``D`` the response reads, keyed as :func:`system_data`.
    """

    def __init__(self, value: float, terms: dict | None = None,
                 stream: Callable[[int], dict] | None = None, data: dict | None = None):
        self.value = float(value)
        self.terms = terms or {}
        self.stream = stream
        self.data = data or {}

    def at(self, n: int) -> dict:
        """``{name: ∂f/∂name_n}`` at time index ``n`` (empty where the response does not read
        that time)."""
        out = dict(self.terms.get(n, {}))
        if self.stream is not None:
            for name, g in self.stream(n).items():
                out[name] = out[name] + g if name in out else g
        return out


def system_data(system, key: str) -> np.ndarray:
    """The array of ``system`` a data key names: a System field (``"elem_B"``) or a body's
    table (``"body:<name>:X"``)."""
    if key.startswith("body:"):
        _, name, field = key.split(":")
        return getattr(system.body(name), field)
    return getattr(system, key)


def response_vjp(name: str, fn, result) -> ResponseVJP:
    """``fn.vjp(result)``, or a :class:`SensitivityError` saying how to differentiate a
    response without one."""
    vjp = getattr(fn, "vjp", None)
    if vjp is None:
        raise SensitivityError(
            f"response {name!r} has no gradient with respect to the histories (a vjp method), "
            "which the adjoint method needs: build it from the factories of morphlab.responses "
            "(ks_max_stress, rms_error, max_error, point_displacement, ...), or use "
            "method='direct' (any complex-safe response)")
    out = vjp(result)
    if not isinstance(out, ResponseVJP):
        raise SensitivityError(f"response {name!r}: vjp must return a ResponseVJP, got "
                               f"{type(out).__name__}")
    if not np.isfinite(out.value):
        raise SensitivityError(f"response {name!r} is not finite ({out.value!r})")
    return out
