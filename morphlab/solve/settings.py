"""The options of a run, in one object that travels with the task (to a worker process too).

:class:`Settings` holds every option of :func:`morphlab.simulate` that shapes the solution
(time span and step, the generalized-alpha scheme, Newton's tolerance, the constraint
stabilization) and those that only choose how it is computed (``newton``, ``dense_max``,
``compiled_newton``). ``simulate`` and ``sensitivities`` take the same fields as keyword
arguments (or one ``settings=`` object); nothing is read from module globals.
"""

from __future__ import annotations

import dataclasses
import numbers
from collections.abc import Mapping
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from ..errors import ModelError
from ..results.checks import KINEMATIC_TOL
from .linalg import DENSE_MAX
from .scheme import SCHEMES, GeneralizedAlpha, _is_real


def _is_int(x) -> bool:
    return isinstance(x, numbers.Integral) and not isinstance(x, (bool, np.bool_))


class State(NamedTuple):
    """Solution at one time: ``t``, ``q`` (n_dof), ``v`` = q', ``a`` = q'' and ``lam``
    (n_con); ``g`` is the algorithmic acceleration of the generalized-alpha recurrence (equal
    to ``a`` for the paper's form)."""

    t: float
    q: np.ndarray
    v: np.ndarray
    a: np.ndarray
    lam: np.ndarray
    g: np.ndarray | None = None


@dataclass(frozen=True)
class Settings:
    """Options of a run (the keyword arguments of :func:`morphlab.simulate`).

    Attributes
    ----------
    t_end, dt : float
        End time and time step [s]; ``(t_end - t_start)/dt`` is rounded up to whole steps
        (:attr:`n_steps`, :attr:`h`).
    rho_inf : float
        Spectral radius at infinite frequency, in [0, 1].
    tol : float
        Newton stops when the position correction is below ``tol`` times the model size.
    max_iter : int
        Newton iteration limit per step.
    stabilization, stabilization_damping : float
        ``omega h`` and damping ratio of the Baumgarte term of the constraint rows
        (``docs/theory.md`` §4).
    constraint_form : {"paper", "endpoint"}
        With ``scheme="paper"``: weighting of the acceleration constraint rows.
    t_start : float
        Start time [s].
    scheme : {"arnold-bruls", "paper"}
        Generalized-alpha form (``docs/theory.md`` §5).
    newton : {"full", "modified"}
        Exact Newton matrix every iteration, or kept over iterations and steps while the
        corrections contract (primal runs only).
    dense_max : int
        Step matrices of at most this many unknowns are factored dense
        (:mod:`morphlab.solve.linalg`).
    compiled_newton : bool
        Run the Newton loop of a step in one compiled call once the factorization has settled
        (the same iterates as the loop from Python, which remains for ``False``).
    chunk_seconds : float
        Work of one compiled chunk of steps [s of wall time]: between chunks the run checks
        for an interrupt and reports progress; 0 gives one step per chunk. The results do not
        depend on it.
    checks : {"warn", "raise", "off"}
        What a finished run does when one of its own checks fails (constraint drift beyond
        ``constraint_tol``, unbounded growth, implausible deformation or stress:
        :mod:`morphlab.results.checks`): status ``"warning"`` and an AccuracyWarning, an
        AccuracyError, or nothing.
    constraint_tol : float
        Largest position-level constraint violation accepted, relative to the model size;
        beyond 10 times it the run fails (:class:`~morphlab.errors.ConstraintViolationError`).
    kinematic_tol : float or None
        Largest estimated kinematic error of a beam's floating frames accepted, relative to
        the beam's length (default 1e-3: docs/frames.md; :mod:`morphlab.results.kinematics`;
        a :class:`~morphlab.errors.KinematicAccuracyWarning` above it); None: not checked.
    """

    t_end: float
    dt: float
    rho_inf: float = 0.8
    tol: float = 1e-10
    max_iter: int = 12
    stabilization: float = 0.5
    stabilization_damping: float = 1.0
    constraint_form: str = "paper"
    t_start: float = 0.0
    scheme: str = "arnold-bruls"
    newton: str = "full"
    dense_max: int = DENSE_MAX
    compiled_newton: bool = True
    chunk_seconds: float = 0.1
    checks: str = "warn"
    constraint_tol: float = 1e-3
    kinematic_tol: float | None = KINEMATIC_TOL

    # read like a mapping of its fields: ``simulate(m, **settings)``, ``dict(settings, dt=...)``
    def keys(self):
        return [f.name for f in dataclasses.fields(self)]

    def __getitem__(self, name: str):
        if name not in self.keys():
            raise KeyError(name)
        return getattr(self, name)

    def __iter__(self):
        return iter(self.keys())

    def __len__(self) -> int:
        return len(self.keys())

    @classmethod
    def of(cls, settings: Settings | None = None, **options) -> Settings:
        """``settings`` with ``options`` replaced (or new Settings from ``options``),
        validated. Unknown option names raise :class:`ModelError` naming the valid ones."""
        names = {f.name for f in dataclasses.fields(cls)}
        unknown = sorted(set(options) - names)
        if unknown:
            raise ModelError(f"unknown settings {unknown}; valid: {sorted(names)}")
        if settings is None:
            missing = [k for k in ("t_end", "dt") if k not in options]
            if missing:
                raise ModelError(f"settings {missing} are required (t_end and dt [s])")
            out = cls(**options)
        elif isinstance(settings, Mapping) and not isinstance(settings, Settings):
            return cls.of(None, **{**settings, **options})
        elif not isinstance(settings, Settings):
            raise ModelError(f"settings must be a morphlab.Settings (or a dict of its "
                             f"fields), got {type(settings).__name__}")
        else:
            out = dataclasses.replace(settings, **options)
        out.validate()
        return out

    def validate(self) -> None:
        """Raise :class:`ModelError` naming the first invalid setting."""
        for name in ("t_end", "dt"):
            v = getattr(self, name)
            if not _is_real(v) or not np.isfinite(v) or not v > 0:
                raise ModelError(f"{name} must be a finite positive number, got {v!r}")
        if not (_is_real(self.t_start) and np.isfinite(self.t_start)):
            raise ModelError(f"t_start must be a finite number, got {self.t_start!r}")
        if self.dt > self.t_end - self.t_start:
            raise ModelError(f"dt={self.dt} is larger than the simulated span "
                             f"{self.t_end - self.t_start}")
        if not _is_real(self.rho_inf):
            raise ModelError(f"rho_inf must be a number in [0, 1], got {self.rho_inf!r}")
        GeneralizedAlpha(float(self.rho_inf))
        if not (_is_real(self.tol) and 0 < self.tol < 1):
            raise ModelError(f"tol must be a number in (0, 1), got {self.tol!r}")
        if not (_is_int(self.max_iter) and self.max_iter >= 1):
            raise ModelError(f"max_iter must be an integer >= 1, got {self.max_iter!r}")
        for name in ("stabilization", "stabilization_damping"):
            v = getattr(self, name)
            if not (_is_real(v) and np.isfinite(v) and v >= 0):
                raise ModelError(f"{name} must be a finite number >= 0, got {v!r}")
        for name, valid in (("newton", ("full", "modified")), ("scheme", SCHEMES),
                            ("constraint_form", ("paper", "endpoint")),
                            ("checks", ("warn", "raise", "off"))):
            if getattr(self, name) not in valid:
                raise ModelError(f"{name} must be one of {', '.join(map(repr, valid))}, got "
                                 f"{getattr(self, name)!r}")
        if not (_is_int(self.dense_max) and self.dense_max >= 0):
            raise ModelError(f"dense_max must be an integer >= 0, got {self.dense_max!r}")
        if not (_is_real(self.chunk_seconds) and 0.0 <= self.chunk_seconds < np.inf):
            raise ModelError(f"chunk_seconds must be a finite number >= 0, got "
                             f"{self.chunk_seconds!r}")
        if not (_is_real(self.constraint_tol) and 0 < self.constraint_tol < 1):
            raise ModelError(f"constraint_tol must be a number in (0, 1), got "
                             f"{self.constraint_tol!r}")
        if self.kinematic_tol is not None and not (_is_real(self.kinematic_tol)
                                                   and 0 < self.kinematic_tol < 1):
            raise ModelError(f"kinematic_tol must be None (off) or a number in (0, 1) "
                             f"(relative to a beam's length), got {self.kinematic_tol!r}")
        if not isinstance(self.compiled_newton, (bool, np.bool_)):
            raise ModelError(f"compiled_newton must be True or False, got "
                             f"{self.compiled_newton!r}")

    @property
    def n_steps(self) -> int:
        """Number of steps: ``ceil((t_end - t_start)/dt)`` (the step is then shortened to fit)."""
        return int(np.ceil((self.t_end - self.t_start) / self.dt - 1e-9))

    @property
    def h(self) -> float:
        """The step actually used, ``(t_end - t_start) / n_steps``."""
        return (self.t_end - self.t_start) / self.n_steps


