"""Generalized-alpha time integration as data: coefficients of the method and of one step.

A step is a small table (:class:`StepCoefficients`): the Newmark predictor and update, the
recurrence of the algorithmic acceleration and the weights of the residual's time levels.
The solver (:mod:`morphlab.solve.stepper`) and the sensitivities (:mod:`morphlab.sensitivity`)
run the same step code on these numbers; the update is linear, and one pair of kernels
(:mod:`morphlab.kernels.newmark`) advances states and sensitivity columns alike.
Formulation: ``docs/theory.md`` §5.
"""

from __future__ import annotations

import functools
import numbers
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from ..errors import ModelError
from ..kernels import newmark
from ..kernels.steps import Scheme
from ..kernels.types import Weights


def _is_real(x) -> bool:
    """A real number that is not a boolean."""
    return isinstance(x, numbers.Real) and not isinstance(x, (bool, np.bool_))


@dataclass(frozen=True)
class GeneralizedAlpha:
    """Coefficients of the generalized-alpha method (Chung & Hulbert 1993) from ``rho_inf``.

    ``alpha_m = (2 rho - 1)/(rho + 1)``, ``alpha_f = rho/(rho + 1)``,
    ``gamma = 1/2 - alpha_m + alpha_f``, ``beta = (1 - alpha_m + alpha_f)²/4``: second order,
    unconditionally stable for linear problems, spectral radius ``rho_inf`` at infinite
    frequency. ``rho_inf = 1`` is the trapezoidal rule (no dissipation).
    """

    rho_inf: float = 0.8

    def __post_init__(self):
        r = self.rho_inf
        if not (_is_real(r) and 0.0 <= r <= 1.0):
            raise ModelError(f"rho_inf must be a number in [0, 1], got {r!r}")

    @property
    def alpha_m(self) -> float:
        return (2.0 * self.rho_inf - 1.0) / (self.rho_inf + 1.0)

    @property
    def alpha_f(self) -> float:
        return self.rho_inf / (self.rho_inf + 1.0)

    @property
    def gamma(self) -> float:
        return 0.5 - self.alpha_m + self.alpha_f

    @property
    def beta(self) -> float:
        return 0.25 * (1.0 - self.alpha_m + self.alpha_f) ** 2

    order = 2


SCHEMES = ("arnold-bruls", "paper")


class CoefficientArrays(NamedTuple):
    """A step's coefficients as the float64 arrays the kernels take."""

    pc: np.ndarray  # (h, cqa, cqg, cva, cvg, bh2, gh): kernels.newmark
    upd: np.ndarray  # (ga, gan, ggn): kernels.newmark
    w_old: np.ndarray  # weights (wm, wl, wf, wcm, wcf) of the old level (zeros: none)
    w_new: np.ndarray  # weights of the new level


@dataclass
class StepCoefficients:
    """One step of the generalized-alpha recurrence, as data.

    The unknown is ``a = q''_{n+1}``; with ``g`` the algorithmic acceleration::

        q_{n+1} = q_hat + bh2 a,   q_hat = q_n + h v_n + cqa a_n + cqg g_n
        v_{n+1} = v_hat + gh a,    v_hat = v_n + cva a_n + cvg g_n
        g_{n+1} = ga a + gan a_n + ggn g_n

    and the residual is ``E(s_{n+1}; new) + E(s_n; old)`` (``old is None``: no history).
    The update is linear: :mod:`morphlab.kernels.newmark` advances states and sensitivity
    columns alike.
    """

    h: float
    new: tuple  # weights (wm, wl, wf, wcm, wcf)
    old: tuple | None
    bh2: float
    gh: float
    pred: tuple = (0.0, 0.0, 0.0, 0.0)  # (cqa, cqg, cva, cvg)
    upd: tuple = (1.0, 0.0, 0.0)  # (ga, gan, ggn)

    @functools.cached_property
    def arrays(self) -> CoefficientArrays:
        """The coefficients as the float64 arrays the kernels take (formed once per
        coefficient object; zero old weights when there is no old level)."""
        return CoefficientArrays(
            np.array((self.h,) + tuple(self.pred) + (self.bh2, self.gh), dtype=np.float64),
            np.array(self.upd, dtype=np.float64),
            np.array(self.old if self.old is not None else (0.0,) * 5, dtype=np.float64),
            np.array(self.new, dtype=np.float64))


