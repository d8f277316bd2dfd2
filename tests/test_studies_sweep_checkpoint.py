"""Sweep checkpoints: tied to the task that wrote them, matched bitwise, appended row by row,
damaged records found and dropped.

A checkpoint written by one task must never give its rows to another: every kind of
difference (responses, gradients, a setting, the build, the variables) is tried and must
raise a StudyError naming it, where the old behaviour returned rows "ok" with NaN or stale
values. The file itself is checked byte by byte: each finished job only appends to it (the
content so far is a prefix of the content after, in the same file), and a record cut short
or with a flipped byte is dropped with a warning while the records before it are kept.
"""

import json
import os
import zlib

import numpy as np
import pytest
from test_studies_sweep import RESPONSES, SETTINGS, build, tip_x, tip_y

from morphlab.solve.settings import Settings
from morphlab.studies import (
    CheckpointWarning,
    SimulationTask,
    StudyError,
    SweepResult,
    sweep,
    sweep_iter,
)
from morphlab.studies.identity import as_json, callable_identity, task_identity

DESIGNS = [{"t": 2.0, "g": 1.0}, {"t": 2.2, "g": 0.9}]
TASK = SimulationTask(build, RESPONSES, SETTINGS, gradients=True)


@pytest.fixture
def written(tmp_path):
    """A checkpoint of TASK over DESIGNS, and the table that wrote it."""
    path = tmp_path / "study.ckpt"
    return path, sweep(TASK, DESIGNS, executor="serial", checkpoint=path)


def other_build(p):
    """The pendulum under twice the gravity: another model with the same variables."""
    return build({"t": p["t"], "g": 2.0 * p["g"]})


@pytest.mark.parametrize("task, named", [
    (SimulationTask(build, {"tip_y": tip_y}, SETTINGS, gradients=True), "responses.tip_x"),
    (SimulationTask(build, {"tip_y": tip_x, "tip_x": tip_y}, SETTINGS, gradients=True),
     "responses.tip_y"),
    (SimulationTask(build, RESPONSES, SETTINGS), "gradients: true in the checkpoint, false"),
    (SimulationTask(build, RESPONSES, SETTINGS, gradients=["t"]), "gradients"),
    (SimulationTask(build, RESPONSES, {**SETTINGS, "t_end": 0.02}, gradients=True),
     "settings.t_end: 0.01 in the checkpoint, 0.02 for this sweep"),
    (SimulationTask(build, RESPONSES, {**SETTINGS, "store": "all"}, gradients=True),
     "options.store: only for this sweep"),
    (SimulationTask(build, RESPONSES, SETTINGS, gradients=True, method="adjoint"), "method"),
    (SimulationTask(other_build, RESPONSES, SETTINGS, gradients=True), "task.build.name"),
    (lambda p: {"tip_y": 0.0, "tip_x": 0.0}, "task.kind"),
])
def test_a_checkpoint_of_another_task_is_refused_naming_the_difference(written, task, named):
    path, _ = written
    before = path.read_bytes()
    with pytest.raises(StudyError, match="written by another task") as info:
        sweep(task, DESIGNS, executor="serial", checkpoint=path)
    assert named in str(info.value) and "start afresh" in str(info.value)
    with pytest.raises(StudyError, match="written by another task"):
        sweep_iter(task, DESIGNS, executor="serial", checkpoint=path)  # at the call
    assert path.read_bytes() == before  # nothing written


def test_the_same_build_with_other_closure_values_or_code_is_another_task(tmp_path):
    def pendulum_of(scale):
        def scaled(p):
            return build({"t": p["t"], "g": scale * p["g"]})
        return scaled

    path = tmp_path / "c.ckpt"
    sweep(SimulationTask(pendulum_of(1.0), RESPONSES, SETTINGS), DESIGNS[:1],
          executor="serial", checkpoint=path)
    with pytest.raises(StudyError, match=r"task.build: its code, defaults or closure values "
                                         r"differ \(fingerprint [0-9a-f]{12} in the"):
        sweep(SimulationTask(pendulum_of(1.5), RESPONSES, SETTINGS), DESIGNS[:1],
              executor="serial", checkpoint=path)
    # the same qualified name (a lambda of one function) with other code
    path2 = tmp_path / "f.ckpt"
    sweep(lambda p: {"s": p["t"] + p["g"]}, DESIGNS, executor="serial", checkpoint=path2)
    with pytest.raises(StudyError, match="task.task: its code"):
        sweep(lambda p: {"s": p["t"] - p["g"]}, DESIGNS, executor="serial", checkpoint=path2)
    again = sweep(lambda p: {"s": p["t"] + p["g"]}, DESIGNS, executor="serial",
                  checkpoint=path2)  # the same code: resumed
    assert list(again.values["s"]) == [3.0, 3.1]


def test_other_variables_are_refused(written):
    path, _ = written
    with pytest.raises(StudyError, match=r"holds designs of \['t', 'g'\], these have \['t'\]"):
        sweep(lambda p: {"x": p["t"]}, [{"t": 1.0}], executor="serial", checkpoint=path)