@dataclass(frozen=True)
class StaticSettings:
    """Options of a static equilibrium path (:func:`morphlab.static`).

    Attributes
    ----------
    t : float
        Time at which loads and driving constraints are evaluated [s].
    steps : int
        Continuation steps: equilibria at ``t_k = k t / steps`` in turn, each from the
        previous one (load control along the model's own profiles).
    tol : float
        Newton stops when the position correction is below ``tol`` times the model size.
    max_iter : int
        Newton iteration limit per continuation step.
    dense_max : int
        Linear solver (as :class:`Settings`).
    kinematic_tol : float or None
        Largest estimated kinematic error of a beam's floating frames accepted, relative to
        its length (default 1e-3: docs/frames.md; :mod:`morphlab.results.kinematics`); None:
        not checked.
    """

    t: float = 0.0
    steps: int = 1
    tol: float = 1e-10
    max_iter: int = 30
    dense_max: int = DENSE_MAX
    kinematic_tol: float | None = KINEMATIC_TOL

    @classmethod
    def of(cls, settings: StaticSettings | None = None, **options) -> StaticSettings:
        """``settings`` with ``options`` replaced (or new StaticSettings from ``options``);
        unknown option names raise :class:`ModelError` naming the valid ones."""
        names = {f.name for f in dataclasses.fields(cls)}
        unknown = sorted(set(options) - names)
        if unknown:
            raise ModelError(f"unknown static settings {unknown}; valid: {sorted(names)}")
        base = settings if settings is not None else cls()
        if not isinstance(base, cls):
            raise ModelError(f"settings must be a StaticSettings, got {type(base).__name__}")
        return dataclasses.replace(base, **options)
