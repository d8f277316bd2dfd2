"""Robust design: minimise ``mean + k std`` of a response under scattered variables, the
moments by first-order second-moment propagation (:mod:`.uncertainty`).

With ``g = dr/dξ`` the gradient of the objective response by the scattered variables ``ξ``
(covariance ``C``) at the design ``p``, FOSM gives the mean ``r(p)`` and
``std = sqrt(gᵀ C g)``. The robust objective ``J = r + k std`` has the gradient

    dJ/dp_j = dr/dp_j + k (gᵀ C dg/dp_j) / std

whose second derivatives ``dg/dp_j`` are forward differences of the exact gradients at
``p + h_j e_j`` (``h_j = step · max(|p_j|, 1)``): one gradient run for the design and one per
design variable, ``1 + n`` in all. The problem records ``<objective>.std`` and
``<objective>.robust`` beside its responses and minimises the latter.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from ..errors import ModelError


class Robust:
    """The robust objective of a :class:`~.problem.Problem` (module docstring).

    Parameters
    ----------
    spec : dict
        ``{"std": {variable: σ}, "k": 3.0}`` (independent scatter, variable units), or
        ``{"cov": (m, m) array, "variables": [...], "k": 3.0}``. ``k`` >= 0.
    objective : str
        The response whose mean and std are combined.
    known : list[str]
        The design's variables (keys of ``p0``): the scattered ones must be among them.
    """

    def __init__(self, spec: Mapping, objective: str, known):
        if not isinstance(spec, Mapping) or not (("std" in spec) ^ ("cov" in spec)):
            raise ModelError("robust must be {'std': {variable: sigma}, 'k': 3.0} or "
                             "{'cov': matrix, 'variables': [...], 'k': 3.0}")
        unknown_keys = sorted(set(spec) - {"std", "cov", "variables", "k"})
        if unknown_keys:
            raise ModelError(f"robust has unknown entries {unknown_keys}")
        self.k = float(spec.get("k", 3.0))
        if not (np.isfinite(self.k) and self.k >= 0):
            raise ModelError(f"robust k must be a finite number >= 0, got {spec.get('k')!r}")
        if "std" in spec:
            std = spec["std"]
            if not isinstance(std, Mapping) or not std:
                raise ModelError("robust std must be a non-empty dict variable -> sigma")
            self.variables = [str(v) for v in std]
            s = np.array([float(std[v]) for v in std])
            if not np.all(np.isfinite(s) & (s >= 0)):
                raise ModelError(f"robust std must be finite and >= 0, got {dict(std)}")
            self.cov = np.diag(s * s)
        else:
            self.variables = [str(v) for v in spec.get("variables", [])]
            self.cov = np.asarray(spec["cov"], dtype=float)
            m = len(self.variables)
            if self.cov.shape != (m, m) or not np.all(np.isfinite(self.cov)) or \
                    not np.allclose(self.cov, self.cov.T) or \
                    (m and np.linalg.eigvalsh(self.cov).min() < -1e-12 * np.abs(self.cov).max()):
                raise ModelError(f"robust cov must be a symmetric positive semi-definite "
                                 f"({m}, {m}) matrix for the variables {self.variables}")
        missing = [v for v in self.variables if v not in known]
        if missing or not self.variables:
            raise ModelError(f"robust scatter of {missing or '[]'}: not variables of p0 "
                             f"(known: {list(known)})")
        self.objective = objective
        self.names = (f"{objective}.std", f"{objective}.robust")

    def evaluate(self, run, p: dict, design_variables: list, gradient: bool, step: float
                 ) -> tuple[dict, dict | None, int]:
        """``(values, gradients, simulations)`` with the robust entries added.

        ``run(p, variables) -> (values, gradients, simulations)`` is one gradient run of the
        problem by ``variables``."""
        need = list(dict.fromkeys(list(design_variables) + self.variables))
        values, grads, n_sim = run(p, need)
        g = np.array([grads[self.objective][v] for v in self.variables])
        std = float(np.sqrt(max(g @ self.cov @ g, 0.0)))
        values = dict(values)
        values[self.names[0]], values[self.names[1]] = std, values[self.objective] + self.k * std
        if not gradient:
            return values, None, n_sim
        dstd = {}
        for v in design_variables:
            h = step * max(abs(p[v]), 1.0)
            _, gh, more = run({**p, v: p[v] + h}, self.variables)
            n_sim += more
            dg = (np.array([gh[self.objective][w] for w in self.variables]) - g) / h
            dstd[v] = float(g @ self.cov @ dg / std) if std > 0 else 0.0
        out = {r: {v: by_v[v] for v in design_variables} for r, by_v in grads.items()}
        out[self.names[0]] = dstd
        out[self.names[1]] = {v: out[self.objective][v] + self.k * dstd[v]
                              for v in design_variables}
        return values, out, n_sim
