"""Complex-safe response functions of a :class:`~morphlab.results.result.Result`.

A response is any function ``f(result) -> scalar``. :func:`morphlab.sensitivities` differentiates
it by complex step over perturbed histories, so it must keep imaginary parts: use ``+ - * /``,
``np.sqrt``, ``np.exp``, ``np.log``, sums and means; pick extrema by the real part
(:func:`max_by_real`) instead of ``np.max``; never ``abs``, ``np.abs``, ``float()`` or
``np.hypot`` on values that carry a derivative.

The factories below return such functions; their values are plain numbers for a real result.
The joint reactions' responses (:class:`reaction`, :class:`peak_reaction`) live in
:mod:`morphlab.results.reaction_responses` and are imported here.
"""

from __future__ import annotations

import warnings
from collections.abc import Callable

import numpy as np

from ..errors import ModelError
from .gradients import ResponseVJP, StressMap, node_positions_vjp, rigid_point_vjp


def ks(values, rho: float):
    """Kreisselmeier–Steinhauser aggregate, a smooth upper bound of ``max(values)``.

    ``KS = s* + ln(sum exp(rho (v - s*))) / rho`` with ``s* = max(real(v))`` (shift against
    overflow; it cancels exactly). ``max(v) <= KS <= max(v) + ln(N)/rho`` for N values.

    Parameters
    ----------
    values : array_like
        Any shape; aggregated over all entries.
    rho : float
        Aggregation parameter [1/unit of values]; larger is closer to the max.
    """
    return _ks_signed(values, rho, (1.0,))


def ks_abs(values, rho: float):
    """KS aggregate of the magnitude: of ``values`` and ``-values`` together (complex-safe),
    ``max|v| <= KS <= max|v| + ln(2N)/rho``."""
    return _ks_signed(values, rho, (1.0, -1.0))


def _ks_signed(values, rho: float, signs: tuple):
    """KS of the entries ``sign * v`` for every sign in ``signs`` (each +1 or -1).

    Complex input (a complex-step perturbed history) is summed as
    ``sum exp(rho (x - s*)) (cos(rho y) + i sin(rho y))`` with real exponentials: the same
    complex number as ``sum exp(rho (v - s*))`` (every factor exact to round-off), cheaper
    than NumPy's complex ``exp`` on the many stresses of a run (and without
    the trigonometry when the imaginary parts are a complex step's). The input is read in
    place, in any layout, and one scratch array holds the weights of every sign: fresh
    arrays of this size would cost page faults on every call.
    """
    v = np.asarray(values)
    if v.size == 0:
        raise ModelError("ks: no values to aggregate")
    if not rho > 0:
        raise ModelError(f"ks: rho must be positive, got {rho!r}")
    x = np.real(v)
    s = max(float(np.max(x)) if sg > 0 else -float(np.min(x)) for sg in signs)
    w = np.empty(x.shape)
    complex_input = np.iscomplexobj(v)
    cos_y = sin_y = None
    if complex_input:
        y = np.imag(v)
        if rho * float(np.max(np.abs(y))) <= 1e-8:
            # cos(rho y) rounds to 1 and sin(rho y) to rho y in double precision (errors
            # (rho y)²/2 and (rho y)³/6 relative, below half an ulp): the complex step's case
            sin_y = y
        else:
            cos_y, sin_y = np.cos(rho * y), np.sin(rho * y) / rho
    re = im = 0.0
    for sg in signs:
        np.multiply(x, sg * rho, out=w)
        w -= rho * s
        np.exp(w, out=w)
        re += float(np.sum(w)) if cos_y is None else float(np.sum(w * cos_y))
        if complex_input:
            im += sg * rho * float(np.sum(np.multiply(w, sin_y, out=w)))  # w is spent here
    if complex_input:
        return s + np.log(complex(re, im)) / rho
    return s + float(np.log(re)) / rho


def max_by_real(values):
    """The entry with the largest real part (keeps its imaginary part)."""
    v = np.asarray(values).ravel()
    return v[int(np.argmax(np.real(v)))]


def rms(values):
    """Root mean square ``sqrt(mean(v²))`` (complex-safe)."""
    v = np.asarray(values).ravel()
    return np.sqrt(np.mean(v * v))


def distance(a, b):
    """Euclidean distance along the last axis, ``sqrt(sum((a - b)²))`` (complex-safe)."""
    d = np.asarray(a) - np.asarray(b)
    return np.sqrt(np.sum(d * d, axis=-1))


def ks_rel(values, rho_rel: float):
    """Scale-free KS aggregate of the magnitudes: ``s * ks_abs(values / s, rho_rel)`` with
    ``s`` the RMS of the values (complex-safe, part of the function, so differentiated with
    it). ``max|v| <= KS_rel <= max|v| + s ln(2N)/rho_rel <= max|v| (1 + ln(2N)/rho_rel)``."""
    v = np.asarray(values)
    s = rms(v)
    return s * ks_abs(v / s, rho_rel)


