"""The checkpoint of a sweep: an append-only file of finished rows, tied to its task.

File format (``format_version`` 1): ASCII text, one record per line, each line the CRC-32
of its JSON text (8 hexadecimal digits), a space, the JSON text (one line, written by
Python's ``json``: floats in their shortest exact form, ``NaN`` and ``Infinity`` for
non-finite values, no spaces) and a newline::

    be2652b1 {"format":"morphlab-sweep-checkpoint","format_version":1,...}
    5c353376 {"design":[1.0,3.0],"status":"ok","values":{"area":3.0},...}

The first line is the header: the format and its version, the morphlab and Python versions
that wrote it, the design ``variables`` and the identity of the ``task``
(:mod:`.identity`). Every other line is one finished design: its values in the header's
variable order, its status, values, gradients, error text and wall time [s]. A design run
again (a failed one, on resume) gets a new line; the last one counts.

Rows are appended as they finish, all rows of a job in one write, and the file is synced
to the disk on the first append a second or more after the last sync (and at the end):
writing N rows costs O(N), never a rewrite. The header is written to a temporary file and
linked into place, so a checkpoint always starts whole. A sweep interrupted in the middle
of a write (a crash, a killed process, a full disk) leaves a last line that is incomplete
or fails its CRC: reading ignores it, like any damaged line, with a
:class:`CheckpointWarning` naming it, keeps every other line, and resuming cuts an
incomplete last line off before appending. While a sweep writes its checkpoint it holds
an exclusive lock on it (POSIX ``flock``), so two sweeps never append to one file.
"""

from __future__ import annotations

import json
import os
import sys
import tempfile
import time
import warnings
import zlib

import numpy as np

from .._version import __version__
from ..errors import MorphlabWarning, StudyError
from .identity import as_json, differences
from .sweep_result import FAILED, OK

FORMAT = "morphlab-sweep-checkpoint"
VERSION = 1
SYNC_S = 1.0  # the longest time rows stay unsynced to the disk

try:
    import fcntl
except ImportError:  # Windows: no advisory locks
    fcntl = None


class CheckpointWarning(MorphlabWarning):
    """Damaged records in a sweep checkpoint were ignored (their designs run again)."""


def _line(record: dict) -> bytes:
    text = json.dumps(record, allow_nan=True, separators=(",", ":"))
    data = text.encode("ascii")
    return b"%08x %s\n" % (zlib.crc32(data), data)


def _parse(line: bytes):
    """The JSON record of one line, or None if its CRC or its JSON is wrong."""
    if len(line) < 10 or line[8:9] != b" ":
        return None
    data = line[9:]
    try:
        if int(line[:8], 16) != zlib.crc32(data):
            return None
        return json.loads(data.decode("ascii"))
    except ValueError:
        return None


def _number(x) -> bool:
    return isinstance(x, float | int) and not isinstance(x, bool)


def _row_of(record, n_v: int):
    """``(design, row)`` of a row record, or None if it is not one."""
    try:
        design, status, values = record["design"], record["status"], record["values"]
        grads, error, wall = record["gradients"], record["error"], record["wall_time"]
        ok = (isinstance(design, list) and len(design) == n_v and all(map(_number, design))
              and status in (OK, FAILED) and isinstance(error, str) and _number(wall)
              and isinstance(values, dict) and all(map(_number, values.values()))
              and isinstance(grads, dict) and all(
                  isinstance(g, dict) and all(map(_number, g.values())) for g in grads.values()))
    except (KeyError, TypeError):
        return None
    if not ok:
        return None
    row = {"status": status, "values": {str(k): float(v) for k, v in values.items()},
           "gradients": {str(r): {str(v): float(x) for v, x in g.items()}
                         for r, g in grads.items()},
           "error": error, "wall_time": float(wall)}
    return np.array(design, dtype=float), row


def read(path, stacklevel: int = 2) -> tuple[dict, list]:
    """``(header, [(design, row), ...])`` of the checkpoint at ``path``, in file order;
    damaged records are left out with a :class:`CheckpointWarning` naming their lines.

    Raises
    ------
    StudyError
        A file that is not a sweep checkpoint (a table of :meth:`SweepResult.save`, an
        older morphlab's checkpoint, anything else), a damaged header, a newer format.
    """
    name = os.fspath(path)
    with open(name, "rb") as fh:
        data = fh.read()
    lines = data.split(b"\n")
    incomplete = lines.pop()  # b"" after a last newline, else a line cut short
    header = _parse(lines[0]) if lines else None
    if data.startswith(b"PK"):
        raise StudyError(
            f"{name!r} is a sweep table (SweepResult.save, or the checkpoint of an older "
            "morphlab) with no record of the task that made it, so its rows cannot be "
            "matched to this sweep: read it with SweepResult.load, and delete it or give "
            "another checkpoint path to start afresh")
    if not isinstance(header, dict) or header.get("format") != FORMAT:
        raise StudyError(f"{name!r} is not a sweep checkpoint (or its header is damaged): "
                         "give another checkpoint path, or delete it to start afresh")
    if not isinstance(header.get("format_version"), int) or header["format_version"] > VERSION:
        raise StudyError(f"{name!r} has checkpoint format version "
                         f"{header.get('format_version')!r}; this morphlab ({__version__}) "
                         f"reads versions up to {VERSION}: update morphlab")
    variables = header.get("variables")
    if not (isinstance(variables, list) and variables
            and all(isinstance(v, str) for v in variables)):
        raise StudyError(f"{name!r}: the checkpoint header names no design variables")
    rows, damaged = [], []
    for k, line in enumerate(lines[1:], start=2):
        parsed = _row_of(_parse(line), len(variables))
        if parsed is None:
            damaged.append(k)
        else:
            rows.append(parsed)
    if incomplete:
        damaged.append(len(lines) + 1)
    if damaged:
        shown = ", ".join(map(str, damaged[:5])) + (", ..." if len(damaged) > 5 else "")
        warnings.warn(
            f"checkpoint {name!r}: ignored {len(damaged)} damaged record(s) (line {shown}; "
            "a sweep stopped while writing leaves its last record incomplete); the rows "
            "before them are kept and their designs run again", CheckpointWarning,
            stacklevel=stacklevel + 1)
    return header, rows


