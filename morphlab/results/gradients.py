"""Gradients of responses with respect to what they read: the discrete adjoint's input.

A response ``f(result) -> scalar`` that can be differentiated by the adjoint method also has a
``vjp(result) -> ResponseVJP`` method: its value and the derivatives ``∂f/∂q_n``, ``∂f/∂q'_n``,
``∂f/∂q''_n``, ``∂f/∂λ_n`` at every time index ``n`` it reads (``at(n)``), and the derivatives
with respect to the compiled system data it reads directly (``data``, e.g. the stress maps
``elements.B`` or a beam's node positions in its frame). The sensitivity code maps the data
derivatives to the design variables with the derivatives of that data (``docs/theory.md`` §7).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from scipy.sparse import csr_matrix

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
        ``stream(ns) -> dict[str, ndarray]`` for responses that read every time: ``ns`` (k,)
        time indices, each value (k, n_dof) or (k, n_con), one row per index (zero where the
        response does not read that time). Computed on demand, a block of steps at a time, so
        the adjoint sweep never holds a whole history of gradients.
    data : dict[str, ndarray], optional
        ``∂f/∂D`` for system data ``D`` the response reads, keyed as :func:`system_data`.
    """

    def __init__(self, value: float, terms: dict | None = None,
                 stream: Callable[[np.ndarray], dict] | None = None, data: dict | None = None):
        self.value = float(value)
        self.terms = terms or {}
        self.stream = stream
        self.data = data or {}

    def over(self, ns) -> dict:
        """``{name: ∂f/∂name}`` at the time indices ``ns`` (k,), each (k, width): one row per
        index; a history the response reads at none of them is absent."""
        ns = np.asarray(ns, dtype=np.int64).reshape(-1)
        out: dict = {}
        for j, n in enumerate(ns.tolist()):
            for name, g in self.terms.get(n, {}).items():
                if name not in out:
                    out[name] = np.zeros((ns.size, np.shape(g)[0]))
                out[name][j] += np.real(g)
        if self.stream is not None:
            for name, g in self.stream(ns).items():
                g = np.real(g)
                out[name] = out[name] + g if name in out else g
        return out

    def at(self, n: int) -> dict:
        """``{name: ∂f/∂name_n}`` at time index ``n`` (empty where the response does not read
        that time)."""
        return {name: g[0] for name, g in self.over([n]).items()}


def system_data(system, key: str) -> np.ndarray:
    """The array of ``system`` a data key names: a kind's field (``"elements.B"``), a body's
    table (``"body:<name>:X"``) or a System field (``"q0"``)."""
    if key.startswith("body:"):
        _, name, field = key.split(":")
        return getattr(system.body(name), field)
    if "." in key:
        kind, field = key.split(".")
        return getattr(system.table(kind), field)
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


# ------------------------------------------------------------- derivatives of the accessors
class StressMap:
    """The stress of one beam as a linear map of ``q``, evaluated over chunks of times (so a
    long run of a fine beam never holds its whole stress history) and transposed for
    gradients. ``times`` (k,): the time indices read; ``P``: the map as a sparse matrix
    (n_elem * 4, n_dof), the stresses of element ``e`` in rows ``4 e .. 4 e + 3``."""

    def __init__(self, result, body: str, times, chunk: int = 256):
        system = result.system
        info = system.body(body)
        self.result, self.times, self.chunk = result, np.asarray(times), chunk
        self.ed = system.arrays.elements.dofs[info.elements]
        self.keep = self.ed >= 0
        self.B = np.real(system.arrays.elements.B[info.elements]).reshape(-1, 4, 6)
        self.n_dof = system.n_dof
        n_e = self.B.shape[0]
        rows = np.broadcast_to(np.arange(4 * n_e).reshape(n_e, 4, 1), self.B.shape)
        cols = np.broadcast_to(self.ed[:, None, :], self.B.shape)
        ok = np.broadcast_to(self.keep[:, None, :], self.B.shape)
        self.P = csr_matrix((self.B[ok], (rows[ok], cols[ok])), shape=(4 * n_e, self.n_dof))

    def _local(self, k0: int, k1: int) -> np.ndarray:
        """Element coordinates at times ``times[k0:k1]``, (k, n_e, 6) (zero where removed)."""
        q = np.real(self.result.q[self.times[k0:k1]])
        return np.where(self.keep, q[:, np.maximum(self.ed, 0)], 0.0)

    def chunks(self):
        """``(k0, k1, stress (k, n_e, 4), local coordinates (k, n_e, 6))`` over the times."""
        for k0 in range(0, self.times.size, self.chunk):
            k1 = min(k0 + self.chunk, self.times.size)
            qe = self._local(k0, k1)
            yield k0, k1, np.einsum("enj,kej->ken", self.B, qe), qe

    def stress(self, q: np.ndarray) -> np.ndarray:
        """The stresses (k, n_e * 4) of the states ``q`` (k, n_dof)."""
        return np.asarray((self.P @ np.real(q).T).T)

    def q_gradient(self, G: np.ndarray) -> np.ndarray:
        """``d sum(G_k * stress_k) / dq_k`` (k, n_dof) for ``G`` (k, n_e * 4)."""
        return np.asarray((self.P.T @ np.asarray(G).T).T)


