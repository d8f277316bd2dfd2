"""Parameter studies (morphlab.studies.sweep) on a 2-element flexible pendulum.

The reference of every row is a single ``ml.sensitivities`` call for that design. A design
runs the same code on one thread whichever executor carries it, so rows must be *bitwise*
equal across the serial executor, local process pools of any batch size and a Dask cluster
(any difference would mean designs influence each other, or the task changed on its way).
Killed workers are simulated with ``os._exit`` inside the task; files count the calls, since
the calls happen in other processes.
"""

import os
import pathlib

import numpy as np
import pytest

import morphlab as ml
from morphlab.studies import SimulationTask, StudyError, SweepResult, sweep

SETTINGS = {"t_end": 0.01, "dt": 1e-3, "max_iter": 6}
DESIGNS = [{"t": t, "g": g} for t in (1.8, 2.0, 2.2) for g in (0.9, 1.1)]


def build(p):
    """Aluminium strip of two elements (100 mm, width 10 mm, thickness p["t"] mm) hinged at
    the origin, falling under gravity scaled by p["g"]."""
    m = ml.Model(gravity=(0.0, -9.81e3 * p["g"]), name="pendulum")
    nodes = np.array([[0.0, 0.0], [50.0, 0.0], [100.0, 0.0]])
    beam = m.add_beam(nodes, E=7e4, rho=2.7e-9, thickness=p["t"], width=10.0, damping=1e-4,
                      name="beam")
    m.add_revolute(m.ground, beam, at=(0.0, 0.0), name="pivot")
    return m


def tip_y(result):
    return result.node_positions("beam")[-1, -1, 1]


def tip_x(result):
    return result.node_positions("beam")[-1, -1, 0]


RESPONSES = {"tip_y": tip_y, "tip_x": tip_x}
TASK = SimulationTask(build, RESPONSES, SETTINGS, gradients=True)


def assert_same_rows(a: SweepResult, b: SweepResult):
    assert list(a.status) == list(b.status) and a.errors == b.errors
    np.testing.assert_array_equal(a.designs, b.designs)
    assert list(a.values) == list(b.values) and list(a.gradients) == list(b.gradients)
    for r in a.values:
        assert a.values[r].tobytes() == b.values[r].tobytes(), r  # bitwise, NaN included
    for r in a.gradients:
        assert list(a.gradients[r]) == list(b.gradients[r])
        for v in a.gradients[r]:
            assert a.gradients[r][v].tobytes() == b.gradients[r][v].tobytes(), (r, v)


@pytest.fixture(scope="module")
def serial():
    return sweep(TASK, DESIGNS, executor="serial")


@pytest.fixture(scope="module")
def dask_client():
    distributed = pytest.importorskip("distributed")
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                  dashboard_address=None) as cluster:
        with distributed.Client(cluster) as client:
            yield client


def test_rows_in_design_order_equal_single_sensitivity_calls(serial):
    assert serial.variables == ["t", "g"] and list(serial.status) == ["ok"] * len(DESIGNS)
    for i, p in enumerate(DESIGNS):
        ref = ml.sensitivities(build, p, RESPONSES, **SETTINGS)
        assert serial.design(i) == p
        for r in RESPONSES:
            assert serial.values[r][i] == ref.values[r]  # the same computation: bitwise
            for v in p:
                assert serial.gradients[r][v][i] == ref.gradients[r][v]
    assert np.all(serial.wall_time > 0)


def test_values_only_and_a_subset_of_gradients():
    plain = sweep(SimulationTask(build, RESPONSES, SETTINGS), DESIGNS[:3], executor="serial")
    assert plain.gradients == {}
    for i, p in enumerate(DESIGNS[:3]):
        res = ml.simulate(build(p), **SETTINGS)
        for r, fn in RESPONSES.items():
            assert plain.values[r][i] == float(fn(res))  # the same run: bitwise
    some = sweep(SimulationTask(build, RESPONSES, SETTINGS, gradients=["g"]), DESIGNS[:2],
                 executor="serial")
    ref = ml.sensitivities(build, DESIGNS[1], RESPONSES, variables=["g"], **SETTINGS)
    assert list(some.gradients["tip_y"]) == ["g"]
    assert some.gradients["tip_y"]["g"][1] == ref.gradients["tip_y"]["g"]