def check_identity(path, header: dict, variables: list[str], identity: dict) -> None:
    """Raise a StudyError naming what differs unless the checkpoint was written for these
    variables (in any order) by a task of this identity."""
    name = os.fspath(path)
    if sorted(header["variables"]) != sorted(variables):
        raise StudyError(f"checkpoint {name!r} holds designs of {header['variables']}, these "
                         f"have {variables}: give another checkpoint path, or delete it to "
                         "start afresh")
    diff = differences(header.get("task"), as_json(identity), "task")
    if diff:
        shown = "; ".join(diff[:6]) + (f"; and {len(diff) - 6} more" if len(diff) > 6 else "")
        python = f"{sys.version_info[0]}.{sys.version_info[1]}"
        hint = "" if header.get("python") in (None, python) else (
            f" (it was written by Python {header.get('python')}, whose bytecode differs: "
            f"functions read as other code under Python {python})")
        raise StudyError(
            f"checkpoint {name!r} was written by another task, so its rows do not belong to "
            f"this sweep: {shown}{hint}. Delete the file or give another checkpoint path to "
            "start afresh")


def matched(header: dict, rows: list, variables: list[str], table: np.ndarray) -> list:
    """One slot per design of ``table``: the last ``"ok"`` row of the checkpoint whose
    design is bitwise the same, or None."""
    order = [variables.index(v) for v in header["variables"]]
    found = {design.tobytes(): row for design, row in rows if row["status"] == OK}
    keys = np.ascontiguousarray(table[:, order], dtype=np.float64)
    return [found.get(keys[i].tobytes()) for i in range(len(table))]


class Writer:
    """Appends finished rows to a checkpoint (created with its header if absent), holding
    its lock until :meth:`close`. ``variables``: the header's (the file's column order);
    ``order``: where each of them is in the designs given to :meth:`append`."""

    def __init__(self, path, variables: list[str], order: list[int], identity: dict):
        self.path, self.variables, self.order = os.fspath(path), list(variables), order
        self.fd, self.synced = None, time.monotonic()
        if not os.path.exists(self.path):
            self._create(identity)
        self.fd = os.open(self.path, os.O_RDWR | os.O_APPEND)
        try:
            if fcntl is not None:
                try:
                    fcntl.flock(self.fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
                except BlockingIOError as exc:
                    raise StudyError(f"checkpoint {self.path!r} is being written by another "
                                     "running sweep: give this one another path") from exc
            size = os.fstat(self.fd).st_size
            if size and os.pread(self.fd, 1, size - 1) != b"\n":  # cut a line left incomplete off
                with open(self.path, "rb") as fh:
                    os.ftruncate(self.fd, fh.read().rfind(b"\n") + 1)
        except BaseException:
            self.close()
            raise

    def _create(self, identity: dict) -> None:
        header = {"format": FORMAT, "format_version": VERSION, "morphlab_version": __version__,
                  "python": f"{sys.version_info[0]}.{sys.version_info[1]}",
                  "variables": self.variables, "task": identity}
        folder = os.path.dirname(os.path.abspath(self.path))
        fd, tmp = tempfile.mkstemp(prefix=f".{os.path.basename(self.path)}.", dir=folder)
        try:
            with os.fdopen(fd, "wb") as fh:
                fh.write(_line(header))
                fh.flush()
                os.fsync(fh.fileno())
            try:
                os.link(tmp, self.path)  # fails if a file appeared meanwhile: never replaced
            except FileExistsError as exc:
                raise StudyError(f"checkpoint {self.path!r} was created by another sweep "
                                 "meanwhile: give this one another path") from exc
        finally:
            os.unlink(tmp)

    def append(self, rows: list[tuple[np.ndarray, dict]]) -> None:
        """Append ``(design, row)`` records in one write; sync at most every SYNC_S."""
        data = b"".join(_line({"design": design[self.order].tolist(), **row})
                        for design, row in rows)
        view = memoryview(data)
        while view:
            view = view[os.write(self.fd, view):]
        now = time.monotonic()
        if now - self.synced >= SYNC_S:
            os.fsync(self.fd)
            self.synced = now

    def close(self) -> None:
        if self.fd is not None:
            try:
                os.fsync(self.fd)
            finally:
                os.close(self.fd)  # also releases the lock
                self.fd = None


def load_rows(path) -> tuple[list[str], np.ndarray, list[dict]]:
    """``(variables, designs, rows)`` of a checkpoint: every design once, with its last
    record, in the order first written."""
    header, records = read(path, stacklevel=3)
    last = {}
    for design, row in records:
        last[design.tobytes()] = (design, row)
    n_v = len(header["variables"])
    designs = np.array([d for d, _ in last.values()], dtype=float).reshape(len(last), n_v)
    return list(header["variables"]), designs, [r for _, r in last.values()]
