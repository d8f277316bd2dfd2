"""Design sensitivities of dynamic responses (paper §3, DESIGN.md §6).

Direct differentiation of the step residual ``R(z_{n+1}(p); s_n(p), p) = 0`` gives, for every
design variable ``p_i``,

    J dz_{n+1}/dp_i = -D_i R,    D_i R = R_s ds_n/dp_i + dR/dp_i

with ``J`` the exact Newton matrix of the converged step. The pseudo-load is split as in the
paper (eq. 35, 37):

* the state part ``R_s ds_n``: the residual sees the old state through the Newmark predictors
  (and, with the paper's weighting, its old-level share), so it is ``R_q dq_hat + R_v dv_hat
  (+ ...)`` with ``R_q``, ``R_v`` from the primal's own Newton-matrix kernel, exact and shared
  by all variables;
* the partial derivative ``dR/dp_i`` at the converged state, through the primal's residual
  kernel evaluated over only the bodies, elements, joint rows and loads whose data ``p_i``
  changes, by complex step ``Im R(z; p + i h e_i) / h`` with ``h = 1e-30`` (``method="direct"``,
  exact to round-off) or by a forward difference (``method="direct-fd"``, the paper's
  semi-analytical variant: first order where the residual is nonlinear in the changed data,
  e.g. a thickness, exact up to round-off where it is linear, e.g. E, a load, a rigid body's
  joint point; a geometry change that moves a beam's nodes can make its partial derivatives
  large against the total, and the difference's truncation error with them).

All right-hand sides of a step are solved with the primal's last factorization. That
factorization is taken at the Newton iterate before the final correction ``dz``; the mismatch
``J(z_k) - J(z*) = O(|dz|)`` is removed by iterative refinement against the exact matrix at the
converged point (assembled, not factored), so no factorization beyond the primal's is needed.
The Newmark update is linear, so ``dq_{n+1} = dq_hat + beta h² da_{n+1}``,
``dv_{n+1} = dv_hat + gamma h da_{n+1}``. Initial sensitivities: ``dq_0, dv_0`` from ``build``
by complex step (forward difference for ``direct-fd``), ``da_0, dlam_0`` from the
differentiated initial solve. The run is :mod:`morphlab.sensitivity_direct`, the compiled
work of a step :mod:`morphlab.kernels.direct`.

Response gradients ``dr/dp_i = d/de r(history + e d(history)/dp_i; p + e e_i)`` are taken by
complex step of the response over the perturbed histories, so any complex-safe function of a
:class:`~morphlab.results.Result` works.

Comparators: ``"complex-step"`` (the whole simulation in complex arithmetic, one run per
variable: the reference, no truncation error), ``"forward-difference"`` (n_x + 1 runs) and
``"central-difference"`` (2 n_x + 1 runs).
"""

from __future__ import annotations

import time as _time
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field

import numpy as np

from ..compile import System, compile_model
from ..errors import SensitivityError
from ..results.result import Result
from ..solve.stepper import Settings
from ..solve.timeloop import integrate
from .direct import (
    CS_STEP,
    HISTORIES,
    check_same_layout,
    direct_run,
    histories_to_store,
)

METHODS = ("direct", "direct-fd", "complex-step", "forward-difference", "central-difference")