class ks_max_stress:  # noqa: N801 - a response factory, named like the functions it replaced
    """Response: Kreisselmeier–Steinhauser maximum of the stress magnitude of ``body`` over
    elements, element ends, both fibres and time steps (paper eq. 40).

    Parameters
    ----------
    body : str
        A beam.
    rho : float, optional
        Absolute aggregation parameter [1/stress unit] (the paper's form): with N stress
        values the aggregate exceeds the largest magnitude by at most ``ln(2N)/rho``.
    rho_rel : float
        Without ``rho``: the scale-free form :func:`ks_rel` (the default), which exceeds the
        largest magnitude by at most ``s ln(2N)/rho_rel``, ``s`` the RMS stress: a bounded
        relative amount (about 0.1 for a run of ~10^4 values, much less where few values are
        near the peak), whatever the stress scale.
    times : slice, optional
        The time steps aggregated (default: all).
    rho_ks : float, optional
        The earlier name of ``rho`` (deprecated).

    Has ``vjp`` (the adjoint method): the derivatives with respect to ``q`` at every time,
    streamed, and to the stress maps ``elements.B``.
    """

    def __init__(self, body: str, rho: float | None = None, *, rho_rel: float = 100.0,
                 times: slice | None = None, rho_ks: float | None = None):
        if rho_ks is not None:  # the earlier name of ``rho``
            warnings.warn("ks_max_stress(rho_ks=...) is now ks_max_stress(rho=...); without "
                          "rho the aggregate is scale-free (rho_rel)", DeprecationWarning,
                          stacklevel=2)
            rho = rho_ks if rho is None else rho
        if rho is not None and not rho > 0:
            raise ModelError(f"ks_max_stress: rho must be positive, got {rho!r}")
        if not rho_rel > 0:
            raise ModelError(f"ks_max_stress: rho_rel must be positive, got {rho_rel!r}")
        self.body, self.rho, self.rho_rel, self.times = body, rho, rho_rel, times
        self.__name__ = f"ks_max_stress_{body}"

    def __call__(self, result):
        s = result.stress(self.body)
        if self.times is not None:
            s = s[self.times]
        return ks_abs(s, self.rho) if self.rho is not None else ks_rel(s, self.rho_rel)

    def vjp(self, result) -> ResponseVJP:
        """Value and gradient over chunks of time steps (:class:`StressMap`): passes for the
        scale (RMS, largest magnitude), the aggregate, and (relative form) the weighted sum
        its derivative needs; the derivatives with respect to ``q_n`` are formed when the
        sweep reaches a block of steps, so no history of stresses or gradients is held."""
        idx = np.arange(result.n_t)[self.times if self.times is not None else slice(None)]
        smap = StressMap(result, self.body, idx)
        n_val, ssq, peak = 0, 0.0, 0.0
        for _, _, sig, _ in smap.chunks():
            n_val += sig.size
            ssq += float(np.sum(sig * sig))
            peak = max(peak, float(np.max(np.abs(sig), initial=0.0)))
        if n_val == 0:
            raise ModelError("ks: no values to aggregate")
        s = np.sqrt(ssq / n_val) if self.rho is None else 1.0
        rho = self.rho if self.rho is not None else self.rho_rel
        # KS of the magnitudes of x = sig / s: peak + ln(sum exp(rho (±x - peak))) / rho
        top = peak / s
        total = sum(float(np.sum(np.exp(rho * (x - top)) + np.exp(rho * (-x - top))))
                    for x in (sig / s for _, _, sig, _ in smap.chunks()))
        k = top + np.log(total) / rho

        def weights(sig):  # dk/dx of the chunk's values
            x = sig / s
            return np.exp(rho * (x - k)) - np.exp(rho * (-x - k))

        if self.rho is None:  # KS_rel = s k(x): d/dsig = k ds + gk - (sum gk x) ds, ds = x/N
            c = sum(float(np.sum(weights(sig) * sig / s)) for _, _, sig, _ in smap.chunks())

            def G_of(sig):
                ds = sig / (n_val * s)
                return k * ds + weights(sig) - c * ds
            value = s * k
        else:
            G_of, value = weights, k
        dB = np.zeros(smap.B.shape)
        for _, _, sig, qe in smap.chunks():
            dB += np.einsum("ken,kej->enj", G_of(sig), qe)
        read = np.zeros(result.n_t, dtype=bool)
        read[idx] = True

        def stream(ns):  # one sparse product each way for a block of steps
            dq = np.zeros((ns.size, smap.n_dof))
            sel = read[ns]
            if sel.any():
                dq[sel] = smap.q_gradient(G_of(smap.stress(result.q[ns[sel]])))
            return {"q": dq}

        return ResponseVJP(value, stream=stream,
                           data={"elements.B": _full_elem_B(result, self.body,
                                                        dB.reshape(-1, 2, 2, 6))})


def _full_elem_B(result, body: str, dB: np.ndarray) -> np.ndarray:
    """``dB`` of one beam's elements placed in an array shaped like the stress maps
    ``elements.B``."""
    out = np.zeros(np.shape(result.system.arrays.elements.B))
    out[result.system.body(body).elements] = dB
    return out


