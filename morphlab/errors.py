"""The exceptions of morphlab: one small hierarchy under :class:`MorphlabError`; its warnings
under :class:`MorphlabWarning`, emitted by :func:`warn` at the user's line."""

from __future__ import annotations

import os
import sys
import warnings


class MorphlabError(Exception):
    """Base class of every error raised on purpose by morphlab."""


class ModelError(MorphlabError, ValueError):
    """The model description is invalid (geometry, parameters, topology, settings)."""


class SensitivityError(MorphlabError, ValueError):
    """A sensitivity request cannot be answered correctly (unknown method, design variable not
    used by ``build``, response not complex-safe, topology changing with a design variable)."""


class ResponseError(SensitivityError):
    """A response raised, or returned something other than a finite real scalar. The analysis
    is kept: ``sensitivity`` holds a SensitivityResult with the responses evaluated before it
    (its ``derivative`` works for a corrected response), and the response's own exception is
    the ``__cause__``."""

    def __init__(self, message, *, response=None, sensitivity=None):
        super().__init__(message)
        self.response = response
        self.sensitivity = sensitivity


class FormatError(MorphlabError, ValueError):
    """A file cannot be written or read in the morphlab file format (not a morphlab file, a
    newer format version, an entry that has no file representation, metadata that is not
    JSON)."""


class SolverError(MorphlabError, RuntimeError):
    """A run failed. ``result`` holds the solution up to the last converged step.

    Attributes
    ----------
    time, step : float, int
        Time and step index at which the failure happened.
    residual : float
        Norm of the residual (or correction) when the solver gave up.
    dominant : list of str
        The equations with the largest residual entries, named by body/joint.
    result : Result or None
        The results up to the last converged step.
    """

    def __init__(self, message, *, time=None, step=None, residual=None, dominant=(), result=None):
        super().__init__(message)
        self.time = time
        self.step = step
        self.residual = residual
        self.dominant = list(dominant)
        self.result = result


class ConvergenceError(SolverError):
    """Newton–Raphson did not converge within the iteration limit."""


class SingularMatrixError(SolverError):
    """The saddle-point matrix is singular (redundant constraints, a body without mass, ...)."""


class NonFiniteError(SolverError):
    """A NaN or Inf appeared in the residual or the solution."""


class ProfileError(SolverError):
    """A time profile (of a load, a torque or a drive) raised an exception or returned a NaN or
    Inf: the message names it and the time; ``result`` holds the steps before that time (the
    user's exception is the ``__cause__``)."""


class AccuracyError(SolverError):
    """A finished run failed one of its own checks (``simulate(..., checks="raise")``):
    constraint drift, unbounded growth, implausible deformation or stress. ``result`` holds the
    run, with its ``findings``."""


class ConstraintViolationError(AccuracyError):
    """A finished run violates a joint far beyond ``constraint_tol`` (more than
    :data:`morphlab.results.checks.FAILURE_FACTOR` times it): the bodies are visibly apart and
    the run describes another mechanism, so it failed whatever ``checks`` asks for (except
    ``"off"``). ``time`` and ``step`` are those of the first step beyond that limit,
    ``result`` the whole run (status ``"failed"``, its ``findings`` name the joint)."""


class MorphlabWarning(UserWarning):
    """Base class of the warnings morphlab emits."""


class AccuracyWarning(MorphlabWarning):
    """A finished run failed one of its own checks (see :class:`AccuracyError`); the run's
    status is ``"warning"`` and ``result.findings`` lists what and where."""


class KinematicAccuracyWarning(AccuracyWarning):
    """A beam's floating frames turn too little with it: the estimated kinematic error of the
    linear frames exceeds ``kinematic_tol`` times the beam's length
    (:mod:`morphlab.results.kinematics`); the message suggests a number of ``frames``."""


class UnitsWarning(MorphlabWarning):
    """A model's data look like a unit mistake (:func:`morphlab.compile.checks.check_units`):
    a material or gravity that fits no consistent unit system together with the rest of the
    model, or an angle that looks like degrees. The message names the item."""


class Interrupted(KeyboardInterrupt):
    """A run stopped by an interrupt (Ctrl-C / SIGINT, or a KeyboardInterrupt raised by an
    observer or a progress callback). A :class:`KeyboardInterrupt`, so code that stops on
    Ctrl-C keeps doing so; ``result`` holds the steps converged before it, ``time`` and
    ``step`` the last of them."""

    def __init__(self, message, *, time=None, step=None, result=None):
        super().__init__(message)
        self.time = time
        self.step = step
        self.result = result


class StudyError(MorphlabError, ValueError):
    """A study cannot run as asked: a design table that is not a table of finite real numbers,
    a task that cannot travel to a worker process, an unknown executor or setting, a sampler
    size the sequence does not support. The message names the item and what is valid."""


class ResourceError(MorphlabError, MemoryError):
    """A run needs more memory than the machine has available (the message says how much and
    what to change)."""


_PACKAGE = os.path.dirname(os.path.abspath(__file__)) + os.sep


def warn(warning: Warning) -> None:
    """Emit ``warning`` attributed to the first caller outside the morphlab package (the
    user's line that called ``simulate``, ``static``, ``sensitivities``, a study, ...), however
    deep in the library it arises: ``warnings.warn`` with the matching ``stacklevel``."""
    level, frame = 2, sys._getframe(1)
    while frame is not None and os.path.abspath(frame.f_code.co_filename).startswith(_PACKAGE):
        frame, level = frame.f_back, level + 1
    warnings.warn(warning, stacklevel=level)