@dataclass
class SensitivityResult:
    """Values and gradients of responses, with the histories behind them.

    Attributes
    ----------
    result : Result
        The primal run at ``p0``.
    values : dict[str, float]
        Response values at ``p0``.
    gradients : dict[str, dict[str, float]]
        ``gradients[response][variable]``.
    variables : list[str]
        Design variable names, in column order of the arrays below.
    state : dict[str, ndarray]
        Direct methods: the sensitivity histories kept (``store`` of :func:`sensitivities`;
        by default those the responses read), of ``"q"``, ``"v"``, ``"a"`` (n_t, n_dof, n_x)
        and ``"lam"`` (n_t, n_con, n_x). Empty for the other methods.
    timing : dict[str, float]
        Wall seconds: ``"primal"``, ``"sensitivity"`` (the extra work) and ``"total"``.
    stats : dict
        Factorizations, refinement residuals and other diagnostics.
    """

    method: str
    variables: list
    result: Result
    values: dict
    gradients: dict
    state: dict = field(default_factory=dict)
    timing: dict = field(default_factory=dict)
    stats: dict = field(default_factory=dict)
    _perturbed: list = field(default_factory=list, repr=False)
    _steps: dict = field(default_factory=dict, repr=False)

    def derivative(self, fn: Callable[[Result], np.ndarray]) -> np.ndarray:
        """``d fn(result) / d p`` for any complex-safe accessor ``fn`` (e.g. ``lambda r:
        r.stress("skin")``); shape ``fn(result).shape + (n_x,)``."""
        cols = [_diff_column(fn, self.result, pert, self.method, self._steps.get(name))
                for name, pert in zip(self.variables, self._perturbed)]
        return np.stack(cols, axis=-1)

    def stress(self, body: str) -> np.ndarray:
        """d(stress)/dp of a beam, (n_t, n_elem, 2, 2, n_x)."""
        return self.derivative(lambda r: r.stress(body))

    def node_positions(self, body: str) -> np.ndarray:
        """d(node position)/dp of a beam, (n_t, n_nodes, 2, n_x)."""
        return self.derivative(lambda r: r.node_positions(body))

    def table(self, digits: int = 4) -> str:
        """The gradients as a text table (responses in rows, variables in columns)."""
        head = "response".ljust(18) + "".join(v.rjust(14) for v in self.variables)
        lines = [head]
        for name, g in self.gradients.items():
            lines.append(name.ljust(18) + "".join(f"{g[v]:14.{digits}g}" for v in self.variables))
        return "\n".join(lines)


def _diff_column(fn, base: Result, pert, method, step):
    """One column of a derivative from a perturbed result (complex or finite difference)."""
    if method in ("direct", "direct-fd", "complex-step"):
        return np.imag(fn(pert)) / CS_STEP
    if method == "forward-difference":
        return (np.asarray(fn(pert)) - np.asarray(fn(base))) / step
    plus, minus = pert
    return (np.asarray(fn(plus)) - np.asarray(fn(minus))) / (2.0 * step)


def _uses_variable(sys_p: System, sys0: System, t_end: float) -> bool:
    """Does the perturbed system differ from the nominal one anywhere?"""
    arrays = ("q0", "v0", "gravity", "body_scal", "body_damp", "flex_IS", "flex_I0S",
              "flex_I0IS", "elem_M", "elem_St", "elem_K", "elem_B", "con_u0", "con_c0",
              "load_u0", "load_F0", "torque_T0")
    for k in arrays:
        if not np.array_equal(getattr(sys_p, k), getattr(sys0, k)):
            return True
    for t in (0.0, 0.37 * t_end, t_end):
        for x, y in zip(sys_p.time_arrays(t), sys0.time_arrays(t)):
            if not np.array_equal(x, y):
                return True
    return False


def _check_response(name, fn, value_c, value0):
    if not np.iscomplexobj(np.asarray(value_c)):
        raise SensitivityError(
            f"response {name!r} is not complex-safe: it returned a real number for a complex "
            "(perturbed) result, so the imaginary part carrying the derivative was dropped. "
            "Avoid abs, np.abs, np.max, float(), np.hypot on values that depend on the "
            "design; see morphlab.responses (ks, max_by_real, distance, rms)")
    if np.ndim(value_c) != 0:
        raise SensitivityError(f"response {name!r} must return a scalar, got shape "
                               f"{np.shape(value_c)}")
    if not np.isclose(np.real(value_c), value0, rtol=1e-9, atol=1e-300):
        raise SensitivityError(
            f"response {name!r} is not complex-safe: its real part changed under a complex "
            f"perturbation ({np.real(value_c)!r} vs {value0!r})")