def step_coefficients(scheme: str, method: GeneralizedAlpha, h: float,
                      constraint_form: str = "paper") -> StepCoefficients:
    """Coefficients of a step of length ``h``.

    ``"arnold-bruls"`` (default; Arnold & Brüls 2007, Multibody Syst. Dyn. 18:185–202): the
    equations of motion and the acceleration constraints hold at ``t_{n+1}`` for the physical
    acceleration ``a``, and the algorithmic acceleration obeys
    ``(1 - alpha_m) g_{n+1} + alpha_m g_n = (1 - alpha_f) a_{n+1} + alpha_f a_n``. Second order
    for every ``rho_inf``.

    ``"paper"`` (eq. 25–26): the residual weights ``M a + J^T lam`` with ``alpha_m`` and the
    forces with ``alpha_f`` between ``t_n`` and ``t_{n+1}`` and ``a`` is the algorithmic
    acceleration. Second order for ``rho_inf = 1`` (where both schemes coincide) and for linear
    systems; with a configuration-dependent mass matrix or constraints the weighting mixes
    values ``(alpha_m - alpha_f) h`` apart and the error is first order (measured: pendulum
    period error slope 0.96 at rho_inf = 0.9, tests/test_convergence_dt.py).
    """
    am, af, b, gm = method.alpha_m, method.alpha_f, method.beta, method.gamma
    if scheme == "paper":
        w_m, w_f = (am, af) if constraint_form == "paper" else (0.0, 0.0)
        return StepCoefficients(
            h, (1 - am, 1 - am, 1 - af, 1 - w_m, 1 - w_f), (am, am, af, w_m, w_f),
            b * h * h, gm * h, ((0.5 - b) * h * h, 0.0, (1 - gm) * h, 0.0), (1.0, 0.0, 0.0))
    r = 1.0 / (1.0 - am)
    return StepCoefficients(
        h, (1.0, 1.0, 1.0, 1.0, 1.0), None, b * h * h * (1 - af) * r, gm * h * (1 - af) * r,
        (b * h * h * af * r, (0.5 - b) * h * h - b * h * h * am * r,
         gm * h * af * r, (1 - gm) * h - gm * h * am * r),
        ((1 - af) * r, af * r, -am * r))


def weights(w: tuple, scale: float, b0: float, b1: float) -> Weights:
    """The kernels' :class:`~morphlab.kernels.types.Weights` of one level's weights ``w =
    (wm, wl, wf, wcm, wcf)`` (zeros for None) and the run's constants."""
    wm, wl, wf, wcm, wcf = (float(x) for x in (w if w is not None else (0.0,) * 5))
    return Weights(wm, wl, wf, wcm, wcf, float(scale), float(b0), float(b1))


def kernel_scheme(coef: StepCoefficients, scale: float, b0: float, b1: float,
                  split: bool = False) -> Scheme:
    """The kernels' :class:`~morphlab.kernels.steps.Scheme` of ``coef``; ``split``: the Newton
    fill forms ``Dq`` and ``Dv`` beside the Newton matrix (a sensitivity run)."""
    C = [[1.0, coef.bh2, coef.gh]]
    if split:
        C += [[0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]
    arr = coef.arrays
    return Scheme(arr.pc, arr.upd, weights(coef.new, scale, b0, b1),
                  weights(coef.old, scale, b0, b1), coef.old is not None, np.array(C))


def old_weights(sc: Scheme):
    """The weights of the old level of the kernels' scheme ``sc``, None for a scheme without
    one. The sensitivity kernels take them as an argument and prune the old level's matrix on
    None (Numba prunes a branch on an argument that is None, not on a field of one); every
    call of a run passes the regular steps' (``Stepper.scheme_of()``), also at the initial
    solve, which has no old level: one compiled signature."""
    return sc.w_old if sc.has_old else None


def newmark_predict(coef: StepCoefficients, q, v, a, g):
    """Predictors ``(q_hat, v_hat)`` of arrays of any one shape (states (n,), sensitivity
    columns (n, n_x)): :func:`morphlab.kernels.newmark.predict`."""
    shape = np.shape(q)
    q, v, a, g = _flat(q, v, a, g)
    qh, vh = np.empty_like(q), np.empty_like(q)
    newmark.predict(coef.arrays.pc, q, v, a, g, qh, vh)
    return qh.reshape(shape), vh.reshape(shape)


def newmark_update(coef: StepCoefficients, qh, vh, a1, a, g):
    """``(q_{n+1}, v_{n+1}, g_{n+1})`` from the predictors and the new acceleration ``a1``
    (:func:`morphlab.kernels.newmark.update`)."""
    shape = np.shape(qh)
    qh, vh, a1, a, g = _flat(qh, vh, a1, a, g)
    q1, v1, g1 = np.empty_like(qh), np.empty_like(qh), np.empty_like(qh)
    arr = coef.arrays
    newmark.update(arr.pc, arr.upd, qh, vh, a1, a, g, q1, v1, g1)
    return q1.reshape(shape), v1.reshape(shape), g1.reshape(shape)


def _flat(*xs):
    """The arrays as contiguous 1-D arrays of one dtype (no copies when they already are:
    the states of a run)."""
    dt = xs[0].dtype
    if all(x.ndim == 1 and x.dtype == dt and x.flags.c_contiguous for x in xs):
        return xs
    dt = np.result_type(*xs)
    return tuple(np.ascontiguousarray(x, dtype=dt).reshape(-1) for x in xs)


INITIAL = StepCoefficients(0.0, (1.0, 1.0, 1.0, 1.0, 1.0), None, 0.0, 0.0)
