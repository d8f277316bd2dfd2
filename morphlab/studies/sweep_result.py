"""The table of a parameter study: one row per design, in the order the designs were given.

:func:`design_table` turns what a user passes as designs (a list of dicts, a dict of columns,
a pandas DataFrame) into the variable names and an ``(n, n_v)`` array; :class:`SweepResult`
holds the responses, gradients, status and error text of every row, saves and loads itself
bitwise through :func:`morphlab.io.save_arrays` and turns into a pandas DataFrame.
"""

from __future__ import annotations

import numbers
from dataclasses import dataclass

import numpy as np

from ..errors import StudyError
from ..io import load_arrays, save_arrays

SWEEP_FORMAT = "morphlab-sweep"
OK, FAILED = "ok", "failed"


def _number(value, where: str) -> float:
    """``value`` as a float, or a StudyError: only finite real numbers are design values."""
    if isinstance(value, bool | np.bool_) or not isinstance(value, numbers.Real):
        raise StudyError(f"{where} must be a finite real number, got {value!r}")
    out = float(value)
    if not np.isfinite(out):
        raise StudyError(f"{where} must be a finite real number, got {value!r}")
    return out


def _from_columns(columns: dict) -> tuple[list[str], np.ndarray]:
    names = [str(k) for k in columns]
    cols = []
    for name, col in columns.items():
        if np.ndim(col) != 1:
            raise StudyError(f"design column {name!r} must be a 1-D sequence of values, got "
                             f"{col!r}")
        arr = np.asarray(col, dtype=object)
        cols.append([_number(v, f"design {i}, variable {name!r}") for i, v in enumerate(arr)])
    lengths = {len(c) for c in cols}
    if len(lengths) != 1:
        sizes = {n: len(c) for n, c in zip(names, cols)}
        raise StudyError(f"design columns must have one length, got {sizes}")
    return names, np.array(cols, dtype=float).T.reshape(lengths.pop(), len(names))


def _from_rows(rows: list) -> tuple[list[str], np.ndarray]:
    if not all(isinstance(r, dict) for r in rows):
        bad = next(i for i, r in enumerate(rows) if not isinstance(r, dict))
        raise StudyError(f"designs given as a list must be dicts of variable -> value; design "
                         f"{bad} is {type(rows[bad]).__name__}")
    names = [str(k) for k in rows[0]]
    table = np.empty((len(rows), len(names)))
    for i, row in enumerate(rows):
        if set(map(str, row)) != set(names):
            raise StudyError(f"design {i} has the variables {sorted(map(str, row))}, design 0 "
                             f"has {sorted(names)}: every design needs the same ones")
        for j, name in enumerate(names):
            table[i, j] = _number(row[name], f"design {i}, variable {name!r}")
    return names, table


def design_table(designs) -> tuple[list[str], np.ndarray]:
    """Variable names and an ``(n, n_v)`` float array from a list of dicts, a dict of columns
    or a pandas DataFrame (columns = variables).

    Raises
    ------
    StudyError
        No designs, no variables, designs with different variables, columns of different
        lengths, values that are not finite real numbers.
    """
    if hasattr(designs, "columns") and hasattr(designs, "to_dict"):  # a DataFrame
        designs = {c: designs[c].to_numpy() for c in designs.columns}
    if isinstance(designs, dict):
        names, table = _from_columns(designs) if designs else ([], np.empty((0, 0)))
    elif isinstance(designs, list | tuple):
        names, table = _from_rows(list(designs)) if designs else ([], np.empty((0, 0)))
    else:
        raise StudyError("designs must be a list of dicts, a dict of columns or a pandas "
                         f"DataFrame, got {type(designs).__name__}")
    if table.shape[0] == 0 or not names:
        raise StudyError("designs is empty: give at least one design with one variable")
    if len(set(names)) != len(names):
        raise StudyError(f"design variables named twice: {names}")
    return names, table