def sensitivities(build: Callable[[dict], object], p0: Mapping[str, float],
                  responses: Mapping[str, Callable[[Result], float]], *, t_end: float,
                  dt: float, rho_inf: float = 0.8, method: str = "direct",
                  variables: list | None = None, step: float = 1e-6, tol: float = 1e-10,
                  max_iter: int = 12, stabilization: float = 0.5,
                  stabilization_damping: float = 1.0, constraint_form: str = "paper",
                  scheme: str = "arnold-bruls", refine: int = 1, store="auto",
                  progress: bool = False) -> SensitivityResult:
    """Values and design gradients of ``responses`` of the model ``build(p0)``.

    Parameters
    ----------
    build : callable
        ``build(p) -> Model`` for a dict of design variables; must work with complex values
        (complex step) and keep the topology fixed.
    p0 : dict[str, float]
        Nominal design.
    responses : dict[str, callable]
        ``f(result) -> scalar``, complex-safe (see :mod:`morphlab.responses`).
    t_end, dt, rho_inf, tol, max_iter, stabilization, stabilization_damping, constraint_form,
    scheme :
        Solver settings, as in :func:`morphlab.simulate`.
    method : str
        ``"direct"``, ``"direct-fd"``, ``"complex-step"``, ``"forward-difference"`` or
        ``"central-difference"`` (module docstring).
    variables : list[str], optional
        Subset of ``p0`` to differentiate (default: all).
    step : float
        Relative step of the finite differences (``h_i = step * |p_i|``, or ``step`` when
        ``p_i = 0``); used by ``"direct-fd"`` and the difference methods.
    refine : int
        Iterative-refinement sweeps of the direct solve against the exact converged matrix
        (each contracts the error by O(last Newton correction) <= 1e-10: one is enough).
    store : "auto", "all" or tuple of {"q", "v", "a", "lam"}
        Direct methods: the sensitivity histories kept for every step, (n_t, ..., n_x) each
        (the others keep only the two levels the time stepping needs). ``"auto"`` keeps those
        the responses read, found by calling them once on a two-step probe of the nominal
        model (all four if a response fails there); ``"all"`` keeps all four. What is kept is
        what :meth:`SensitivityResult.derivative` can differentiate afterwards.
    progress : bool
        Print a progress bar.

    Returns
    -------
    SensitivityResult

    Raises
    ------
    SensitivityError
        Unknown method, unknown or unused design variable, structure-changing variable,
        response that is not complex-safe.
    """
    if method not in METHODS:
        raise SensitivityError(f"unknown method {method!r}; choose one of {', '.join(METHODS)}")
    if not isinstance(p0, Mapping) or not p0:
        raise SensitivityError("p0 must be a non-empty dict of design variables")
    names = list(p0) if variables is None else list(variables)
    unknown = [v for v in names if v not in p0]
    if unknown:
        raise SensitivityError(f"design variables {unknown} are not in p0 (known: {list(p0)})")
    if not isinstance(responses, Mapping) or not responses:
        raise SensitivityError("responses must be a non-empty dict name -> function(result)")
    for k, fn in responses.items():
        if not callable(fn):
            raise SensitivityError(f"response {k!r} is not callable")
    if not (store in ("auto", "all") or (isinstance(store, (tuple, list)) and store
                                         and set(store) <= set(HISTORIES))):
        raise SensitivityError(f"store must be 'auto', 'all' or a non-empty tuple of "
                               f"{HISTORIES}, got {store!r}")
    if not (isinstance(step, float) and 0 < step < 1):
        raise SensitivityError(f"step must be a float in (0, 1), got {step!r}")
    settings = Settings(t_end=t_end, dt=dt, rho_inf=rho_inf, tol=tol, max_iter=max_iter,
                        stabilization=stabilization,
                        stabilization_damping=stabilization_damping,
                        constraint_form=constraint_form, scheme=scheme)
    settings.validate()
    p0 = {k: float(np.real(v)) for k, v in p0.items()}
    # relative steps (a density of 2.7e-9 t/mm^3 must not get an absolute step)
    steps = {v: step * (abs(p0[v]) if p0[v] != 0.0 else 1.0) for v in names}

    t_start = _time.perf_counter()
    sys0 = compile_model(build(dict(p0)))
    perturbed_cs = []
    for v in names:
        pv = dict(p0)
        pv[v] = p0[v] + 1j * CS_STEP
        sp_ = compile_model(build(pv), dtype=np.complex128, like=sys0)
        check_same_layout(sys0, sp_, v)
        if not _uses_variable(sp_, sys0, t_end):
            raise SensitivityError(
                f"design variable {v!r} is not used by build: no compiled array, initial "
                "state or load changes with it, so its gradient would be silently zero")
        perturbed_cs.append(sp_)
    t_setup = _time.perf_counter() - t_start

    if method in ("direct", "direct-fd"):
        kept = histories_to_store(store, responses, sys0, settings)
        out = direct_run(sys0, settings, names, perturbed_cs, build, p0, steps, method, refine,
                      progress, kept)
    elif method == "complex-step":
        out = _complex_step(sys0, settings, names, perturbed_cs, progress)
    else:
        out = _differences(sys0, settings, names, build, p0, steps, method, progress)
    res0, perturbed, state, timing, stats = out
    timing["setup"] = t_setup

    values: dict = {}
    gradients: dict = {}
    t_resp = _time.perf_counter()
    for rname, fn in responses.items():
        val0 = fn(res0)
        if np.ndim(val0) != 0:
            raise SensitivityError(f"response {rname!r} must return a scalar, got shape "
                                   f"{np.shape(val0)}")
        if np.iscomplexobj(np.asarray(val0)):
            val0 = np.real(val0)
        values[rname] = float(val0)
        gradients[rname] = {}
        for v, pert in zip(names, perturbed):
            if method in ("direct", "direct-fd", "complex-step"):
                vc = fn(pert)
                _check_response(rname, fn, vc, values[rname])
                gradients[rname][v] = float(np.imag(vc) / CS_STEP)
            else:
                gradients[rname][v] = float(np.real(_diff_column(fn, res0, pert, method,
                                                                 steps[v])))
    timing["responses"] = _time.perf_counter() - t_resp
    timing["total"] = _time.perf_counter() - t_start
    return SensitivityResult(method=method, variables=names, result=res0, values=values,
                             gradients=gradients, state=state, timing=timing, stats=stats,
                             _perturbed=perturbed, _steps=steps)


