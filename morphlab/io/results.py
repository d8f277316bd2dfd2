"""Saving and loading a Result or a SensitivityResult (the ``"morphlab-result"`` and
``"morphlab-sensitivity"`` kinds of :mod:`morphlab.io`)."""

from __future__ import annotations

import dataclasses
import os
import types

import numpy as np

from ..errors import FormatError
from ..results.result import Result
from ..sensitivity.api import SensitivityResult
from ..solve.settings import Settings, StaticSettings
from .encoding import Writer, decode
from .files import (
    ARRAYS_FORMAT,
    FORMAT_VERSION,
    RESULT_FORMAT,
    SENSITIVITY_FORMAT,
    morphlab_version,
    read_file,
    write_file,
)
from .system import bodies_meta, system_from, system_meta, units_meta


def save(result, path) -> None:
    """Save a :class:`~morphlab.results.result.Result` or a
    :class:`~morphlab.sensitivity.SensitivityResult` to ``path`` (``.npz``, atomic write).

    Parameters
    ----------
    result : Result or SensitivityResult
        From :func:`morphlab.simulate` or :func:`morphlab.static` (also the partial
        ``error.result`` of a failed run), or from :func:`morphlab.sensitivities` (values,
        gradients, design, kept sensitivity histories and its primal result).
    path : str or os.PathLike
        Destination, used as given (``.npz`` is customary).

    Raises
    ------
    FormatError
        ``result`` is neither (the message says so when the arguments are swapped), or holds
        a value the format cannot represent; nothing is written then.
    OSError
        The file cannot be written (disk full, no permission): the message names it, an
        existing file at ``path`` is left untouched.

    Notes
    -----
    The format is described in the module docstring.
    """
    if isinstance(path, (Result, SensitivityResult)):
        raise FormatError(f"save(result, path): the result comes first, then the path; got "
                          f"{type(result).__name__} {result!r} first and a "
                          f"{type(path).__name__} second: swap the arguments")
    w = Writer()
    if isinstance(result, SensitivityResult):
        header = _result_header(result.result, w)
        header["format"] = SENSITIVITY_FORMAT
        header["sensitivity"] = _sensitivity_meta(result, w)
    elif isinstance(result, Result):
        header = _result_header(result, w)
    else:
        raise FormatError(f"save expects a Result or a SensitivityResult, got "
                          f"{type(result).__name__}; use save_arrays for a dict of arrays")
    write_file(path, header, w.arrays)


def _sensitivity_meta(sens, w: Writer) -> dict:
    where = "SensitivityResult"
    return {
        "method": sens.method, "variables": [str(v) for v in sens.variables],
        "design": w.value(dict(sens.design), "sensitivity/design", f"{where}.design"),
        "values": w.value(dict(sens.values), "sensitivity/values", f"{where}.values"),
        "gradients": w.value({k: dict(g) for k, g in sens.gradients.items()},
                             "sensitivity/gradients", f"{where}.gradients"),
        "timing": w.value(dict(sens.timing), "sensitivity/timing", f"{where}.timing"),
        "stats": w.value(dict(sens.stats), "sensitivity/stats", f"{where}.stats"),
        "state": {k: w.array(f"sensitivity/state/{k}", v) for k, v in sens.state.items()},
    }


def _result_fields(result: Result, w: Writer) -> dict:
    """The ``"result"`` entry: every field of ``result`` but the system, the settings and
    the caches (arrays to ``w``)."""
    res_meta = {}
    for f in dataclasses.fields(result):
        if f.name in ("system", "settings", "energy_cache", "kinematics_cache"):  # derived data
            continue
        val = getattr(result, f.name)
        if f.name == "newton_history":
            res_meta[f.name] = [[[float(x) for x in pair] for pair in step] for step in val]
        elif val is None:  # a history the run did not keep (``store``)
            res_meta[f.name] = None
        elif isinstance(val, np.ndarray) or f.type in ("np.ndarray", np.ndarray):
            w.array(f"result/{f.name}", val)  # converted while the member is written
        else:
            res_meta[f.name] = w.value(val, f"result/{f.name}", f"Result.{f.name}")
    return res_meta


