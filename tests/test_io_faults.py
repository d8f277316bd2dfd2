"""Saving sensitivity results, and reading damaged, foreign or incomplete files: a bitwise round
trip or a FormatError naming the file, never a raw error and never wrong data."""

import io
import json
import os
import zipfile

import numpy as np
import pytest
from models import tip_loaded_cantilever

import morphlab as ml
from morphlab import io as mio
from morphlab.errors import FormatError


def same_bits(x, y):
    x, y = np.asarray(x), np.asarray(y)
    return x.dtype == y.dtype and x.shape == y.shape and x.tobytes() == y.tobytes()


@pytest.fixture(scope="module")
def sens():
    resp = {"tip": lambda r: r.node_positions("beam", -1)[-1, 1]}
    return ml.sensitivities(tip_loaded_cantilever, {"t": 2.0, "F": 1.0}, resp,
                            method="direct", t_end=2e-3, dt=5e-4, store="all")


def test_sensitivity_result_round_trip_is_bitwise(sens, tmp_path):
    path = tmp_path / "sens.npz"
    mio.save(sens, path)
    back = mio.load(path)
    assert isinstance(back, ml.SensitivityResult)
    assert (back.method, back.variables, back.design) == (sens.method, sens.variables,
                                                          {"t": 2.0, "F": 1.0})
    assert back.values == sens.values and back.gradients == sens.gradients
    assert back.timing == sens.timing and back.stats == sens.stats
    assert back.state.keys() == sens.state.keys() and len(sens.state) == 4
    assert all(same_bits(sens.state[k], back.state[k]) for k in sens.state)
    for name in ("t", "q", "v", "a", "lam"):
        assert same_bits(getattr(sens.result, name), getattr(back.result, name))
    assert back.table() == sens.table()


def test_adjoint_result_without_kept_histories_round_trips(tmp_path):
    """The adjoint keeps only the positions (v, a, lam are None): saved and loaded as None."""
    sens = ml.sensitivities(tip_loaded_cantilever, {"t": 2.0, "F": 1.0},
                            {"ks": ml.responses.ks_max_stress("beam")}, method="adjoint",
                            t_end=1e-3, dt=5e-4)
    assert sens.result.v is None
    mio.save(sens, tmp_path / "adj.npz")
    back = mio.load(tmp_path / "adj.npz")
    assert back.gradients == sens.gradients and back.result.v is None
    assert same_bits(back.result.q, sens.result.q)


def test_composite_profiles_round_trip(tmp_path):
    """Sums, products, integrals of library profiles are stored as data and evaluate the same."""
    m = tip_loaded_cantilever({"t": 2.0, "F": 1.0})
    m.add_torque(m.body("beam"), 3.0, at=(100.0, 0.0), name="T",
                 profile=(2.0 * ml.SmoothStep(0.0, 1e-3) + ml.Sine(50.0)).integral(0.5)
                 * ml.Sine(30.0) - ml.Polynomial((0.0, 1.0, 2.0)) / 3)
    run = ml.simulate(m, t_end=1e-3, dt=5e-4)
    mio.save(run, tmp_path / "r.npz")
    back = mio.load(tmp_path / "r.npz")
    i = run.system.names["torques"].index("T")
    assert dict(back.system.time_profiles["torques"])[i] == \
        dict(run.system.time_profiles["torques"])[i]
    assert all(same_bits(run.energy[k], back.energy[k]) for k in run.energy)