def _complex_step(sys0, settings, names, perturbed_cs, progress):
    t0 = _time.perf_counter()
    res0 = integrate(sys0, settings, progress=progress)
    t_primal = _time.perf_counter() - t0
    perturbed = []
    for s in perturbed_cs:
        perturbed.append(integrate(s, settings, scale=res0.scale, polish=1, progress=progress))
    total = _time.perf_counter() - t0
    timing = {"primal": t_primal, "sensitivity": total - t_primal, "run": total}
    stats = {"n_factorizations": res0.n_factorizations + sum(r.n_factorizations
                                                             for r in perturbed)}
    return res0, perturbed, {}, timing, stats


def _differences(sys0, settings, names, build, p0, steps, method, progress):
    t0 = _time.perf_counter()
    res0 = integrate(sys0, settings, progress=progress)
    t_primal = _time.perf_counter() - t0
    perturbed = []
    nfac = res0.n_factorizations
    for v in names:
        runs = []
        for sign in ((1.0,) if method == "forward-difference" else (1.0, -1.0)):
            pv = dict(p0)
            pv[v] = p0[v] + sign * steps[v]
            sp_ = compile_model(build(pv), dtype=np.float64, like=sys0)
            check_same_layout(sys0, sp_, v)
            r = integrate(sp_, settings, scale=res0.scale, progress=progress)
            nfac += r.n_factorizations
            runs.append(r)
        perturbed.append(runs[0] if len(runs) == 1 else tuple(runs))
    total = _time.perf_counter() - t0
    timing = {"primal": t_primal, "sensitivity": total - t_primal, "run": total}
    return res0, perturbed, {}, timing, {"n_factorizations": nfac}