@dataclass
class SweepResult:
    """Responses of a parameter study, one row per design (in the order given).

    Attributes
    ----------
    variables : list of str
        Design variable names (the columns of ``designs``).
    designs : (n, n_v) float array
        The designs, one per row.
    values : dict of str -> (n,) float array
        Response values; NaN in failed rows.
    gradients : dict of str -> dict of str -> (n,) float array
        ``gradients[r][v]``: derivative of response r by variable v (tasks with gradients
        only, else empty; NaN in failed rows).
    status : (n,) str array
        ``"ok"`` or ``"failed"``.
    errors : list of str
        The exception type and message of each failed row (``""`` for ok rows).
    wall_time : (n,) float array
        Seconds each design took in its worker (of its last attempt).
    """

    variables: list[str]
    designs: np.ndarray
    values: dict[str, np.ndarray]
    gradients: dict[str, dict[str, np.ndarray]]
    status: np.ndarray
    errors: list[str]
    wall_time: np.ndarray

    @property
    def ok(self) -> np.ndarray:
        """(n,) bool: the rows with status ``"ok"``."""
        return self.status == OK

    def __len__(self) -> int:
        return len(self.designs)

    def design(self, i: int) -> dict[str, float]:
        """Row ``i`` as the dict the task received."""
        return {v: float(x) for v, x in zip(self.variables, self.designs[i])}

    def __repr__(self) -> str:
        n_ok = int(np.sum(self.ok))
        grad = f", gradients by {len(next(iter(self.gradients.values())))} variables" if (
            self.gradients) else ""
        return (f"SweepResult({len(self)} designs of {self.variables}, responses "
                f"{list(self.values)}{grad}; {n_ok} ok, {len(self) - n_ok} failed, "
                f"{float(np.sum(self.wall_time)):.3g} s of work)")

    def to_pandas(self):
        """A pandas DataFrame: the variables, the responses, ``d(r)/d(v)`` columns, status,
        error and wall time."""
        try:
            import pandas as pd
        except ImportError as exc:
            raise ImportError("SweepResult.to_pandas needs pandas: pip install pandas (or "
                              "pip install 'morphlab[tables]')") from exc
        cols = {v: self.designs[:, j] for j, v in enumerate(self.variables)}
        cols.update(self.values)
        for r, by_v in self.gradients.items():
            cols.update({f"d({r})/d({v})": g for v, g in by_v.items()})
        cols.update(status=self.status, error=self.errors, wall_time=self.wall_time)
        return pd.DataFrame(cols)

    def save(self, path) -> None:
        """Write the table to ``path`` (``.npz``, atomic; floats bitwise)."""
        arrays = {"designs": self.designs, "status": np.asarray(self.status, dtype=str),
                  "errors": np.asarray(self.errors, dtype=str).reshape(len(self)),
                  "wall_time": self.wall_time}
        arrays.update({f"values/{i}": a for i, a in enumerate(self.values.values())})
        grad_vars = list(next(iter(self.gradients.values()))) if self.gradients else []
        for i, by_v in enumerate(self.gradients.values()):
            arrays.update({f"gradients/{i}/{j}": by_v[v] for j, v in enumerate(grad_vars)})
        meta = {"format": SWEEP_FORMAT, "variables": self.variables,
                "responses": list(self.values), "gradient_responses": list(self.gradients),
                "gradient_variables": grad_vars}
        save_arrays(path, arrays, meta)

    @classmethod
    def load(cls, path) -> SweepResult:
        """Read a table written by :meth:`save`, or the rows of a sweep checkpoint (each
        design once, with its last record, in the order they finished)."""
        if is_checkpoint(path):
            from .checkpoint import load_rows

            variables, designs, rows = load_rows(path)
            return assemble(variables, designs, rows)
        arrays, meta = load_arrays(path)
        if meta.get("format") != SWEEP_FORMAT:
            raise StudyError(f"{path} is not a sweep table (format {meta.get('format')!r})")
        values = {r: arrays[f"values/{i}"] for i, r in enumerate(meta["responses"])}
        gradients = {r: {v: arrays[f"gradients/{i}/{j}"]
                         for j, v in enumerate(meta["gradient_variables"])}
                     for i, r in enumerate(meta["gradient_responses"])}
        return cls(list(meta["variables"]), arrays["designs"], values, gradients,
                   arrays["status"].astype(object), [str(e) for e in arrays["errors"]],
                   arrays["wall_time"])