def _flip(data: bytes, bit: int) -> bytes:
    b = bytearray(data)
    b[bit // 8] ^= 1 << (bit % 8)
    return bytes(b)


def _regions(data: bytes) -> list[range]:
    """Byte ranges of the headers of the array member ``x``: its local header (with name and
    zip64 extra) and its .npy header up to the end of the shape, its central directory record
    and the end of central directory record."""
    with zipfile.ZipFile(io.BytesIO(data)) as zf:
        info = zf.getinfo("x.npy")
    start = info.header_offset
    data_start = start + 30 + len(info.filename) + int.from_bytes(
        data[start + 28:start + 30], "little")
    shape_end = data.index(b"), }", data_start) + 3
    record = data.rindex(b"PK\x01\x02")  # x is written last: the last directory record
    assert data[record + 46:record + 51] == b"x.npy"
    return [range(start, shape_end), range(record, len(data))]


def test_every_single_bit_flip_of_the_headers_loads_the_same_or_fails_cleanly(tmp_path):
    """A file with the metadata and one small array: every bit of the array's headers (local
    header, name, zip64 extra, .npy header up to its shape; directory record, end record) is
    flipped once (about 1200 flips, ~3 ms each); each load either gives bitwise the original
    array and metadata or raises FormatError naming the file (the single-bit flips of the zip
    layer are all caught by a CRC-32, a size check or the header check)."""
    x = {"x": np.arange(12.0).reshape(3, 4)}
    good = tmp_path / "good.npz"
    mio.save_arrays(good, x, {"run": 1})
    data = good.read_bytes()
    bits = sorted({8 * b + k for r in _regions(data) for b in r for k in range(8)})
    assert 800 < len(bits) < 2000
    path = tmp_path / "flipped.npz"
    outcomes = {"same": 0, "error": 0}
    for bit in bits:
        path.write_bytes(_flip(data, bit))
        try:
            arrays, meta = mio.load_arrays(path)
        except FormatError as exc:
            assert str(path) in str(exc), (bit, str(exc))
            outcomes["error"] += 1
            continue
        assert meta == {"run": 1} and arrays.keys() == x.keys(), bit
        assert all(same_bits(arrays[k], x[k]) for k in x), bit
        outcomes["same"] += 1
    # the data-bearing fields (sizes, offsets, CRC, names, shape) are caught; the flips that
    # load unchanged are in fields zipfile does not use (times, the local header's copies)
    assert outcomes["error"] > 0.5 * len(bits) and outcomes["same"] > 0


def _rewrite(src, dst, edit):
    """Copy the archive ``src`` to ``dst`` with ``edit(name, bytes) -> bytes or None`` applied
    to every member (None: drop it); a valid ZIP with valid CRCs of the edited content."""
    with zipfile.ZipFile(src) as zin, zipfile.ZipFile(dst, "w") as zout:
        for info in zin.infolist():
            new = edit(info.filename, zin.read(info))
            if new is not None:
                zout.writestr(info.filename, new)


def test_incomplete_and_inconsistent_files_raise_format_error(sens, tmp_path):
    path = tmp_path / "s.npz"
    mio.save(sens, path)

    def drop_key(name, b):
        if name != "metadata.npy":
            return b
        meta = json.loads(str(np.load(io.BytesIO(b))[()]))
        del meta["system"]["con_names"], meta["sensitivity"]["gradients"]
        buf = io.BytesIO()
        np.save(buf, np.array(json.dumps(meta)))
        return buf.getvalue()

    def shrink(name, b):  # a valid CRC, but a shape announcing one entry less than stored
        if name != "result/t.npy":
            return b
        i = b.index(b"'shape': (") + 10
        j = b.index(b",", i)
        return b[:i] + str(int(b[i:j]) - 1).encode().rjust(j - i) + b[j:]

    cases = {"missing key": drop_key, "missing member": lambda n, b: None
             if n == "result/q.npy" else b, "shrunken shape": shrink,
             "compressed": None}
    for what, edit in cases.items():
        bad = tmp_path / f"{what}.npz"
        if edit is None:
            with zipfile.ZipFile(path) as zin, zipfile.ZipFile(bad, "w", zipfile.ZIP_DEFLATED) \
                    as zout:
                for info in zin.infolist():
                    zout.writestr(info.filename, zin.read(info))
        else:
            _rewrite(path, bad, edit)
        with pytest.raises(FormatError) as err:
            mio.load(bad)
        assert str(bad) in str(err.value), what


def test_write_errors_name_the_file(tmp_path, monkeypatch):
    """Disk full (simulated at the write) and a folder without write permission: an OSError
    naming the file, the errno kept, nothing left behind."""
    import morphlab.io.container as container

    real = container.np.lib.format.write_array

    def full(*a, **k):
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(container.np.lib.format, "write_array", full)
    with pytest.raises(OSError) as err:
        mio.save_arrays(tmp_path / "x.npz", {"a": np.ones(3)})
    assert err.value.errno == 28 and "x.npz" in str(err.value)
    monkeypatch.setattr(container.np.lib.format, "write_array", real)
    assert os.listdir(tmp_path) == []
    locked = tmp_path / "locked"
    locked.mkdir(mode=0o500)
    if os.access(locked, os.W_OK):  # root ignores permissions
        pytest.skip("running as a user that can write anywhere")
    with pytest.raises(PermissionError, match="locked"):
        mio.save_arrays(locked / "x.npz", {"a": np.ones(3)})