def test_resume_reuses_rows_bitwise_and_only_for_bitwise_equal_designs(written,
                                                                        monkeypatch):
    """A design one ulp away is another design: it runs; the others come from the file,
    bitwise (gradients included), also with the variables in another order."""
    path, first = written
    calls = []
    evaluate = SimulationTask.evaluate

    def counted(self, p):
        calls.append(dict(p))
        return evaluate(self, p)

    monkeypatch.setattr(SimulationTask, "evaluate", counted)
    near = {"g": 0.9, "t": float(np.nextafter(2.2, 3.0))}
    out = sweep(TASK, [{"g": 1.0, "t": 2.0}, near], executor="serial", checkpoint=path)
    assert calls == [near]
    assert out.values["tip_y"][0].tobytes() == first.values["tip_y"][0].tobytes()
    assert out.gradients["tip_x"]["g"][0].tobytes() == first.gradients["tip_x"]["g"][0].tobytes()


def test_values_survive_the_file_bitwise(tmp_path):
    """Numbers JSON cannot write plainly (NaN, infinities, -0.0, subnormals, 0.1 + 0.2) come
    back from a checkpoint bitwise."""
    odd = [float("nan"), float("inf"), -float("inf"), -0.0, 5e-324, 0.1 + 0.2, 1 / 3]

    def task(p):
        return {f"r{k}": v * (1.0 if p["i"] == 0 else 1.0) for k, v in enumerate(odd)}

    path = tmp_path / "odd.ckpt"
    fresh = sweep(task, [{"i": 0.0}], executor="serial", checkpoint=path)
    back = SweepResult.load(path)
    for r in fresh.values:
        assert back.values[r].tobytes() == fresh.values[r].tobytes(), r
    assert back.wall_time.tobytes() == fresh.wall_time.tobytes()


def test_rows_are_appended_never_rewritten(tmp_path):
    """After every job the file is the same file (inode), grown by that job's rows only: the
    content before is a prefix of the content after. Writing N rows is therefore O(N)."""
    path = tmp_path / "append.ckpt"
    seen = []

    def look(done, total):
        if path.exists():
            seen.append((done, os.stat(path).st_ino, path.read_bytes()))

    designs = [{"x": float(i)} for i in range(40)]
    sweep(lambda p: {"y": 2.0 * p["x"]}, designs, executor="serial", batch_size=3,
          checkpoint=path, progress=look)
    assert [n for n, _, _ in seen] == [*range(0, 40, 3), 40]  # the header, then 14 jobs
    assert len({ino for _, ino, _ in seen}) == 1
    for (n0, _, before), (n1, _, after) in zip(seen, seen[1:]):
        assert after.startswith(before) and after.count(b"\n") - before.count(b"\n") == n1 - n0
    assert seen[-1][2].count(b"\n") == 41  # the header and one line per design


def _rewrite_line(path, k, edit):
    lines = path.read_bytes().split(b"\n")
    lines[k] = edit(lines[k])
    path.write_bytes(b"\n".join(lines))


def test_a_half_written_last_record_is_dropped_with_a_warning(tmp_path):
    path = tmp_path / "cut.ckpt"
    designs = [{"x": float(i)} for i in range(4)]
    calls = []

    def task(p):
        calls.append(p["x"])
        return {"y": p["x"] ** 2}

    sweep(task, designs, executor="serial", batch_size=1, checkpoint=path)
    whole = path.read_bytes()
    path.write_bytes(whole[:-7])  # the last record cut short, as by a crash while writing
    with pytest.warns(CheckpointWarning, match=r"ignored 1 damaged record\(s\) \(line 5;"):
        partial = SweepResult.load(path)
    assert list(partial.designs[:, 0]) == [0.0, 1.0, 2.0]
    calls.clear()
    with pytest.warns(CheckpointWarning, match="line 5"):
        out = sweep(task, designs, executor="serial", checkpoint=path)
    assert calls == [3.0]  # only the design whose record was lost
    np.testing.assert_array_equal(out.values["y"], [0.0, 1.0, 4.0, 9.0])
    assert path.read_bytes().count(b"\n") == 5  # the cut line was removed before appending
    SweepResult.load(path)  # no warning: the file is whole again


def test_a_record_with_a_flipped_byte_is_dropped(tmp_path):
    path = tmp_path / "flip.ckpt"
    designs = [{"x": float(i)} for i in range(4)]
    sweep(lambda p: {"y": p["x"] + 0.5}, designs, executor="serial", batch_size=1,
          checkpoint=path)
    _rewrite_line(path, 2, lambda line: line.replace(b"1.5", b"1.6"))  # row x = 1: a wrong y
    with pytest.warns(CheckpointWarning, match=r"1 damaged record\(s\) \(line 3;"):
        table = SweepResult.load(path)
    assert list(table.designs[:, 0]) == [0.0, 2.0, 3.0]  # the others are kept
    assert list(table.values["y"]) == [0.5, 2.5, 3.5]


