"""The record of an optimization: :class:`History` (every evaluation request and iteration)
and :class:`OptimizationResult` (best design, status, counts), saved and loaded with
:func:`morphlab.io.save_arrays` / :func:`morphlab.io.load_arrays`."""

from __future__ import annotations

import os
from dataclasses import dataclass, field, fields

import numpy as np

from ..errors import FormatError
from ..io import load_arrays, save_arrays

_EVAL_KEYS = ("objective", "max_violation", "time", "duration", "new", "simulations")
_ITER_KEYS = ("iteration", "objective", "max_violation", "step_norm", "runs", "time")


@dataclass
class History:
    """Every evaluation request and every iteration of an optimization.

    Attributes
    ----------
    variables, responses : list[str]
        Design variables and recorded responses, in the column order of :meth:`column`.
    evaluations : list[dict]
        One record per request of the optimizer: ``design`` (variables only), ``x`` (the
        optimizer's vector, its exact bits, for a resume), ``values``, ``gradients``
        (``[response][variable]`` or None), ``objective`` (the raw response),
        ``max_violation``, ``time`` [s since the start], ``duration`` [s of the run],
        ``new`` (a new run, or False for a cache hit) and ``simulations``.
    iterations : list[dict]
        One record per accepted iterate (scipy's callback; the start design is iteration 0):
        ``iteration``, ``objective``, ``max_violation``, ``step_norm`` (in optimizer
        variables), ``runs`` (so far), ``time`` [s] and ``design``.
    """

    variables: list
    responses: list
    evaluations: list = field(default_factory=list)
    iterations: list = field(default_factory=list)

    def column(self, table: str, key: str) -> np.ndarray:
        """One field of ``"evaluations"`` or ``"iterations"`` as an array; ``"design"`` and
        ``"x"`` give (n, n_variables), ``"values"`` (n, n_responses), ``"gradients"`` (n,
        n_responses, n_variables, NaN where none)."""
        recs = getattr(self, table)
        n, nv, nr = len(recs), len(self.variables), len(self.responses)
        if key == "design":
            return np.array([[r["design"][v] for v in self.variables] for r in recs],
                            dtype=float).reshape(n, nv)
        if key == "x":
            return np.array([r.get("x", [np.nan] * nv) for r in recs],
                            dtype=float).reshape(n, nv)
        if key == "values":
            return np.array([[r["values"][k] for k in self.responses] for r in recs],
                            dtype=float).reshape(n, nr)
        if key == "gradients":
            nan = {k: dict.fromkeys(self.variables, np.nan) for k in self.responses}
            return np.array([[[(r["gradients"] or nan)[k][v] for v in self.variables]
                              for k in self.responses] for r in recs]).reshape(n, nr, nv)
        return np.array([r[key] for r in recs])

    def to_arrays(self) -> dict:
        out = {}
        for table, keys in (("evaluations", _EVAL_KEYS), ("iterations", _ITER_KEYS)):
            for key in keys + (("design", "x", "values", "gradients") if table == "evaluations"
                               else ("design",)):
                out[f"{table}/{key}"] = self.column(table, key)
        return out

    @classmethod
    def from_arrays(cls, variables: list, responses: list, arrays: dict) -> History:
        def records(table, keys):
            n = arrays[f"{table}/design"].shape[0]
            recs = [{k: arrays[f"{table}/{k}"][i].item() for k in keys} for i in range(n)]
            for i, r in enumerate(recs):
                r["design"] = dict(zip(variables, arrays[f"{table}/design"][i].tolist()))
            return recs

        evals = records("evaluations", _EVAL_KEYS)
        for i, r in enumerate(evals):
            if "evaluations/x" in arrays:  # written since the optimizer vector is recorded
                r["x"] = arrays["evaluations/x"][i].tolist()
            r["values"] = dict(zip(responses, arrays["evaluations/values"][i].tolist()))
            g = arrays["evaluations/gradients"][i]
            r["gradients"] = None if np.isnan(g).all() else {
                k: dict(zip(variables, g[j].tolist())) for j, k in enumerate(responses)}
        return cls(list(variables), list(responses), evals, records("iterations", _ITER_KEYS))


