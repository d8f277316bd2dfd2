"""The discrete adjoint of the time loop (``docs/theory.md`` §7).

The direct method carries ``dx_n/dp`` forward, one column per design variable. The adjoint
carries ``x̄_n = dψ/dx_n`` backward, one column per response ``ψ``: it is the exact transpose
of the direct recursion (:mod:`morphlab.sensitivity.direct`), so both agree to round-off.
For step ``n`` (from the last to the initial solve), with ``x̄`` holding the adjoint of the
state ``x_n = (q, q', q'', g, λ)_n`` plus the response's own derivative at ``n``:

* through the Newmark update ``q = q̂ + bh2 a``, ``q' = v̂ + gh a``, ``g = ga a + gan a_n-1 +
  ggn g_n-1``, ``λ = s z_λ``: the adjoint of the step unknowns ``z̄ = (ā + bh2 q̄ + gh v̄ + ga ḡ,
  s λ̄)``;
* through the step solve ``J z = -D R``: ``μ = J^-T z̄`` with the primal's kept factorization
  (refined against the exact converged matrix where the primal's last Newton correction was
  not negligible, as in the direct method);
* through the pseudo-load: the predictors get ``-R_q^T μ``, ``-R_v^T μ`` (and, with the
  paper's weighting, the previous state its old-level share), and the design gets
  ``-μ^T ∂R/∂p``;
* through the predictors ``q̂ = q + h v + cqa a + cqg g``, ``v̂ = v + cva a + cvg g``: the
  adjoint of the previous state.

At the initial solve the adjoints of ``q_0``, ``q'_0`` meet their derivatives from ``build``.
The state matrices ``R_q``, ``R_v`` come from the same kernels as the direct method's
(:func:`~morphlab.kernels.direct.split_matrices`), the transposed solves from the same factors
(:meth:`morphlab.solve.linalg.Factor.solve_transposed`).
"""

from __future__ import annotations

import time as _time

import numpy as np

from ..compile import System
from ..kernels.direct import (
    csc_residual_transposed,
    csc_transposed_product,
    explicit_block,
    split_matrices,
)
from ..results.gradients import ResponseVJP, response_vjp, system_data
from ..solve.settings import Settings
from ..solve.timeloop import StepInfo, integrate
from .perturb import CS_STEP, PseudoLoadData


class _Recorder:
    """Forward observer: keeps every converged step's state, factorization and last Newton
    correction, with the coefficients and tables it was solved with."""

    def __init__(self):
        self.steps: list = []  # (n, state, factor, last correction, coefficients)
        self.stepper = None
        self.table = None

    def __call__(self, info: StepInfo) -> None:
        self.stepper, self.table = info.stepper, info.table
        last = info.newton_history[-1][1] if info.newton_history else 0.0
        self.steps.append((info.n, info.state, info.lu, last, info.coef))


def _explicit(sys0: System, rec: _Recorder, data: PseudoLoadData, j: int) -> np.ndarray:
    """``-∂R_n/∂p`` (n, n_x) of recorded step ``j`` at its converged state (both levels): the
    explicit part of the direct method's right-hand side."""
    n, st, _, _, coef = rec.steps[j]
    prev = rec.steps[j - 1][1] if j > 0 else None
    stp = rec.stepper
    old = (st.q, st.v, np.zeros(sys0.n_dof), np.zeros(sys0.n_con)) if prev is None else (
        prev.q, prev.v, prev.a, prev.lam)
    Q, V, A, L = (np.stack([old[c], (st.q, st.v, st.a, st.lam)[c]]) for c in range(4))
    E = np.zeros((1, sys0.n, data.dq0.shape[1]))
    explicit_block(data.S_nom, data.P, data.parts, Q, V, A, L, coef.arrays.w_new,
                   coef.old is not None, coef.arrays.w_old, stp.scale, stp.b0, stp.b1,
                   data.TAB, data.tab0, np.array([max(n - 1, 0)]), np.array([n]), sys0.n_dof,
                   data.pert, np.zeros((2, sys0.n), dtype=data.dtype), E)
    return E[0]


def _split(stp, st, w, F, n_dof):
    """``(D0, Dq, Dv)`` CSC data of one level's residual share at the state ``st``."""
    nnz = stp.system.nnz
    D0, Dq, Dv = np.zeros(nnz), np.zeros(nnz), np.zeros(nnz)
    split_matrices(stp.S, st.q, st.v, st.a, st.lam, w, stp.scale, stp.b0, stp.b1, F, D0, Dq,
                   Dv, np.zeros(nnz, dtype=np.complex128))
    return D0, Dq, Dv


def _tproduct(sys0: System, D, x, n_cols: int) -> np.ndarray:
    """``-D[:, :n_cols]^T x`` (n_cols, m)."""
    out = np.zeros((n_cols, x.shape[1]))
    csc_transposed_product(D, sys0.indices, sys0.indptr, n_cols, x, out)
    return out


