"""Tasks for the propagation methods: a plain function with gradients, and variants of a
:class:`~.tasks.SimulationTask` with or without gradients.

:class:`FunctionTask` lets a function ``p -> (values, gradients)`` (an analytic model, a
surrogate) run wherever a SimulationTask runs: in :func:`~.sweep.sweep` on any executor, and
in the reliability methods that need gradients.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping

from ..errors import StudyError
from .tasks import SimulationTask


class FunctionTask(SimulationTask):
    """A task on a function ``fn(p) -> (values, gradients)``.

    Parameters
    ----------
    fn : callable
        ``fn(p)`` for a dict of design variables returns ``values`` (``{response: float}``)
        and ``gradients`` (``{response: {variable: float}}``, or None when it has none).
        It must be picklable (cloudpickle) to run on worker processes.

    Notes
    -----
    A sweep runs it like a SimulationTask with gradients: its rows carry the gradients the
    function returned.
    """

    def __init__(self, fn: Callable[[dict], tuple]):
        if not callable(fn):
            raise StudyError(f"fn must be a function p -> (values, gradients), got {fn!r}")
        self.fn = self.build = fn
        self.responses, self.settings, self.method = {}, {}, None
        self.gradients = True

    def evaluate(self, p: dict) -> tuple[dict, dict]:
        out = self.fn(dict(p))
        if not (isinstance(out, tuple) and len(out) == 2 and isinstance(out[0], Mapping)):
            raise StudyError("a FunctionTask's function must return (values dict, gradients "
                             f"dict or None), got {type(out).__name__}")
        values, grads = out
        values = {str(k): float(v) for k, v in values.items()}
        if grads is None:
            return values, {}
        if not isinstance(grads, Mapping):
            raise StudyError("gradients must be a dict {response: {variable: float}} or None")
        return values, {str(r): {str(v): float(g) for v, g in by_v.items()}
                        for r, by_v in grads.items()}

    def __repr__(self) -> str:
        return f"FunctionTask({getattr(self.fn, '__name__', self.fn)!r})"


def _options_of(task: SimulationTask, gradients: bool) -> dict:
    """The task's keyword options for a variant with or without gradients. Without: the
    options only a sensitivity run takes (``store``, ...) are left out; with: a primal run's
    own options (``max_halvings``, ``q0``, ``v0``, ...) are refused (a sensitivity run cannot
    honour them)."""
    from .tasks import _allowed

    allowed = _allowed(gradients)
    if gradients:
        primal = sorted(set(task.options) - allowed)
        if primal:
            raise StudyError(f"this method needs gradients, and the task's options {primal} "
                             f"are not options of morphlab.sensitivities: give a "
                             f"SimulationTask with gradients=... and options it takes")
    return {k: v for k, v in task.options.items() if k in allowed}


def with_gradients(task, names: list[str]):
    """``task`` computing gradients by at least ``names``; a SimulationTask without them is
    rebuilt with ``gradients=names`` (same build, responses, settings and method)."""
    if isinstance(task, FunctionTask):
        return task
    if not isinstance(task, SimulationTask):
        raise StudyError("this method needs gradients: give a SimulationTask (its gradients "
                         "are computed by morphlab.sensitivities) or a FunctionTask, got "
                         f"{task!r}")
    if task.gradients is True or (task.gradients and set(names) <= set(task.gradients)):
        return task
    return SimulationTask(task.build, task.responses, task.settings, gradients=list(names),
                          method=task.method, options=_options_of(task, True))


def values_only(task):
    """``task`` without gradients where that saves work (a SimulationTask with gradients is
    rebuilt without them); other tasks as they are."""
    if isinstance(task, FunctionTask) or not isinstance(task, SimulationTask) \
            or not task.gradients:
        if not callable(task):
            raise StudyError(f"task must be a SimulationTask, a FunctionTask or a function "
                             f"p -> dict, got {task!r}")
        return task
    return SimulationTask(task.build, task.responses, task.settings,
                          options=_options_of(task, False))
