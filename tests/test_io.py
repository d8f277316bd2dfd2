"""Saving and loading: bitwise round trips, atomic writes, the documented format, determinism.

The reference of a round trip is the object in memory: every array must come back with the
same dtype, shape and bytes, and every accessor must give bitwise the same numbers.
"""

import json
import os

import numpy as np
import pytest
from models import E_AL, RHO_AL, flexible_mechanism, straight_nodes

import morphlab as ml
from morphlab import io as mio
from morphlab.errors import FormatError

RESULT_ARRAYS = ("t", "q", "v", "a", "lam", "newton_iterations", "constraint_violation",
                 "velocity_violation")


def same_bits(x, y):
    x, y = np.asarray(x), np.asarray(y)
    return x.dtype == y.dtype and x.shape == y.shape and x.tobytes() == y.tobytes()


@pytest.fixture(scope="module")
def run():
    return ml.simulate(flexible_mechanism(), t_end=0.004, dt=1e-3)


def test_result_round_trip_is_bitwise(run, tmp_path):
    path = tmp_path / "run.npz"
    mio.save(run, path)
    back = mio.load(path)
    for name in RESULT_ARRAYS:
        assert same_bits(getattr(run, name), getattr(back, name)), name
    assert back.newton_history == run.newton_history
    assert back.settings == run.settings
    for name in ("status", "message", "n_factorizations", "wall_time", "scale"):
        assert getattr(back, name) == getattr(run, name), name
    assert back.summary() == run.summary()
    # accessors that go through the rebuilt System and bodies
    assert same_bits(run.node_positions("coupler"), back.node_positions("coupler"))
    assert same_bits(run.node_rotations("coupler"), back.node_rotations("coupler"))
    assert same_bits(run.deformation("coupler"), back.deformation("coupler"))
    assert same_bits(run.stress("coupler"), back.stress("coupler"))
    assert same_bits(run.dof("crank.theta"), back.dof("crank.theta"))
    for body, at in (("crank", (0.0, 20.0)), ("rocker", (3.0, 1.0))):
        assert same_bits(run.point_positions(body, at), back.point_positions(body, at))
    e_run, e_back = run.energy, back.energy  # uses every kernel array and the time profiles
    assert e_run.keys() == e_back.keys()
    assert all(same_bits(e_run[k], e_back[k]) for k in e_run)


def test_loaded_system_is_complete(run, tmp_path):
    # the System in the file drives the solver to bitwise the same history: nothing of the
    # compiled model (arrays, index tables, CSC pattern, profiles) was lost
    mio.save(run, tmp_path / "run.npz")
    system = mio.load(tmp_path / "run.npz").system
    again = ml.simulate(system, t_end=0.004, dt=1e-3)
    assert same_bits(again.q, run.q) and same_bits(again.lam, run.lam)


def test_complex_result_round_trip(tmp_path):
    # a complex-step run stores complex128 histories; build one directly on a complex System
    system = ml.compile_model(flexible_mechanism(), dtype=np.complex128)
    rng = np.random.default_rng(1)
    n_t = 3

    def c(*shape):
        return rng.normal(size=shape) + 1e-30j * rng.normal(size=shape)

    res = ml.Result(system=system, settings=ml.Settings(t_end=0.002, dt=1e-3),
                    t=np.arange(n_t) * 1e-3, q=c(n_t, system.n_dof), v=c(n_t, system.n_dof),
                    a=c(n_t, system.n_dof), lam=c(n_t, system.n_con),
                    newton_iterations=np.ones(n_t, dtype=np.int64),
                    constraint_violation=np.zeros(n_t), velocity_violation=np.zeros(n_t))
    mio.save(res, tmp_path / "cs.npz")
    back = mio.load(tmp_path / "cs.npz")
    assert back.system.dtype == np.complex128
    for name in RESULT_ARRAYS:
        assert same_bits(getattr(res, name), getattr(back, name)), name
    assert same_bits(res.node_positions("coupler"), back.node_positions("coupler"))
    assert same_bits(res.stress("coupler"), back.stress("coupler"))