def _target_for(target, n_nodes: int) -> np.ndarray:
    return np.asarray(target(n_nodes) if callable(target) else target)


def node_errors(body: str, target, time_index: int = -1) -> Callable:
    """Response factory: distance of every node of ``body`` from ``target`` (n_nodes, 2), or
    ``target(n_nodes)``, at one time (paper eq. 41); returns an array, use with
    :func:`rms_error` / :func:`max_error`."""

    def errors(result):
        pos = result.node_positions(body, time_index)
        tgt = _target_for(target, pos.shape[0])
        if pos.shape != tgt.shape:
            raise ModelError(f"target has shape {tgt.shape}, beam {body!r} has "
                             f"{pos.shape[0]} nodes")
        return distance(pos, tgt)

    return errors


class _NodeErrorResponse:
    """A scalar of the node errors of a beam against a target at one time, with its vjp."""

    def __init__(self, body: str, target, time_index: int = -1):
        self.body, self.target, self.time_index = body, target, time_index
        self._errors = node_errors(body, target, time_index)

    def vjp(self, result) -> ResponseVJP:
        pos = np.real(result.node_positions(self.body, self.time_index))
        d = pos - _target_for(self.target, pos.shape[0])
        e = np.sqrt(np.sum(d * d, axis=1))
        value, de = self._of_errors(e)
        G = de[:, None] * d / np.where(e > 0, e, 1.0)[:, None]
        dq, dX = node_positions_vjp(result, self.body, self.time_index, G)
        n = self.time_index % result.n_t
        return ResponseVJP(value, terms={n: {"q": dq}}, data={f"body:{self.body}:X": dX})


class rms_error(_NodeErrorResponse):  # noqa: N801 - a response factory
    """Response: RMS of the node errors of ``body`` against ``target`` (n_nodes, 2) (or
    ``target(n_nodes)``) at one time (paper eq. 42). Has ``vjp``."""

    def __init__(self, body: str, target, time_index: int = -1):
        super().__init__(body, target, time_index)
        self.__name__ = f"rms_error_{body}"

    def __call__(self, result):
        return rms(self._errors(result))

    @staticmethod
    def _of_errors(e):
        value = float(np.sqrt(np.mean(e * e)))
        return value, e / (e.size * value)


class max_error(_NodeErrorResponse):  # noqa: N801 - a response factory
    """Response: the largest node error against ``target`` (exact max, complex-safe; its
    derivative is that of the maximising node). Has ``vjp``."""

    def __init__(self, body: str, target, time_index: int = -1):
        super().__init__(body, target, time_index)
        self.__name__ = f"max_error_{body}"

    def __call__(self, result):
        return max_by_real(self._errors(result))

    @staticmethod
    def _of_errors(e):
        k = int(np.argmax(e))
        de = np.zeros_like(e)
        de[k] = 1.0
        return float(e[k]), de


class point_displacement:  # noqa: N801 - a response factory
    """Response: displacement component (0: x, 1: y) of the material point initially at
    ``at`` at one time. Has ``vjp``."""

    def __init__(self, body: str, at, component: int, time_index: int = -1):
        if component not in (0, 1):
            raise ModelError(f"component must be 0 (x) or 1 (y), got {component!r}")
        self.body, self.at, self.component, self.time_index = body, at, component, time_index
        self.__name__ = f"displacement_{body}_{'xy'[component]}"

    def __call__(self, result):
        traj = result.point_positions(self.body, self.at)
        return traj[self.time_index, self.component] - traj[0, self.component]

    def vjp(self, result) -> ResponseVJP:
        value = float(np.real(self(result)))
        g = np.zeros(2)
        g[self.component] = 1.0
        n = self.time_index % result.n_t
        info = result.system.body(self.body)
        if info.kind == "beam":
            k, _ = result.system.model.body(self.body).nearest_node(self.at)
            G = np.zeros((info.X.shape[0], 2))
            G[k] = g
            dq1, dX1 = node_positions_vjp(result, self.body, n, G)
            dq0, dX0 = node_positions_vjp(result, self.body, 0, G)
            return ResponseVJP(value, terms=_terms(n, dq1, 0, -dq0),
                               data={f"body:{self.body}:X": dX1 - dX0})
        dq1, d0a = rigid_point_vjp(result, self.body, self.at, n, g)
        dq0, d0b = rigid_point_vjp(result, self.body, self.at, 0, g)
        return ResponseVJP(value, terms=_terms(n, dq1, 0, -dq0), data={"q0": d0a - d0b})


def _terms(n1: int, g1, n0: int, g0) -> dict:
    """History terms of ``q`` at two times (which may coincide)."""
    terms = {n1: {"q": g1}}
    if n0 in terms:
        terms[n0] = {"q": g1 + g0}
    else:
        terms[n0] = {"q": g0}
    return terms


# the reactions' responses, which use ks above (re-exported: ml.responses.reaction, ...)
from .reaction_responses import peak_reaction, reaction  # noqa: E402, F401