def _sweep(sys0: System, rec: _Recorder, vjps: list[ResponseVJP], data: PseudoLoadData,
           refine: int, refine_tol: float, stats: dict) -> np.ndarray:
    """The backward sweep (module docstring): ``dψ_r/dp_i`` (n_x, m) without the responses'
    own data terms."""
    n_dof, n_con, m = sys0.n_dof, sys0.n_con, len(vjps)
    stp = rec.stepper
    s = stp.scale
    bar = {k: np.zeros((w, m)) for k, w in (("q", n_dof), ("v", n_dof), ("a", n_dof),
                                             ("g", n_dof), ("lam", n_con))}
    grad = np.zeros((data.dq0.shape[1], m))
    F = rec.table.F
    for j in range(len(rec.steps) - 1, -1, -1):
        n, st, lu, last, coef = rec.steps[j]
        for r, vj in enumerate(vjps):
            for name, g in vj.at(n).items():
                bar[name][:, r] += np.real(g)
        pc, upd, w_old, w_new = coef.arrays
        h, cqa, cqg, cva, cvg, bh2, gh = pc
        ga, gan, ggn = upd
        zb = np.concatenate([bar["a"] + bh2 * bar["q"] + gh * bar["v"] + ga * bar["g"],
                             s * bar["lam"]])
        D0, Dq, Dv = _split(stp, st, w_new, F[n], n_dof)
        mu = lu.solve_transposed(zb)
        if refine and n > 0 and last > refine_tol:
            J = D0 + bh2 * Dq + gh * Dv
            r = np.empty_like(zb)
            for _ in range(refine):
                csc_residual_transposed(J, sys0.indices, sys0.indptr, mu, zb, r)
                mu = mu + lu.solve_transposed(r)
            rr, bb = csc_residual_transposed(J, sys0.indices, sys0.indptr, mu, zb, r)
            stats["refinement_residual"].append(rr / max(bb, 1e-300))
        qhb = bar["q"] + _tproduct(sys0, Dq, mu, n_dof)
        vhb = bar["v"] + _tproduct(sys0, Dv, mu, n_dof)
        grad += _explicit(sys0, rec, data, j).T @ mu
        if n == 0:
            return grad + data.dq0.T @ qhb + data.dv0.T @ vhb
        gb = bar["g"]
        bar["q"] = qhb
        bar["v"] = h * qhb + vhb
        bar["a"] = cqa * qhb + cva * vhb + gan * gb
        bar["g"] = cqg * qhb + cvg * vhb + ggn * gb
        bar["lam"] = np.zeros((n_con, m))
        if coef.old is not None:  # the paper's weighting: the old level's share
            prev = rec.steps[j - 1][1]
            D0o, Dqo, Dvo = _split(stp, prev, w_old, F[n - 1], n_dof)
            bar["q"] += _tproduct(sys0, Dqo, mu, n_dof)
            bar["v"] += _tproduct(sys0, Dvo, mu, n_dof)
            wz = _tproduct(sys0, D0o, mu, sys0.n)
            bar["a"] += wz[:n_dof]
            bar["lam"] += wz[n_dof:] / s
    raise AssertionError("the recorded run has no initial solve")  # pragma: no cover


def _data_terms(vjps: list[ResponseVJP], sys0: System, complex_systems: list) -> np.ndarray:
    """The responses' own derivatives through the system data they read, mapped to the
    variables with the data's complex-step derivatives (n_x, m)."""
    out = np.zeros((len(complex_systems), len(vjps)))
    for r, vj in enumerate(vjps):
        for key, g in vj.data.items():
            for i, cs in enumerate(complex_systems):
                out[i, r] += np.sum(np.real(g) * np.imag(system_data(cs, key))) / CS_STEP
    return out


def adjoint_run(sys0: System, settings: Settings, responses: dict, complex_systems: list,
                data: PseudoLoadData, *, refine: int = 1, refine_tol: float = 1e-12,
                progress=False):
    """The primal run, the responses' gradients and the backward sweep.

    Returns ``(result, values, gradients, timing, stats)`` with ``values[name]`` and
    ``gradients[name]`` (n_x,) in the order of the complex systems' variables."""
    rec = _Recorder()
    t0 = _time.perf_counter()
    res0 = integrate(sys0, settings, observer=rec, progress=progress)
    t_primal = _time.perf_counter() - t0
    names = list(responses)
    vjps = [response_vjp(k, responses[k], res0) for k in names]
    stats = {"refinement_residual": [], "n_factorizations": res0.n_factorizations}
    grad = _sweep(sys0, rec, vjps, data, refine, refine_tol, stats)
    grad += _data_terms(vjps, sys0, complex_systems)
    total = _time.perf_counter() - t0
    timing = {"primal": t_primal, "sensitivity": total - t_primal, "run": total}
    values = {k: vj.value for k, vj in zip(names, vjps)}
    gradients = {k: grad[:, r] for r, k in enumerate(names)}
    return res0, values, gradients, timing, stats