@pytest.mark.parametrize("batch_size", [1, 4, None])
def test_local_pool_equals_serial_bitwise(serial, batch_size):
    assert_same_rows(sweep(TASK, DESIGNS, batch_size=batch_size), serial)


def test_dask_equals_serial_bitwise(serial, dask_client):
    assert_same_rows(sweep(TASK, DESIGNS, executor=dask_client.get_executor()), serial)


def test_a_closure_reaches_pool_workers():
    scale = 3.0

    def task(p):
        return {"pid": float(os.getpid()), "scaled": scale * p["t"]}

    out = sweep(task, DESIGNS, batch_size=1)
    np.testing.assert_array_equal(out.values["scaled"], [3.0 * d["t"] for d in DESIGNS])
    assert os.getpid() not in set(out.values["pid"])  # ran in worker processes


# ------------------------------------------------------------------------------ lost workers
class Killer:
    """Task that exits its worker process on the designs with t in ``kill`` (the first
    ``times`` calls of each), and counts every call of every design in files."""

    def __init__(self, folder, kill=(), times=1):
        self.folder, self.kill, self.times = pathlib.Path(folder), set(kill), times

    def calls(self, t: float) -> int:
        return len(list(self.folder.glob(f"t{t!r}-*")))

    def __call__(self, p):
        n = self.calls(p["t"])
        (self.folder / f"t{p['t']!r}-{n}-{os.getpid()}").touch()
        if p["t"] in self.kill and n < self.times:
            os._exit(3)
        return {"twice": 2.0 * p["t"]}


DESIGNS_1D = [{"t": float(t)} for t in range(8)]


@pytest.mark.parametrize("own_pool", [False, True])
def test_killed_pool_worker_is_rescheduled(tmp_path, own_pool):
    """The default pool, or the caller's, is replaced by a fresh pool when a worker dies."""
    import concurrent.futures as cf

    task = Killer(tmp_path, kill={3.0})
    pool = cf.ProcessPoolExecutor(2) if own_pool else None
    out = sweep(task, DESIGNS_1D, batch_size=2, executor=pool)
    if pool is not None:
        pool.shutdown()
    assert list(out.status) == ["ok"] * 8
    np.testing.assert_array_equal(out.values["twice"], 2.0 * np.arange(8))
    assert task.calls(3.0) == 2  # killed once, rerun alone once


def test_no_retries_reports_the_designs_in_flight(tmp_path):
    task = Killer(tmp_path, kill={3.0})
    out = sweep(task, DESIGNS_1D, batch_size=2, retries=0)
    failed = [i for i in range(8) if out.status[i] == "failed"]
    assert 3 in failed and task.calls(3.0) == 1
    for i in failed:
        assert "worker died" in out.errors[i] and "BrokenProcessPool" in out.errors[i]
    for i in set(range(8)) - set(failed):
        assert out.values["twice"][i] == 2.0 * i


def test_a_design_that_always_kills_fails_after_the_retries(tmp_path):
    task = Killer(tmp_path, kill={5.0}, times=100)
    out = sweep(task, DESIGNS_1D, batch_size=2, retries=2)
    assert [i for i in range(8) if out.status[i] == "failed"] == [5]
    assert "worker died" in out.errors[5] and "3 time(s), 2 of them alone" in out.errors[5]
    assert "retries=2" in out.errors[5]
    assert task.calls(5.0) == 3  # the first run and two reruns alone
    assert np.isnan(out.values["twice"][5])
    np.testing.assert_array_equal(np.delete(out.values["twice"], 5), 2.0 * np.delete(
        np.arange(8.0), 5))