@dataclass
class OptimizationResult:
    """The outcome of :func:`optimize`.

    Attributes
    ----------
    design : dict[str, float]
        Best design (all entries of ``p0``): scipy's final design when it is feasible, else
        the best feasible design evaluated (the least infeasible when none is).
    values : dict[str, float]
        Its response values.
    objective : float
        Its objective (raw response value).
    feasible : bool
        ``max_violation <= feasibility_tol``.
    max_violation : float
        Largest constraint violation (in the units of :mod:`~morphlab.studies.optimize`).
    status : str
        ``"converged"``, ``"failed"`` (scipy stopped otherwise), ``"budget"``, ``"stopped"``
        (``progress`` raised StopIteration) or ``"error"``; ``message`` says why.
    n_runs, n_simulations : int
        Runs (new designs) and primal simulations, a resumed history included.
    wall_time : float
        Wall time [s], a resumed history included.
    optimizer, gradient : str
        Scipy method and gradient source (None for derivative-free methods).
    history : History
    info : dict
        Objective name, bounds, scales of the objective and constraint rows, constraint rows
        ``(response, kind, sign, limit)``, feasibility tolerance and ``"scipy"``: scipy's
        final ``nit`` and, for trust-constr, ``barrier_parameter``, ``optimality`` and
        ``constr_violation`` (an active inequality ends with a slack of about
        ``barrier_parameter / multiplier`` in optimizer variables).
    jac : ndarray, shape (n_variables,), or None
        Gradient of the objective at the design by the variables (objective units per
        variable unit), where a gradient was computed there.
    multipliers : dict[str, float]
        Lagrange multipliers of the constraint rows (named like ``"stress <= 25"``) at
        scipy's final design, where the method gives them (SLSQP, trust-constr), in the units
        of the problem: the derivative of the optimal objective by the row's limit (negative
        for an active upper limit, positive for an active lower limit, 0 for an inactive
        row). trust-constr also gives the bounds' (``"t <= 3"``, ``"t >= 1.5"``).
    active : list[str]
        Active constraint rows and bounds at the design (within ``1e-6`` in the scaled units
        of :mod:`~morphlab.studies.optimize`; equality rows always).
    nit, nfev, njev : int or None
        Scipy's iterations and function and gradient evaluations (of the last call, a
        resumed part only), None where the method does not report them.

    ``x``, ``fun`` and ``success`` are scipy's names for the design as an array (in the order
    of ``history.variables``, variable units), the objective and ``status == "converged"``.
    """

    design: dict
    values: dict
    objective: float
    feasible: bool
    max_violation: float
    status: str
    message: str
    n_runs: int
    n_simulations: int
    wall_time: float
    optimizer: str
    gradient: str | None
    history: History
    info: dict
    jac: np.ndarray | None = None
    multipliers: dict = field(default_factory=dict)
    active: list = field(default_factory=list)
    nit: int | None = None
    nfev: int | None = None
    njev: int | None = None

    @property
    def x(self) -> np.ndarray:
        """The design as an array in the order of ``history.variables`` (variable units)."""
        return np.array([self.design[v] for v in self.history.variables], dtype=float)

    @property
    def fun(self) -> float:
        """The objective (scipy's name)."""
        return self.objective

    @property
    def success(self) -> bool:
        """``status == "converged"`` (scipy's name)."""
        return self.status == "converged"

    def __repr__(self) -> str:
        design = ", ".join(f"{k}={v:.6g}" for k, v in self.design.items())
        return (f"OptimizationResult({self.status}: objective {self.objective:.8g}, "
                f"{'feasible' if self.feasible else 'INFEASIBLE'} (violation "
                f"{self.max_violation:.2e}), {self.n_runs} runs, {self.wall_time:.2f} s, "
                f"{self.optimizer}; {design}; {self.message})")

    def save(self, path) -> None:
        """Write to ``path`` (``.npz``) with :func:`morphlab.io.save_arrays`."""
        meta = {f.name: getattr(self, f.name) for f in fields(self) if f.name != "history"}
        meta["jac"] = None if self.jac is None else [float(g) for g in self.jac]
        meta.update(kind="OptimizationResult", variables=self.history.variables,
                    responses=self.history.responses)
        save_arrays(path, self.history.to_arrays(), meta)

    @classmethod
    def load(cls, path) -> OptimizationResult:
        """Read a file written by :meth:`save`."""
        arrays, meta = load_arrays(path)
        if meta.pop("kind", None) != "OptimizationResult":
            raise FormatError(f"{os.fspath(path)!r} holds no OptimizationResult")
        hist = History.from_arrays(meta.pop("variables"), meta.pop("responses"), arrays)
        if meta.get("jac") is not None:
            meta["jac"] = np.array(meta["jac"], dtype=float)
        return cls(history=hist, **meta)