def test_python_callable_profiles_are_marked_unsaved(tmp_path):
    m = flexible_mechanism()
    m.add_torque("rocker", 2.0, profile=lambda t: t)  # a Custom profile: code, not data
    res = ml.simulate(m, t_end=0.002, dt=1e-3)
    mio.save(res, tmp_path / "custom.npz")
    back = mio.load(tmp_path / "custom.npz")
    profiles = dict(back.system.time_profiles["torques"])  # torque index -> profile
    assert isinstance(profiles[back.system.count("torques") - 1], mio.UnsavedProfile)
    assert isinstance(profiles[0], ml.SmoothStep)  # built-ins come back
    assert same_bits(res.node_positions("coupler"), back.node_positions("coupler"))
    with pytest.raises(FormatError, match="was a Python callable and was not saved"):
        back.energy  # noqa: B018 - the property evaluates the profiles


def test_static_and_failed_results_round_trip(tmp_path):
    m = ml.Model(name="cantilever")
    beam = m.add_beam(straight_nodes(4), E=E_AL, rho=RHO_AL, thickness=2.0, width=10.0,
                      name="strip")
    m.add_fix(beam, at=(0.0, 0.0))
    m.add_force(beam, at=(100.0, 0.0), force=(0.0, -5.0), profile=ml.Ramp(0.0, 1.0))
    st = ml.static(m, t=1.0, steps=2)
    mio.save(st, tmp_path / "static.npz")
    back = mio.load(tmp_path / "static.npz")
    assert all(same_bits(getattr(st, k), getattr(back, k)) for k in RESULT_ARRAYS)
    with pytest.raises(ml.ConvergenceError) as err:
        ml.simulate(flexible_mechanism(), t_end=0.01, dt=1e-3, max_iter=1, tol=1e-300)
    partial = err.value.result
    mio.save(partial, tmp_path / "failed.npz")
    back = mio.load(tmp_path / "failed.npz")
    assert back.status == "failed" and back.message == partial.message
    assert all(same_bits(getattr(partial, k), getattr(back, k)) for k in RESULT_ARRAYS)


def test_file_is_plain_npz_with_json_metadata(run, tmp_path):
    path = tmp_path / "run.npz"
    mio.save(run, path)
    with np.load(path, allow_pickle=False) as npz:  # no morphlab, no pickle needed
        meta = json.loads(str(npz["metadata"][()]))
        assert same_bits(npz["result/q"], run.q)
        # format 2: the system's tables one member per kind and field
        assert same_bits(npz["system/arrays/bodies/scal"], run.system.arrays.bodies.scal)
    assert meta["format"] == "morphlab-result" and meta["format_version"] == 2
    assert meta["morphlab_version"] == ml.__version__
    assert meta["model"] == "four-bar"
    assert meta["settings"]["fields"]["dt"] == 1e-3
    assert meta["system"]["dof_names"] == run.system.dof_names
    assert meta["system"]["con_names"] == run.system.con_names
    assert [b["name"] for b in meta["bodies"]] == ["crank", "coupler", "rocker"]
    assert mio.read_metadata(path) == meta


class Failing:
    """An array-like that fails when NumPy converts it (in the middle of writing a file)."""

    def __array__(self, dtype=None, copy=None):
        raise RuntimeError("disk full (simulated)")


def test_failed_write_leaves_old_file_and_no_partial_file(run, tmp_path):
    path = tmp_path / "data.npz"
    mio.save_arrays(path, {"x": np.arange(5.0)}, {"run": 1})
    old = path.read_bytes()
    # the metadata and 'a' are written before 'b' fails: a partial archive exists, but only
    # under a temporary name, which is removed
    with pytest.raises(RuntimeError, match="disk full"):
        mio.save_arrays(path, {"a": np.ones(1000), "b": Failing()}, {"run": 2})
    assert path.read_bytes() == old
    assert sorted(os.listdir(tmp_path)) == ["data.npz"]
    # the same for a Result whose arrays cannot be converted, and for a new file name
    broken = ml.Result(**{**run.__dict__, "lam": Failing()})
    with pytest.raises(RuntimeError, match="disk full"):
        mio.save(broken, tmp_path / "new.npz")
    assert sorted(os.listdir(tmp_path)) == ["data.npz"]
    x, meta = mio.load_arrays(path)
    assert meta == {"run": 1} and same_bits(x["x"], np.arange(5.0))