def test_killed_dask_worker_is_rescheduled(tmp_path, dask_client):
    task = Killer(tmp_path, kill={2.0})
    out = sweep(task, DESIGNS_1D, batch_size=2, executor=dask_client.get_executor())
    assert list(out.status) == ["ok"] * 8
    np.testing.assert_array_equal(out.values["twice"], 2.0 * np.arange(8))
    assert task.calls(2.0) >= 2


# --------------------------------------------------------------------------- design failures
def test_model_and_convergence_errors_fail_only_their_rows(serial):
    designs = [*DESIGNS[:2], {"t": -1.0, "g": 1.0}, DESIGNS[2], {"t": 2.0, "g": 1e4}]
    out = sweep(TASK, designs, batch_size=2)
    assert list(out.status) == ["ok", "ok", "failed", "ok", "failed"]
    assert out.errors[2].startswith("ModelError: beam 'beam': thickness")
    # 1e4 g: Newton's first correction is 14 times the model size; 6 iterations are too few
    assert out.errors[4].startswith("ConvergenceError: ") and out.errors[4].endswith(
        "[t=0.001, step=1]")
    for i, j in ((0, 0), (1, 1), (3, 2)):
        for r in RESPONSES:
            assert out.values[r][i] == serial.values[r][j]
            assert out.gradients[r]["t"][i] == serial.gradients[r]["t"][j]
    assert np.isnan(out.values["tip_y"][2]) and np.isnan(out.gradients["tip_x"]["g"][4])


# -------------------------------------------------------------------------------- checkpoint
def test_checkpoint_resumes_only_missing_and_failed(tmp_path):
    calls, tries_of_1 = [], []

    def task(p):
        calls.append(p["t"])
        if p["t"] == 1.0:
            tries_of_1.append(1)
        if p["t"] == 1.0 and len(tries_of_1) == 1:
            raise ValueError("first attempt fails")
        return {"square": p["t"] ** 2}

    def stop_after_two_batches(done, total):
        if done >= 4:
            raise KeyboardInterrupt

    path = tmp_path / "study.npz"
    with pytest.raises(KeyboardInterrupt):
        sweep(task, DESIGNS_1D, executor="serial", batch_size=2, checkpoint=path,
              progress=stop_after_two_batches)
    assert calls == [0.0, 1.0, 2.0, 3.0]
    partial = SweepResult.load(path)
    assert list(partial.status) == ["ok", "failed", "ok", "ok"]
    assert partial.errors[1] == "ValueError: first attempt fails"

    calls.clear()
    out = sweep(task, DESIGNS_1D, executor="serial", batch_size=2, checkpoint=path)
    assert calls == [1.0, 4.0, 5.0, 6.0, 7.0]
    assert list(out.status) == ["ok"] * 8
    np.testing.assert_array_equal(out.values["square"], np.arange(8.0) ** 2)
    calls.clear()
    again = sweep(task, DESIGNS_1D, executor="serial", checkpoint=path)
    assert calls == []
    assert_same_rows(again, out)


# ------------------------------------------------------------------- the table and its input
def test_save_load_bitwise_and_pandas(serial, tmp_path):
    failing = sweep(TASK, [DESIGNS[0], {"t": -1.0, "g": 1.0}], executor="serial")
    for table in (serial, failing):
        table.save(tmp_path / "t.npz")
        back = SweepResult.load(tmp_path / "t.npz")
        assert_same_rows(back, table)
        assert back.wall_time.tobytes() == table.wall_time.tobytes()
    pd = pytest.importorskip("pandas")
    frame = serial.to_pandas()
    assert list(frame.columns[:4]) == ["t", "g", "tip_y", "tip_x"]
    assert "d(tip_y)/d(t)" in frame and list(frame["status"]) == ["ok"] * len(DESIGNS)
    np.testing.assert_array_equal(frame["d(tip_x)/d(g)"], serial.gradients["tip_x"]["g"])
    again = sweep(TASK, pd.DataFrame(DESIGNS), executor="serial")
    assert_same_rows(again, serial)
    assert "6 designs" in repr(serial) and "6 ok, 0 failed" in repr(serial)