def _result_header(result: Result, w: Writer) -> dict:
    """The metadata of ``result`` (its arrays go to ``w``)."""
    model = result.system.model
    res_meta = _result_fields(result, w)
    st = result.settings
    if dataclasses.is_dataclass(st) and not isinstance(st, type):
        settings = {"class": type(st).__name__,
                    "fields": w.value(dataclasses.asdict(st), "settings", "Result.settings")}
    else:
        settings = None
    sys_meta = system_meta(result.system, w)
    model_bodies = bodies_meta(model, w)
    return {
        "format": RESULT_FORMAT, "format_version": FORMAT_VERSION,
        "morphlab_version": morphlab_version(), "model": model.name,
        "gravity": w.value(np.asarray(model.gravity), "model/gravity", "Model.gravity"),
        "settings": settings, "result": res_meta, "system": sys_meta, "bodies": model_bodies,
        "units": units_meta(model),
    }


def load(path):
    """Load a :class:`~morphlab.results.result.Result` or a
    :class:`~morphlab.sensitivity.SensitivityResult` saved by :func:`save`.

    Returns
    -------
    Result or SensitivityResult
        Bitwise the same arrays and numbers as the saved one; ``result.system`` is a System
        rebuilt from the file whose ``model`` holds the bodies only (see the module
        docstring).

    Raises
    ------
    FormatError
        Not a morphlab result file (a :func:`save_arrays` file: use :func:`load_arrays`), a
        newer format version, or a damaged or incomplete file; the message names the file.
    """
    meta, arrays = read_file(path)
    name = os.fspath(path)
    if meta["format"] == ARRAYS_FORMAT:
        raise FormatError(f"{name!r} holds plain arrays ({meta['format']!r}); "
                          "read it with morphlab.io.load_arrays")
    try:
        result = _result_from(meta, arrays)
        if meta["format"] == SENSITIVITY_FORMAT:
            return _sensitivity_from(meta["sensitivity"], arrays, result)
        return result
    except FormatError as exc:
        raise FormatError(f"{name!r}: {exc}") from exc
    except (KeyError, TypeError, ValueError, IndexError, AttributeError) as exc:
        raise FormatError(f"{name!r} is incomplete or damaged: {type(exc).__name__}: "
                          f"{exc}") from exc


def _sensitivity_from(sm: dict, arrays: dict, result):
    return SensitivityResult(
        method=sm["method"], variables=list(sm["variables"]), result=result,
        values=decode(sm["values"], arrays), gradients=decode(sm["gradients"], arrays),
        state={k: decode(v, arrays) for k, v in sm["state"].items()},
        timing=decode(sm["timing"], arrays), stats=decode(sm["stats"], arrays),
        design=decode(sm["design"], arrays))


def _settings_from(st: dict | None, arrays: dict):
    """The solver settings of a file: a Settings (fields it does not know dropped), a
    namespace of the fields of another settings class, or None."""
    if st is None:
        return None
    fields = decode(st["fields"], arrays)
    for cls in (Settings, StaticSettings):
        if st.get("class") == cls.__name__:
            names = {f.name for f in dataclasses.fields(cls)}
            return cls(**{k: v for k, v in fields.items() if k in names})
    return types.SimpleNamespace(**fields)


def _result_from(meta: dict, arrays: dict) -> Result:
    system = system_from(meta, arrays)
    settings = _settings_from(meta.get("settings"), arrays)
    rm = meta["result"]
    rkw = {}
    for f in dataclasses.fields(Result):
        if f.name in ("system", "settings"):
            continue
        key = f"result/{f.name}"
        if key in arrays:
            rkw[f.name] = arrays[key]
        elif f.name == "newton_history" and f.name in rm:
            rkw[f.name] = [[tuple(pair) for pair in step] for step in rm[f.name]]
        elif f.name in rm:
            rkw[f.name] = decode(rm[f.name], arrays)
    return Result(system=system, settings=settings, **rkw)
