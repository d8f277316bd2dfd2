"""Streaming sweeps (studies.sweep_iter).

``sweep_iter`` must yield every design's row exactly once, as it finishes (not in design
order when a design is slow), bitwise equal to the row of ``sweep``'s table, on the serial
executor and on process pools (Dask: tests/test_studies_sweep_dask.py).
"""

import os
import pathlib
import time

import numpy as np
import pytest
from test_studies_sweep import DESIGNS, RESPONSES, TASK

from morphlab.studies import StudyError, SweepRow, sweep, sweep_iter


@pytest.fixture(scope="module")
def table():
    return sweep(TASK, DESIGNS, executor="serial")


@pytest.mark.parametrize("executor, batch_size", [("serial", None), (None, 1), (None, None)])
def test_every_row_once_and_bitwise_the_table_row(table, executor, batch_size):
    seen = list(sweep_iter(TASK, DESIGNS, executor=executor, batch_size=batch_size))
    assert sorted(i for i, _ in seen) == list(range(len(DESIGNS)))
    for i, row in seen:
        assert isinstance(row, SweepRow) and row.ok and not row.resumed
        assert row.design == DESIGNS[i] and row.error == ""
        for r in RESPONSES:
            assert np.float64(row.values[r]).tobytes() == table.values[r][i].tobytes()
            for v in DESIGNS[i]:
                assert np.float64(row.gradients[r][v]).tobytes() == (
                    table.gradients[r][v][i].tobytes())


class Slow:
    """Takes ``seconds`` for the design x == 0 (every design if ``all``), nothing for the
    others; marks each call with a file (the calls happen in worker processes)."""

    def __init__(self, folder, seconds, all=False):
        self.folder, self.seconds, self.all = str(folder), seconds, all

    def calls(self) -> int:
        return len(os.listdir(self.folder))

    def __call__(self, p):
        pathlib.Path(self.folder, f"{p['x']!r}").touch()
        time.sleep(self.seconds if self.all or p["x"] == 0.0 else 0.0)
        return {"y": 3.0 * p["x"]}


def test_rows_come_as_they_finish_and_the_table_keeps_the_order(tmp_path):
    """Design 0 takes 1 s on one of two workers; the seven others finish on the other one
    meanwhile and are yielded before it."""
    designs = [{"x": float(i)} for i in range(8)]
    task = Slow(tmp_path, 1.0)
    order = [i for i, _ in sweep_iter(task, designs, executor=None, batch_size=1)]
    assert sorted(order) == list(range(8)) and order[-1] == 0
    out = sweep(task, designs, batch_size=1)
    np.testing.assert_array_equal(out.values["y"], 3.0 * np.arange(8))  # the order given


def test_closing_the_stream_early_stops_the_sweep(tmp_path):
    """After the first row, closing the stream cancels the jobs not started and shuts its
    pool down: of 40 designs, only those in flight (one per worker) have run."""
    designs = [{"x": float(i)} for i in range(40)]
    task = Slow(tmp_path, 0.1, all=True)
    rows = sweep_iter(task, designs, batch_size=1)
    first = next(rows)
    rows.close()
    assert first[1].ok and task.calls() <= 1 + (os.cpu_count() or 1)


def test_resumed_rows_come_first_marked(tmp_path):
    path = tmp_path / "c.ckpt"
    designs = [{"x": float(i)} for i in range(5)]
    sweep(lambda p: {"y": p["x"]}, designs[:3], executor="serial", checkpoint=path)
    seen = list(sweep_iter(lambda p: {"y": p["x"]}, designs, executor="serial",
                           checkpoint=path))
    assert [(i, row.resumed) for i, row in seen] == [(0, True), (1, True), (2, True),
                                                     (3, False), (4, False)]
    assert [row.values["y"] for _, row in seen] == [0.0, 1.0, 2.0, 3.0, 4.0]


def test_bad_arguments_raise_at_the_call():
    with pytest.raises(StudyError, match="worker_timeout"):
        sweep_iter(lambda p: {}, DESIGNS, worker_timeout=0.0)
    with pytest.raises(StudyError, match="empty"):
        sweep_iter(lambda p: {}, [])