def test_to_pandas_says_how_to_install(serial, monkeypatch):
    import sys

    monkeypatch.setitem(sys.modules, "pandas", None)
    with pytest.raises(ImportError, match="pip install pandas"):
        serial.to_pandas()


def test_list_and_dict_designs_give_the_same_table():
    def task(p):
        return {"s": p["a"] + 10.0 * p["b"]}

    columns = {"a": np.array([1.0, 2.0, 3.0]), "b": [0.5, 0.25, 0.125]}
    rows = [{"a": 1.0, "b": 0.5}, {"a": 2, "b": 0.25}, {"a": 3.0, "b": 0.125}]
    x, y = sweep(task, columns, executor="serial"), sweep(task, rows, executor="serial")
    np.testing.assert_array_equal(x.designs, y.designs)
    np.testing.assert_array_equal(x.values["s"], [6.0, 4.5, 4.25])
    np.testing.assert_array_equal(y.values["s"], [6.0, 4.5, 4.25])


def test_progress_bar_and_callback(capsys):
    seen = []
    sweep(lambda p: {"x": p["t"]}, DESIGNS_1D, executor="serial", batch_size=3,
          progress=lambda done, total: seen.append((done, total)))
    assert seen == [(0, 8), (3, 8), (6, 8), (8, 8)]
    sweep(lambda p: {"x": p["t"]}, DESIGNS_1D, executor="serial", batch_size=4, progress=True)
    assert capsys.readouterr().out.endswith("] 8/8 designs\n")


@pytest.mark.parametrize("designs, match", [
    ([], "empty"),
    ({"a": [1.0, 2.0], "b": [1.0]}, "one length"),
    ([{"a": 1.0}, {"b": 1.0}], "design 1 has the variables"),
    ([{"a": float("nan")}], "design 0, variable 'a'"),
    ([{"a": "1"}], "finite real number"),
    ([{"a": True}], "finite real number"),
    (np.ones((2, 2)), "list of dicts"),
])
def test_bad_designs(designs, match):
    with pytest.raises(StudyError, match=match):
        sweep(lambda p: {}, designs, executor="serial")


@pytest.mark.parametrize("options, match", [
    ({"executor": "threads"}, "executor must be"),
    ({"batch_size": 0}, "batch_size"),
    ({"retries": -1}, "retries"),
    ({"progress": "yes"}, "progress"),
])
def test_bad_options(options, match):
    with pytest.raises(StudyError, match=match):
        sweep(lambda p: {}, DESIGNS_1D, **options)


def test_bad_tasks(monkeypatch):
    import sys

    with pytest.raises(StudyError, match="task must be"):
        sweep(42, DESIGNS_1D)
    with pytest.raises(StudyError, match=r"\['t_ned'\] are not options of morphlab.simulate"):
        SimulationTask(build, RESPONSES, {"t_ned": 1.0, "dt": 1e-3})
    with pytest.raises(StudyError, match="settings refused"):
        SimulationTask(build, RESPONSES, {"t_end": 0.01, "dt": 1e-3, "newton": "sometimes"})
    with pytest.raises(StudyError, match="gradients must be"):
        SimulationTask(build, RESPONSES, SETTINGS, gradients="t")
    # without cloudpickle a closure cannot travel: refused up front, with the remedy
    monkeypatch.setitem(sys.modules, "cloudpickle", None)
    with pytest.raises(StudyError, match="install cloudpickle"):
        sweep(lambda p: {}, DESIGNS_1D)
