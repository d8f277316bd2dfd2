"""The settings a SimulationTask keeps and passes on.

A SimulationTask must normalize its options once, at construction, into a
:class:`morphlab.Settings` (from a dict or a Settings object) and pass that object on to
``simulate`` / ``sensitivities`` as ``settings=``, never spread as keyword arguments; the
other keyword options (``max_halvings``, ``store``, ...) travel apart. The runs are spied on
to see the keyword arguments they receive.
"""

import dataclasses
import functools

import pytest
from test_studies_sweep import DESIGNS, RESPONSES, SETTINGS, build

import morphlab.studies.tasks as tasks
from morphlab.solve.settings import Settings
from morphlab.studies import SimulationTask, StudyError, sweep

FIELDS = {f.name for f in dataclasses.fields(Settings)}


@pytest.fixture
def spied(monkeypatch):
    """The keyword arguments of every simulate / sensitivities call of a SimulationTask."""
    calls = []

    def spy(fn):
        @functools.wraps(fn)  # the same signature: the task reads the options it takes there
        def wrapper(*args, **kwargs):
            calls.append(kwargs)
            return fn(*args, **kwargs)
        return wrapper

    monkeypatch.setattr(tasks, "simulate", spy(tasks.simulate))
    monkeypatch.setattr(tasks, "sensitivities", spy(tasks.sensitivities))
    return calls


@pytest.mark.parametrize("gradients", [False, True])
def test_the_task_passes_one_settings_object_on(spied, gradients):
    options = {"max_halvings": 1} if not gradients else {"store": "all"}
    task = SimulationTask(build, RESPONSES, {**SETTINGS, **options}, gradients=gradients)
    assert task.settings == Settings.of(**SETTINGS) and task.options == options
    out = sweep(task, DESIGNS[:2], executor="serial")
    assert list(out.status) == ["ok", "ok"] and len(spied) == 2
    for kwargs in spied:
        assert kwargs["settings"] is task.settings  # normalized once, at construction
        assert not FIELDS & set(kwargs)  # never spread as keyword arguments
        assert set(options) <= set(kwargs)


def test_settings_objects_and_options():
    base = Settings.of(**SETTINGS)
    task = SimulationTask(build, RESPONSES, base, options={"max_halvings": 2})
    assert task.settings == base and task.options == {"max_halvings": 2}
    with pytest.raises(StudyError, match=r"\['dt'\] are not options .* go in the Settings"):
        SimulationTask(build, RESPONSES, base, options={"dt": 1e-3})
    with pytest.raises(StudyError, match="options must be a dict"):
        SimulationTask(build, RESPONSES, base, options=3)
    with pytest.raises(StudyError, match=r"settings refused: .*\['t_end', 'dt'\] are required"):
        SimulationTask(build, RESPONSES, {"max_iter": 3})