def stress_vjp(result, body: str, G: np.ndarray, times) -> tuple[np.ndarray, np.ndarray]:
    """Derivatives of ``sum(G * result.stress(body)[times])``: with respect to ``q`` at each
    of ``times`` ((len(times), n_dof)) and to the stress maps ``elements.B`` of the beam's
    elements ((n_elem, 2, 2, 6)). ``G`` (len(times), n_elem, 2, 2)."""
    smap = StressMap(result, body, times)
    Gr = np.real(G).reshape(G.shape[0], -1, 4)
    dq = smap.q_gradient(Gr.reshape(Gr.shape[0], -1))
    dB = np.zeros(smap.B.shape)
    for k0, k1, _, qe in smap.chunks():
        dB += np.einsum("ken,kej->enj", Gr[k0:k1], qe)
    return dq, dB.reshape(-1, 2, 2, 6)


def node_positions_vjp(result, body: str, time_index: int, G: np.ndarray):
    """Derivatives of ``sum(G * result.node_positions(body, time_index))`` (G (n_nodes, 2)):
    with respect to ``q`` at that time (n_dof,) and to the beam's node positions in its frame
    ``X`` (n_nodes, 2)."""
    system = result.system
    info = system.body(body)
    q = np.real(result.q[time_index])
    nd = info.node_dofs
    w = np.where(nd >= 0, q[np.maximum(nd, 0)], 0.0)
    several = info.n_frames > 1
    th = q[info.node_ref[:, 2]] if several else q[info.ref[2]]
    c, s = np.cos(th), np.sin(th)
    u = np.real(info.X) + w[:, :2]
    G = np.real(G)
    dq = np.zeros(system.n_dof)
    # d(A u)/dth = A Ĩ u = (-s ux - c uy, c ux - s uy)
    dth = G[:, 0] * (-s * u[:, 0] - c * u[:, 1]) + G[:, 1] * (c * u[:, 0] - s * u[:, 1])
    if several:  # each node moves with the frame that holds it
        for j, g in enumerate((G[:, 0], G[:, 1], dth)):
            np.add.at(dq, info.node_ref[:, j], g)
    else:
        dq[info.ref[0]] = G[:, 0].sum()
        dq[info.ref[1]] = G[:, 1].sum()
        dq[info.ref[2]] = np.sum(dth)
    AtG = np.stack([c * G[:, 0] + s * G[:, 1], -s * G[:, 0] + c * G[:, 1]], axis=1)
    for j in range(2):
        ok = nd[:, j] >= 0
        np.add.at(dq, nd[ok, j], AtG[ok, j])
    return dq, AtG


def rigid_point_vjp(result, body: str, at, time_index: int, g: np.ndarray):
    """Derivatives of ``g · result.point_positions(body, at)[time_index]`` for a point of a
    rigid body (g (2,)): ``x = R + A(th) A(th0)^T (at - R0)`` with ``(R0, th0)`` the body's
    initial coordinates: with respect to ``q`` at that time (n_dof,) and to ``q0`` (n_dof,)."""
    system = result.system
    info = system.body(body)
    q = np.real(result.q[time_index])
    q0 = np.real(system.q0)
    R0, th0 = q0[info.ref[:2]], q0[info.ref[2]]
    d = np.real(np.asarray(at, dtype=complex)) - R0
    c0, s0 = np.cos(th0), np.sin(th0)
    u0 = np.array([c0 * d[0] + s0 * d[1], -s0 * d[0] + c0 * d[1]])
    th = q[info.ref[2]]
    c, s = np.cos(th), np.sin(th)
    g = np.real(np.asarray(g))
    dq = np.zeros(system.n_dof)
    dq[info.ref[:2]] = g
    dq[info.ref[2]] = g @ np.array([-s * u0[0] - c * u0[1], c * u0[0] - s * u0[1]])
    # through u0: dx/du0 = A(th); du0/dR0 = -A(th0)^T; du0/dth0 = -Ĩ u0 (d A(th0)^T/dth0 d)
    gu = np.array([c * g[0] + s * g[1], -s * g[0] + c * g[1]])  # A^T g
    dq0 = np.zeros(system.n_dof)
    dq0[info.ref[:2]] = -np.array([c0 * gu[0] - s0 * gu[1], s0 * gu[0] + c0 * gu[1]])
    dq0[info.ref[2]] = gu @ np.array([u0[1], -u0[0]])
    return dq, dq0