def is_checkpoint(path) -> bool:
    """True if ``path`` starts like a sweep checkpoint (:mod:`.checkpoint`)."""
    try:
        with open(path, "rb") as fh:
            head = fh.read(64)
    except OSError:
        return False
    return head[9:].startswith(b'{"format":"morphlab-sweep-checkpoint"')


@dataclass(frozen=True)
class SweepRow:
    """The outcome of one design, as :func:`~.sweep.sweep_iter` yields it.

    Attributes
    ----------
    design : dict of str -> float
        The design, as the task received it.
    status : str
        ``"ok"`` or ``"failed"``.
    values : dict of str -> float
        Response values (empty when failed).
    gradients : dict of str -> dict of str -> float
        ``gradients[r][v]``, d(response r)/d(variable v) (tasks with gradients only).
    error : str
        The exception's type and message of a failed design (``""`` when ok).
    wall_time : float
        Seconds the design took in its worker (its last attempt).
    resumed : bool
        True for a row read from the checkpoint instead of run.
    """

    design: dict
    status: str
    values: dict
    gradients: dict
    error: str
    wall_time: float
    resumed: bool = False

    @property
    def ok(self) -> bool:
        return self.status == OK


class SweepAborted(StudyError):
    """A sweep stopped before every design finished (e.g. a Dask cluster without workers for
    longer than ``worker_timeout``).

    Attributes
    ----------
    partial : SweepResult
        The rows finished so far, in the order given (also in the checkpoint, if any).
    indices : (k,) int array
        Their positions in the designs given.
    """

    def __init__(self, message: str, *, partial: SweepResult, indices: np.ndarray):
        super().__init__(message)
        self.partial, self.indices = partial, indices


def assemble(variables: list[str], designs: np.ndarray, rows: list[dict]) -> SweepResult:
    """A SweepResult from one row dict per design (``status``, ``values``, ``gradients``,
    ``error``, ``wall_time``); responses named in any row, NaN where a row lacks one."""
    n = len(rows)
    names, grad_names, grad_vars = [], [], []
    for row in rows:
        names += [r for r in row["values"] if r not in names]
        for r, by_v in row["gradients"].items():
            grad_names += [r] if r not in grad_names else []
            grad_vars += [v for v in by_v if v not in grad_vars]
    values = {r: np.full(n, np.nan) for r in names}
    gradients = {r: {v: np.full(n, np.nan) for v in grad_vars} for r in grad_names}
    for i, row in enumerate(rows):
        for r, x in row["values"].items():
            values[r][i] = x
        for r, by_v in row["gradients"].items():
            for v, g in by_v.items():
                gradients[r][v][i] = g
    status = np.array([row["status"] for row in rows], dtype=object)
    return SweepResult(list(variables), np.asarray(designs, dtype=float), values, gradients,
                       status, [row["error"] for row in rows],
                       np.array([row["wall_time"] for row in rows], dtype=float))


def rows_of(result: SweepResult) -> list[dict]:
    """The row dicts of a table (the inverse of :func:`assemble`)."""
    rows = []
    for i in range(len(result)):
        rows.append({"status": str(result.status[i]), "error": result.errors[i],
                     "wall_time": float(result.wall_time[i]),
                     "values": {r: float(a[i]) for r, a in result.values.items()
                                if not np.isnan(a[i])},
                     "gradients": {r: {v: float(g[i]) for v, g in by_v.items()
                                       if not np.isnan(g[i])}
                                   for r, by_v in result.gradients.items()
                                   if result.status[i] == OK}})
    return rows