def test_arrays_round_trip(tmp_path):
    rng = np.random.default_rng(7)
    arrays = {
        "dq_dp": rng.normal(size=(4, 3, 2)),
        "complex/step": rng.normal(size=5) + 1j * rng.normal(size=5),
        "index": np.arange(6, dtype=np.int64).reshape(2, 3),
        "mask": np.array([True, False, True]),
        "single": np.float32([1.5, np.nan, np.inf]),
        "scalar": np.float64(3.25),
        "empty": np.zeros((0, 3)),
        "names": np.array(["t_w", "M_t"]),
    }
    meta = {"design": {"t_w": 2.0, "M_t": 1.0e4}, "units": "mm t s", "n": 3, "tags": [1, "a"],
            "missing": None, "nan": float("nan")}
    mio.save_arrays(tmp_path / "sens.npz", arrays, meta)
    back, meta_back = mio.load_arrays(tmp_path / "sens.npz")
    assert back.keys() == arrays.keys()
    assert all(same_bits(arrays[k], back[k]) for k in arrays)
    assert np.isnan(meta_back.pop("nan")) and meta_back == {k: v for k, v in meta.items()
                                                            if k != "nan"}
    info = mio.read_metadata(tmp_path / "sens.npz")
    assert info["format"] == "morphlab-arrays" and info["arrays"] == list(arrays)


@pytest.mark.parametrize("arrays,meta,match", [
    ({"x": np.array([None, 1.0])}, {}, "dtype object"),
    ({"metadata": np.ones(2)}, {}, "reserved"),
    ({"../x": np.ones(2)}, {}, "not allowed"),
    ({"": np.ones(2)}, {}, "non-empty strings"),
    ({3: np.ones(2)}, {}, "non-empty strings"),
    ({"x": np.ones(2)}, {"s": {1, 2}}, "JSON"),
    ({"x": np.ones(2)}, [1], "meta must be a dict"),
    ([np.ones(2)], {}, "arrays must be a dict"),
])
def test_invalid_arrays_are_refused_and_nothing_is_written(tmp_path, arrays, meta, match):
    with pytest.raises(FormatError, match=match):
        mio.save_arrays(tmp_path / "bad.npz", arrays, meta)
    assert os.listdir(tmp_path) == []


def test_reading_foreign_and_future_files(run, tmp_path):
    with pytest.raises(FormatError, match="save_arrays"):
        mio.save({"q": np.ones(3)}, tmp_path / "x.npz")
    mio.save_arrays(tmp_path / "arrays.npz", {"x": np.ones(2)})
    with pytest.raises(FormatError, match="load_arrays"):
        mio.load(tmp_path / "arrays.npz")
    (tmp_path / "text.npz").write_text("not an archive")
    with pytest.raises(FormatError, match="not a morphlab file"):
        mio.load(tmp_path / "text.npz")
    np.savez(tmp_path / "plain.npz", q=np.ones(3))
    with pytest.raises(FormatError, match="no 'metadata' member"):
        mio.load(tmp_path / "plain.npz")
    np.save(tmp_path / "single.npy", np.ones(3))
    with pytest.raises(FormatError, match="single .npy array"):
        mio.load(tmp_path / "single.npy")
    future = json.dumps({"format": "morphlab-result", "format_version": 99})
    np.savez(tmp_path / "future.npz", metadata=np.array(future))
    with pytest.raises(FormatError, match="format version 99"):
        mio.load(tmp_path / "future.npz")
    with pytest.raises(FileNotFoundError):
        mio.load(tmp_path / "missing.npz")


def test_identical_runs_are_bitwise_identical(run):
    # no hidden state (random numbers, dict order, caches) changes a run: the same model and
    # settings give the same bits
    again = ml.simulate(flexible_mechanism(), t_end=0.004, dt=1e-3)
    for name in ("q", "v", "a", "lam", "newton_iterations"):
        assert same_bits(getattr(run, name), getattr(again, name)), name