def test_files_that_are_not_checkpoints_are_refused_untouched(tmp_path, written):
    _, table = written
    old = tmp_path / "old.npz"
    table.save(old)  # a table, as the checkpoints of older versions were
    with pytest.raises(StudyError, match="no record of the task .* SweepResult.load"):
        sweep(TASK, DESIGNS, executor="serial", checkpoint=old)
    notes = tmp_path / "notes.txt"
    notes.write_text("my notes\n")
    with pytest.raises(StudyError, match="is not a sweep checkpoint"):
        sweep(TASK, DESIGNS, executor="serial", checkpoint=notes)
    assert notes.read_text() == "my notes\n"
    with pytest.raises(StudyError, match="is a folder"):
        sweep(TASK, DESIGNS, executor="serial", checkpoint=tmp_path)


def test_a_newer_format_and_a_damaged_header_are_refused(written):
    path, _ = written

    def newer(line):
        head = json.loads(line[9:])
        head["format_version"] = 2
        data = json.dumps(head, separators=(",", ":")).encode()
        return b"%08x %s" % (zlib.crc32(data), data)

    _rewrite_line(path, 0, newer)
    with pytest.raises(StudyError, match="format version 2; .* update morphlab"):
        sweep(TASK, DESIGNS, executor="serial", checkpoint=path)
    _rewrite_line(path, 0, lambda line: line[:-3])
    with pytest.raises(StudyError, match="header is damaged"):
        sweep(TASK, DESIGNS, executor="serial", checkpoint=path)


def test_one_checkpoint_is_written_by_one_sweep_at_a_time(tmp_path):
    path = tmp_path / "busy.ckpt"
    designs = [{"x": float(i)} for i in range(3)]
    rows = sweep_iter(lambda p: {"y": p["x"]}, designs, executor="serial", batch_size=1,
                      checkpoint=path)
    next(rows)  # the first sweep holds the file
    try:
        with pytest.raises(StudyError, match="being written by another running sweep"):
            sweep(lambda p: {"y": p["x"]}, designs, executor="serial", checkpoint=path)
    finally:
        rows.close()
    out = sweep(lambda p: {"y": p["x"]}, designs, executor="serial", checkpoint=path)
    assert list(out.status) == ["ok"] * 3


def test_a_settings_object_task_matches_its_dict_twin(tmp_path):
    """SimulationTask normalizes its settings once: a Settings object and the equivalent dict
    are the same task (one checkpoint serves both)."""
    path = tmp_path / "s.ckpt"
    as_dict = SimulationTask(build, RESPONSES, {**SETTINGS, "max_halvings": 1})
    as_object = SimulationTask(build, RESPONSES, Settings.of(**SETTINGS),
                               options={"max_halvings": 1})
    first = sweep(as_dict, DESIGNS, executor="serial", checkpoint=path)
    second = sweep(as_object, DESIGNS, executor="serial", checkpoint=path)
    assert second.values["tip_y"].tobytes() == first.values["tip_y"].tobytes()


# ------------------------------------------------------------------------------ identities
def _compiled(source: str):
    scope = {}
    exec(compile(source, "<design>", "exec"), scope)
    return scope["f"]


def test_fingerprints_follow_the_code_not_its_comments_or_docstring():
    base = callable_identity(_compiled('def f(p):\n    return {"y": 2.0 * p["x"]}\n'))
    same = callable_identity(_compiled(
        'def f(p):\n    """Twice x."""\n    # a comment\n\n    return {"y": 2.0 * p["x"]}\n'))
    other = callable_identity(_compiled('def f(p):\n    return {"y": 3.0 * p["x"]}\n'))
    assert base == same and base["code"] != other["code"]


class Mesh:
    """A build as an object: its attributes are part of its identity, unless they are
    mutable containers (a cache)."""

    def __init__(self, n):
        self.n, self.cache = n, {}

    def __call__(self, p):
        return build(p)


def test_object_attributes_count_and_caches_do_not():
    a, b, c = Mesh(4), Mesh(4), Mesh(8)
    b.cache["x"] = 1.0
    assert callable_identity(a) == callable_identity(b)
    assert callable_identity(a)["code"] != callable_identity(c)["code"]
    assert callable_identity(a)["name"] == "test_studies_sweep_checkpoint.Mesh"


SOURCE = '''
import json, sys
sys.path.insert(0, {tests!r})
from test_studies_sweep_checkpoint import identity_of_a_task
print(json.dumps(identity_of_a_task()))
'''


def identity_of_a_task():
    def response(result):
        return float(result.t[-1] in {0.01, "a", "b", "c", "d"})  # a frozenset constant

    return as_json(task_identity(SimulationTask(Mesh(3), {"r": response}, SETTINGS)))


def test_identities_are_the_same_in_another_process():
    """A checkpoint is resumed by another process: the identity must not depend on string
    hashing (PYTHONHASHSEED) or addresses."""
    import subprocess
    import sys

    here = os.path.dirname(os.path.abspath(__file__))
    env = {**os.environ, "PYTHONHASHSEED": "12345"}
    out = subprocess.run([sys.executable, "-c", SOURCE.format(tests=here)], env=env,
                         capture_output=True, text=True, check=True).stdout
    assert json.loads(out) == identity_of_a_task()
