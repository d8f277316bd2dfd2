"""Responses of the joint reactions (:mod:`morphlab.results.reactions`): one component at one
time (:class:`reaction`) and its peak over a run (:class:`peak_reaction`), both complex-safe
and with a ``vjp`` for the adjoint method. Imported into :mod:`morphlab.results.responses`
(``ml.responses.reaction``, ``ml.responses.peak_reaction``)."""

from __future__ import annotations

import numpy as np

from ..errors import ModelError
from . import reactions
from .gradients import ResponseVJP
from .responses import ks_abs, ks_rel, rms

#: Names of the reaction components a response can take.
COMPONENTS = {0: "Fx", 1: "Fy", 2: "M", "magnitude": "F"}

#: Times per block when a response runs over a whole history (bounds the complex copies).
BLOCK = 1024


class reaction:  # noqa: N801 - a response factory
    """Response: one component (0: F_x, 1: F_y, 2: moment) of the reaction of ``joint`` at
    one time (:meth:`Result.reaction`, in the frame of body ``frame`` or global). Has
    ``vjp`` (the multipliers, the coordinates and a slide row's guide angle it reads)."""

    def __init__(self, joint: str, component: int, time_index: int = -1,
                 frame: str | None = None):
        if component not in (0, 1, 2):
            raise ModelError(f"component must be 0 (F_x), 1 (F_y) or 2 (moment), got "
                             f"{component!r}")
        self.joint, self.component, self.time_index, self.frame = (joint, component,
                                                                   time_index, frame)
        self.__name__ = f"reaction_{joint}_{('Fx', 'Fy', 'M')[component]}"

    def __call__(self, result):
        return reactions.reaction(result, self.joint, self.frame)[self.time_index,
                                                                  self.component]

    def vjp(self, result) -> ResponseVJP:
        n = self.time_index % result.n_t
        dq, dlam, du = reactions.reaction_vjp(result, self.joint, self.component, n,
                                              self.frame)
        return ResponseVJP(float(np.real(self(result))), terms={n: {"q": dq, "lam": dlam}},
                           data=du)


