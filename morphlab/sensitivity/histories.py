"""Results of perturbed designs and the histories a sensitivity run keeps.

A direct run keeps the sensitivity histories ``dx/dp`` the responses read (:func:`to_store`);
each design variable's complex history ``x + i h dx/dp`` is formed on demand for the responses
(:class:`PerturbedResult`), so responses are differentiated by complex step over them.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from ..compile import System
from ..errors import SensitivityError
from ..results.result import Result
from ..solve.settings import Settings
from .designs import CS_STEP

HISTORIES = ("q", "v", "a", "lam")


def _lazy_history(name: str) -> property:
    """A history of :class:`_PerturbedResult`, formed on first access."""

    def get(self):
        arr = self._histories.get(name)
        if arr is None:
            base, d, col = self._source
            if name not in d:
                raise SensitivityError(
                    f"the sensitivity history of {name!r} was not kept (kept: {sorted(d)}); "
                    f"run sensitivities(..., store='all') or store=(..., {name!r})")
            arr = getattr(base, name) + 1j * CS_STEP * d[name][col]
            self._histories[name] = arr
        return arr

    def set(self, value):
        if value is not None:
            self._histories[name] = value

    return property(get, set)


class PerturbedResult(Result):
    """A complex Result of one design variable: histories ``x + i h dx/dp_col`` on the complex
    system. Each history is formed when a response first reads it (a response of the
    positions needs neither velocities, accelerations nor multipliers: with many variables
    the other complex copies cost more than the response)."""

    q = _lazy_history("q")
    v = _lazy_history("v")
    a = _lazy_history("a")
    lam = _lazy_history("lam")

    def __init__(self, base: Result, system: System, d: dict, col: int):
        self._histories: dict = {}
        self._source = (base, d, col)
        super().__init__(
            system=system, settings=base.settings, t=base.t, q=None, v=None, a=None, lam=None,
            newton_iterations=base.newton_iterations,
            constraint_violation=base.constraint_violation,
            velocity_violation=base.velocity_violation, status=base.status,
            message=base.message, scale=base.scale)


class _ProbeResult(Result):
    """A two-step Result of the nominal model (initial state, zero rates) that records which
    histories are read: what a direct run must keep for the responses."""

    def __init__(self, system: System, settings: Settings):
        self.read: set = set()
        n_dof, n_con = system.n_dof, system.n_con
        q = np.repeat(np.real(system.q0)[None, :], 2, axis=0)
        zeros = np.zeros((2, n_dof))
        self._h = {"q": q, "v": zeros, "a": zeros, "lam": np.zeros((2, n_con))}
        super().__init__(system=system, settings=settings,
                         t=settings.t_start + settings.h * np.arange(2.0), q=None, v=None,
                         a=None, lam=None, newton_iterations=np.ones(2, dtype=np.int64),
                         constraint_violation=np.zeros(2), velocity_violation=np.zeros(2))

    def _get(self, name):
        self.read.add(name)
        return self._h[name]

    q = property(lambda self: self._get("q"), lambda self, value: None)
    v = property(lambda self: self._get("v"), lambda self, value: None)
    a = property(lambda self: self._get("a"), lambda self, value: None)
    lam = property(lambda self: self._get("lam"), lambda self, value: None)


def to_store(store, responses: Mapping, system: System, settings: Settings) -> tuple:
    """The sensitivity histories a direct run keeps in full (see ``store`` of
    :func:`sensitivities`)."""
    if store == "all":
        return HISTORIES
    if store != "auto":
        return tuple(h for h in HISTORIES if h in store)
    probe = _ProbeResult(system, settings)
    try:
        with np.errstate(all="ignore"):
            for fn in responses.values():
                fn(probe)
    except Exception:  # a response that cannot run on the probe: keep everything
        return HISTORIES
    return tuple(h for h in HISTORIES if h in probe.read)
