"""What a sweep runs in a worker: the task and the batch job around it.

A task is either a :class:`SimulationTask` (a parametric model, its responses and the run's
settings, optionally with gradients) or any function ``p -> dict`` of response values. It
travels to the workers as bytes: serialized with cloudpickle when that is installed (so
closures and functions defined in a notebook work), with plain pickle otherwise, checked up
front. A job is one batch of designs; every design's exception becomes its row's error text,
so one bad design never costs its neighbours.
"""

from __future__ import annotations

import dataclasses
import inspect
import pickle
import threading
import time
from collections.abc import Callable, Mapping

from ..errors import SolverError, StudyError
from ..sensitivity.api import sensitivities
from ..solve.settings import Settings
from ..solve.timeloop import simulate
from ..warmup import warmup
from .identity import callable_identity, state
from .sweep_result import FAILED, OK

# Keyword arguments a task sets itself (or that make no sense in a worker).
_RESERVED = {"model", "build", "p0", "responses", "variables", "method", "settings",
             "progress", "observer", "memmap"}
_FIELDS = {f.name for f in dataclasses.fields(Settings)}


def _allowed(gradients) -> set[str]:
    fn = sensitivities if gradients else simulate
    params = inspect.signature(fn).parameters
    own = {k for k, p in params.items() if p.kind is p.KEYWORD_ONLY}
    return (own | _FIELDS) - _RESERVED


class SimulationTask:
    """One design -> the responses of one run of ``build(p)`` (and their gradients).

    Parameters
    ----------
    build : callable
        ``build(p) -> Model`` for a dict of design variables (as for
        :func:`morphlab.sensitivities`).
    responses : dict of str -> callable
        ``f(result) -> float`` (see :mod:`morphlab.responses`).
    settings : Settings or dict
        The run's options: a :class:`morphlab.Settings`, or a dict of its fields (``t_end``,
        ``dt`` [s], ...) that may also hold the other keyword options of
        :func:`morphlab.simulate` (``max_halvings``, ``store``, ``q0``, ``v0``) or, with
        gradients, of :func:`morphlab.sensitivities` (``store``, ``progress``).
    gradients : bool or list of str
        ``False``: values only (:func:`morphlab.simulate`); ``True``: derivatives by every
        design variable; a list: by these variables (:func:`morphlab.sensitivities`).
    method : str or strategy
        Sensitivity method (with gradients), as for :func:`morphlab.sensitivities`.
    options : dict, optional
        Those other keyword options, when ``settings`` is a Settings object.

    Attributes
    ----------
    settings : Settings
        The run's settings, validated at construction and passed on as ``settings=``.
    options : dict
        The other keyword options (never fields of Settings).

    Raises
    ------
    StudyError
        A build or response that is not callable, an option neither function takes, a
        setting value :class:`morphlab.Settings` refuses.
    """

    def __init__(self, build: Callable[[dict], object], responses: Mapping[str, Callable],
                 settings: Mapping | Settings, *, gradients: bool | list[str] = False,
                 method="direct", options: Mapping | None = None):
        if not callable(build):
            raise StudyError(f"build must be a function p -> Model, got {build!r}")
        if not isinstance(responses, Mapping) or not responses:
            raise StudyError("responses must be a non-empty dict of name -> f(result)")
        bad = [k for k, f in responses.items() if not callable(f)]
        if bad:
            raise StudyError(f"responses {bad} are not callable")
        if not isinstance(gradients, bool) and not (
                isinstance(gradients, list | tuple) and all(isinstance(v, str) for v in gradients)):
            raise StudyError(f"gradients must be True, False or a list of variable names, got "
                             f"{gradients!r}")
        self.build, self.responses, self.method = build, dict(responses), method
        self.gradients = gradients if isinstance(gradients, bool) else list(gradients)
        self.settings, self.options = self._checked(settings, options)

    def _checked(self, settings, options) -> tuple[Settings, dict]:
        """The Settings object (normalized once, here) and the other options."""
        if options is not None and not isinstance(options, Mapping):
            raise StudyError(f"options must be a dict or None, got {options!r}")
        if isinstance(settings, Settings):
            given, base = dict(options or {}), settings
        elif isinstance(settings, Mapping):
            given, base = {**settings, **(options or {})}, None
        else:
            raise StudyError(f"settings must be a dict or a Settings, got {settings!r}")
        fn = "sensitivities" if self.gradients else "simulate"
        extra = _allowed(self.gradients) - _FIELDS
        unknown = sorted(set(given) - extra - (_FIELDS if base is None else set()))
        if unknown:
            valid = sorted(extra | (_FIELDS if base is None else set()))
            raise StudyError(f"settings {unknown} are not options of morphlab.{fn}; valid: "
                             f"{valid}" + ("" if base is None else " (the fields of Settings "
                                           "go in the Settings object)"))
        fields = {k: v for k, v in given.items() if k in _FIELDS}
        try:
            out = Settings.of(base, **fields)
        except Exception as exc:
            raise StudyError(f"settings refused: {exc}") from exc
        return out, {k: v for k, v in given.items() if k not in _FIELDS}

    def evaluate(self, p: dict) -> tuple[dict, dict]:
        """``(values, gradients)`` of the design ``p``: ``{r: float}``,
        ``{r: {v: float}}`` (empty without gradients)."""
        if not self.gradients:
            result = simulate(self.build(p), settings=self.settings, **self.options)
            return {r: float(f(result)) for r, f in self.responses.items()}, {}
        variables = None if self.gradients is True else self.gradients
        sens = sensitivities(self.build, p, self.responses, method=self.method,
                             variables=variables, settings=self.settings, **self.options)
        return dict(sens.values), {r: dict(g) for r, g in sens.gradients.items()}

    def identity(self) -> dict:
        """What decides this task's rows, as JSON data (:mod:`.identity`): the build and
        response functions (qualified names and code fingerprints), the settings and other
        options, the gradients and the method. A sweep checkpoint records it and gives its
        rows only to a task of the same identity."""
        return {"kind": "SimulationTask", "build": callable_identity(self.build),
                "responses": {r: callable_identity(f) for r, f in self.responses.items()},
                "gradients": self.gradients, "method": state(self.method),
                "settings": {f.name: state(getattr(self.settings, f.name))
                             for f in dataclasses.fields(self.settings)},
                "options": {k: state(v) for k, v in self.options.items()}}

    def __call__(self, p: dict) -> dict:
        """Response values of the design ``p`` (a task is also a plain function)."""
        return self.evaluate(p)[0]

    def __repr__(self) -> str:
        grad = "" if not self.gradients else f", gradients={self.gradients!r}"
        return f"SimulationTask({getattr(self.build, '__name__', self.build)!r}, " \
               f"{list(self.responses)}{grad})"