class peak_reaction:  # noqa: N801 - a response factory
    """Response: the peak over a run of a reaction of ``joint`` (the largest force on a pin
    or a guide, the largest drive torque), as a Kreisselmeier–Steinhauser aggregate over the
    time steps: smooth, so it has a gradient, and an upper bound of the peak.

    Parameters
    ----------
    joint : str
        A joint, fix or drive (its reaction: :meth:`Result.reaction`).
    component : 0, 1, 2 or "magnitude"
        The force ``F_x`` (0), ``F_y`` (1) [force], the moment (2) [force·length], each by
        its magnitude ``|F_x|`` ..., or the force's magnitude ``sqrt(F_x² + F_y²)``
        ("magnitude", the default).
    frame : str, optional
        Body whose frame the force components are taken in (default global).
    rho : float, optional
        Absolute aggregation parameter [1/unit of the reaction]: the aggregate exceeds the
        peak by at most ``ln(2 N)/rho`` over ``N`` times.
    rho_rel : float
        Without ``rho``: the scale-free form (:func:`~morphlab.results.responses.ks_rel`,
        the default), which exceeds the peak by at most ``s ln(2 N)/rho_rel``, ``s`` the RMS
        of the reaction over the run; much less where few times are near the peak.
    times : slice, optional
        The time steps aggregated (default all).

    Has ``vjp`` (the adjoint method): the derivatives with respect to ``q`` and ``lam`` at
    every time, streamed a block of steps at a time, and to a slide row's guide direction.
    """

    def __init__(self, joint: str, component: int | str = "magnitude", *,
                 frame: str | None = None, rho: float | None = None, rho_rel: float = 100.0,
                 times: slice | None = None):
        if isinstance(component, (bool, np.bool_)) or component not in COMPONENTS:
            raise ModelError(f"peak_reaction({joint!r}): component must be 0 (F_x), 1 (F_y), "
                             f"2 (moment) or 'magnitude', got {component!r}")
        if rho is not None and not (isinstance(rho, (int, float)) and rho > 0):
            raise ModelError(f"peak_reaction({joint!r}): rho must be a positive number, got "
                             f"{rho!r}")
        if not (isinstance(rho_rel, (int, float)) and rho_rel > 0):
            raise ModelError(f"peak_reaction({joint!r}): rho_rel must be a positive number, "
                             f"got {rho_rel!r}")
        self.joint, self.component, self.frame = joint, component, frame
        self.rho, self.rho_rel, self.times = rho, rho_rel, times
        self.__name__ = f"peak_reaction_{joint}_{COMPONENTS[component]}"

    def _of_forces(self, F):
        """The aggregated values of the reactions ``F`` (n, 3): a component or the force's
        magnitude (complex-safe)."""
        if self.component == "magnitude":
            return np.sqrt(F[:, 0] * F[:, 0] + F[:, 1] * F[:, 1])
        return F[:, self.component]

    def _aggregate(self, v):
        return ks_abs(v, self.rho) if self.rho is not None else ks_rel(v, self.rho_rel)

    def __call__(self, result):
        F = reactions.reaction(result, self.joint, self.frame)
        if self.times is not None:
            F = F[self.times]
        if F.shape[0] == 0:
            raise ModelError(f"peak_reaction({self.joint!r}): no times to aggregate (times="
                             f"{self.times!r} of {result.n_t})")
        return self._aggregate(self._of_forces(F))

    def vjp(self, result) -> ResponseVJP:
        """Value and gradient: the aggregate's weights per time from the real reactions, the
        reactions' partial derivatives per block of steps on demand
        (:func:`~morphlab.results.reactions.reaction_partials`)."""
        s = result.system
        if result.lam is None or result.q is None:
            raise ModelError("peak_reaction needs the histories of lam and q")
        idx = np.arange(result.n_t)[self.times if self.times is not None else slice(None)]
        if idx.size == 0:
            raise ModelError(f"peak_reaction({self.joint!r}): no times to aggregate")
        F = np.real(reactions.reaction(result, self.joint, self.frame))[idx]
        value, w = _ks_gradient(np.real(self._of_forces(F)), self.rho, self.rho_rel)
        weight = np.zeros(result.n_t)
        weight[idx] = w
        G = np.zeros((result.n_t, 3))  # d value / d F at every time
        G[idx] = w[:, None] * self._value_gradient(F)
        data: dict = {}
        for k0 in range(0, idx.size, BLOCK):
            ns = idx[k0:k0 + BLOCK]
            part = reactions.reaction_data_gradient(s, self.joint, self.frame, result.q[ns],
                                                    result.lam[ns], G[ns])
            for key, val in part.items():
                data[key] = data[key] + val if key in data else val

        def stream(ns):
            ns = np.asarray(ns, dtype=np.int64)
            dq = np.zeros((ns.size, s.n_dof))
            dlam = np.zeros((ns.size, s.n_con))
            sel = np.flatnonzero(weight[ns] != 0.0)
            if sel.size:
                m = ns[sel]
                _, dofs, dFq, rows, dFl = reactions.reaction_partials(
                    s, self.joint, self.frame, result.q[m], result.lam[m])
                dq[np.ix_(sel, dofs)] = np.einsum("kc,kjc->kj", G[m], dFq)
                dlam[np.ix_(sel, rows)] = np.einsum("kc,kjc->kj", G[m], dFl)
            return {"q": dq, "lam": dlam}

        return ResponseVJP(value, stream=stream, data=data)

    def _value_gradient(self, F) -> np.ndarray:
        """``d value_n / d F_n`` (n, 3) of the aggregated value at each time (real ``F``; the
        magnitude's gradient is taken as zero where the force vanishes)."""
        out = np.zeros(F.shape)
        if self.component == "magnitude":
            mag = np.sqrt(F[:, 0] ** 2 + F[:, 1] ** 2)
            safe = np.where(mag > 0, mag, 1.0)
            out[:, 0] = np.where(mag > 0, F[:, 0] / safe, 0.0)
            out[:, 1] = np.where(mag > 0, F[:, 1] / safe, 0.0)
        else:
            out[:, self.component] = 1.0
        return out


def _ks_gradient(v: np.ndarray, rho: float | None, rho_rel: float) -> tuple[float, np.ndarray]:
    """``ks_abs(v, rho)`` (or ``ks_rel(v, rho_rel)`` without ``rho``) of real values ``v``
    (n,) and its gradient (n,), in closed form: with ``x = v / s`` (``s = 1``, or the RMS
    ``s`` of ``v`` in the scale-free form) and ``k = ks_abs(x)``, ``dk/dx_n = (e⁺_n - e⁻_n) /
    sum(e⁺ + e⁻)``, ``e± = exp(rho (±x - max|x|))``; the scale-free value ``s k`` adds the
    derivative of ``s``, ``ds/dv_n = v_n / (n s)``."""
    s = 1.0 if rho is not None else float(rms(v))
    if not s > 0:
        raise ModelError("peak_reaction: the reaction is zero at every time aggregated, so "
                         "its scale-free aggregate is undefined; give rho= (absolute)")
    r = rho if rho is not None else rho_rel
    x = v / s
    top = float(np.max(np.abs(x)))
    ep, em = np.exp(r * (x - top)), np.exp(r * (-x - top))
    total = float(np.sum(ep + em))
    k = top + np.log(total) / r
    g = (ep - em) / total
    if rho is not None:
        return float(k), g
    ds = v / (v.size * s)
    return float(s * k), k * ds + g - float(np.sum(g * x)) * ds