# ---------------------------------------------------------------------------- serialization
def serialize(task) -> bytes:
    """``task`` as bytes for the workers (cloudpickle if installed, else plain pickle)."""
    if not callable(task):
        raise StudyError(f"task must be a SimulationTask or a function p -> dict, got {task!r}")
    try:
        import cloudpickle
    except ImportError:
        cloudpickle = None
    try:
        return cloudpickle.dumps(task) if cloudpickle else pickle.dumps(task)
    except Exception as exc:
        hint = "" if cloudpickle else (" Plain pickle sends functions by name only: define the "
                                       "task and its build and responses at module level, or "
                                       "install cloudpickle (pip install 'morphlab[dask]')")
        raise StudyError(f"the task cannot be sent to worker processes: "
                         f"{type(exc).__name__}: {exc}.{hint}") from exc


_WARM = False
_WARM_LOCK = threading.Lock()
_TASKS: dict[bytes, object] = {}


def ensure_warm() -> None:
    """Compile (or load) the kernels once per process, also with several threads."""
    global _WARM
    with _WARM_LOCK:
        if not _WARM:
            warmup()
            _WARM = True


def _task_of(payload):
    if not isinstance(payload, bytes):  # in-process: the task itself
        return payload
    task = _TASKS.get(payload)
    if task is None:
        _TASKS.clear()
        task = _TASKS[payload] = pickle.loads(payload)
    return task


def describe(exc: BaseException) -> str:
    """A failed row's error text: type, message and, for a failed run, where it failed."""
    text = f"{type(exc).__name__}: {exc}"
    if isinstance(exc, SolverError) and (exc.time is not None or exc.step is not None):
        text += f" [t={exc.time}, step={exc.step}]"
    return text


def _evaluate(task, p: dict) -> tuple[dict, dict]:
    if isinstance(task, SimulationTask):
        return task.evaluate(p)
    out = task(p)
    if not isinstance(out, Mapping):
        raise StudyError(f"the task must return a dict of response -> number, got {out!r}")
    return {str(k): float(v) for k, v in out.items()}, {}


def run_batch(payload, batch: list[tuple[int, dict]]) -> list[tuple[int, dict]]:
    """The worker job: ``(index, row)`` for every ``(index, design)`` of the batch."""
    ensure_warm()
    task = _task_of(payload)
    rows = []
    for index, p in batch:
        start = time.perf_counter()
        try:
            values, gradients = _evaluate(task, p)
            row = {"status": OK, "values": values, "gradients": gradients, "error": ""}
        except Exception as exc:  # the design fails, its neighbours go on
            row = {"status": FAILED, "values": {}, "gradients": {}, "error": describe(exc)}
        row["wall_time"] = time.perf_counter() - start
        rows.append((index, row))
    return rows
