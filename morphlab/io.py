"""Saving and loading results: a documented ``.npz`` format, written atomically.

Functions
---------
``save(result, path)`` / ``load(path)``
    A :class:`~morphlab.results.result.Result` (a simulation or a static equilibrium path) with
    everything its accessors need: a loaded result gives bitwise the same ``t, q, v, a, lam``
    and the same ``node_positions``, ``stress``, ``point_positions``, ``reference``, ``dof``,
    ``summary`` and (when every time profile of the model could be stored) ``energy``.
``save_arrays(path, arrays, meta)`` / ``load_arrays(path)``
    A plain dict of arrays with a JSON-serializable dict of metadata (sensitivity results,
    studies, anything else).
``read_metadata(path)``
    The JSON metadata of either kind of file, without loading the arrays.

File format (``format_version`` 1)
----------------------------------
A file is an uncompressed ZIP archive of ``.npy`` members, i.e. a NumPy ``.npz`` file: it opens
with ``numpy.load(path, allow_pickle=False)`` and holds no pickled Python objects. The member
``metadata`` is a 0-d unicode array with one JSON document::

    {"format": "morphlab-result" or "morphlab-arrays",
     "format_version": 1,
     "morphlab_version": "0.1.0",
     ...}

JSON numbers are written by Python's ``json`` (shortest repr that reads back to the same
float, ``NaN``/``Infinity`` for non-finite values). A value that JSON cannot hold exactly -- an
array, a complex number -- is stored as a member of its own and referenced from the metadata
by ``{"$array": "<member name>"}`` (``"scalar": true`` when it was a scalar); slices are
``{"$slice": [start, stop, step]}``.

Every file lists its array members in ``"members"`` (sorted), so a damaged directory that
hides members is found.

``"morphlab-arrays"`` files add ``"meta"`` (the caller's dict) and ``"arrays"`` (the member
names); every other member is one array of the caller's dict under its own key.

``"morphlab-result"`` files add:

``"model"``
    The model's name.
``"settings"``
    ``{"class": "Settings", "fields": dataclasses.asdict(result.settings)}`` (solver settings:
    ``t_end, dt, rho_inf, tol, max_iter, stabilization, ...``).
``"result"``
    Every field of the Result that is not an array (``status, message, n_factorizations,
    wall_time, scale, newton_history``); the array fields are members ``result/<field>``
    (``result/t`` (n_t,), ``result/q``, ``result/v``, ``result/a`` (n_t, n_dof),
    ``result/lam`` (n_t, n_con), ``result/newton_iterations``,
    ``result/constraint_violation``, ``result/velocity_violation`` (n_t,)).
``"system"``
    The compiled :class:`~morphlab.compile.System` without its model: ``dtype``, ``n_dof``,
    ``n_con``, ``length_scale``, ``dof_names``, ``con_names``, ``con_joint``; ``bodies`` (per
    body: ``name, index, kind, elements`` and its arrays ``ref`` (3,), ``angle0``,
    ``node_dofs`` (n_node, 3), ``X`` (n_node, 2) as members ``system/bodies/<i>/<field>``);
    the time profiles ``con_drive`` (``[row, profile]`` pairs), ``load_prof``, ``torque_prof``.
    Every array of the System (``q0, v0, elem_B, elem_dofs, con_u0, indptr, ...``) is a member
    ``system/<field>``.
``"bodies"``
    The bodies of the model (not its joints and loads, which live in the System arrays):
    ``{"kind": "rigid" | "beam", "name", <constructor parameters>}``, numbers inline or as
    members ``model/bodies/<i>/<parameter>``; ``"gravity"`` likewise.

A time profile is ``{"$profile": "<class name>", "fields": {...}}`` for the profiles of
:mod:`morphlab.model.profiles` built from numbers (``Constant, Ramp, SmoothStep, Sine, Linear,
Polynomial``) and from such profiles (``Sum, Scaled, Product, Integral``: their profile fields
nested the same way). A user callable (``Custom`` or a user subclass) cannot be stored
without pickling code: it is written as ``{"$profile": null, "repr": "..."}`` and loads as an
:class:`UnsavedProfile`, which raises :class:`~morphlab.errors.FormatError` when evaluated, so
everything except ``energy`` and ``System.time_arrays`` still works.

``"morphlab-sensitivity"`` files (a :class:`~morphlab.sensitivity.SensitivityResult`) are
result files of its primal ``result`` plus ``"sensitivity"``: ``method``, ``variables``,
``design`` (the nominal ``p0``), ``values``, ``gradients``, ``timing``, ``stats`` and
``state`` (the kept sensitivity histories, members ``sensitivity/state/<name>``, e.g.
``(n_t, n_dof, n_x)``). A loaded one has no perturbed histories: ``derivative()`` needs the
live object.

On load, the model is rebuilt with its bodies only (for the accessors that look bodies up by
name); to simulate again, build the model anew.

Verified reading
----------------
Every member read is read to its end, so its CRC-32 is checked, and its ``.npy`` header must
describe exactly its bytes (:mod:`morphlab.archive`); a damaged, foreign or incomplete file
(missing members or metadata keys included) raises :class:`~morphlab.errors.FormatError`
naming the file.

Atomic writes
-------------
The archive is written to a temporary file in the destination folder, flushed to disk, and
moved over ``path`` with :func:`os.replace` (atomic on POSIX and Windows within one file
system). If anything fails while writing, the temporary file is removed and an existing file
at ``path`` is left untouched: there is never a partial file under the final name.
"""

from __future__ import annotations

import dataclasses
import json
import os
import types

import numpy as np

from .archive import (  # noqa: F401 - UnsavedProfile: loaded profiles are of this class
    UnsavedProfile,
    Writer,
    decode,
    decode_profile,
    read_members,
    write_members,
)
from .compile.system import BodyInfo, System
from .errors import FormatError
from .model import Beam, Model, RigidBody

FORMAT_VERSION = 1
RESULT_FORMAT = "morphlab-result"
SENSITIVITY_FORMAT = "morphlab-sensitivity"
ARRAYS_FORMAT = "morphlab-arrays"
METADATA = "metadata"

# System fields with their own representation (everything else: arrays or plain JSON values)
_SYSTEM_SPECIAL = ("model", "dtype", "bodies", "con_drive", "load_prof", "torque_prof")


def _morphlab_version() -> str:
    from . import __version__

    return __version__


# ---------------------------------------------------------------------------------------------
# the archive itself
def _check_key(key) -> str:
    if not isinstance(key, str) or not key:
        raise FormatError(f"array names must be non-empty strings, got {key!r}")
    if key == METADATA or key.startswith("/") or "\\" in key or ".." in key.split("/"):
        raise FormatError(
            f"array name {key!r} is not allowed ({METADATA!r} is reserved; no leading '/', "
            "backslashes or '..' parts)"
        )
    return key


def _write_atomic(path, metadata: dict, arrays: dict) -> None:
    """Write ``metadata`` (JSON) and ``arrays`` as an ``.npz`` archive, atomically
    (:func:`morphlab.archive.write_members`)."""
    metadata = {**metadata, "members": sorted(arrays)}
    try:
        text = json.dumps(metadata, allow_nan=True)
    except (TypeError, ValueError) as exc:
        raise FormatError(f"metadata cannot be written as JSON: {exc}") from exc
    write_members(path, [(METADATA, np.array(text))] + list(arrays.items()))


def _read(path, arrays_too=True) -> tuple[dict, dict]:
    """``(metadata, arrays)`` of a morphlab file (all members read into memory, or none)."""
    name = os.fspath(path)
    arrays = read_members(name, None if arrays_too else [METADATA])
    if METADATA not in arrays:
        raise FormatError(f"{name!r} is not a morphlab file (no {METADATA!r} member)")
    try:
        meta = json.loads(str(arrays.pop(METADATA)[()]))
    except (ValueError, TypeError, RecursionError) as exc:
        raise FormatError(f"{os.fspath(path)!r}: the metadata is not valid JSON: {exc}") from exc
    kinds = (RESULT_FORMAT, ARRAYS_FORMAT, SENSITIVITY_FORMAT)
    if not isinstance(meta, dict) or meta.get("format") not in kinds:
        raise FormatError(f"{os.fspath(path)!r} is not a morphlab file (format "
                          f"{meta.get('format') if isinstance(meta, dict) else None!r})")
    members = meta.get("members")
    if arrays_too and members is not None and sorted(arrays) != members:
        lost = sorted(set(members) - set(arrays)) or sorted(set(arrays) - set(members))
        raise FormatError(f"{os.fspath(path)!r} is incomplete or damaged: its directory does "
                          f"not list the members of its metadata (e.g. {lost[:3]})")
    version = meta.get("format_version")
    if not isinstance(version, int) or version > FORMAT_VERSION:
        raise FormatError(
            f"{os.fspath(path)!r} has format version {version!r}; this morphlab "
            f"({_morphlab_version()}) reads versions up to {FORMAT_VERSION}: update morphlab"
        )
    return meta, arrays


def read_metadata(path) -> dict:
    """The JSON metadata of a morphlab file (either kind), as a dict."""
    return _read(path, arrays_too=False)[0]


# ---------------------------------------------------------------------------------------------
# plain arrays
def save_arrays(path, arrays: dict, meta: dict | None = None) -> None:
    """Save a dict of arrays and a dict of metadata to ``path`` (``.npz``, atomic write).

    Parameters
    ----------
    path : str or os.PathLike
        Destination, used as given (no extension is added; ``.npz`` is customary).
    arrays : dict of str -> array_like
        Numeric, boolean or string arrays of any shape and dtype (no object arrays). Names
        may contain ``/`` to group them; ``"metadata"`` is reserved.
    meta : dict, optional
        JSON-serializable metadata (design variables, settings, units, ...).

    Raises
    ------
    FormatError
        Invalid names, object arrays, metadata that is not JSON; nothing is written then.
    """
    if not isinstance(arrays, dict):
        raise FormatError(f"arrays must be a dict of name -> array, got {type(arrays).__name__}")
    meta = {} if meta is None else meta
    if not isinstance(meta, dict):
        raise FormatError(f"meta must be a dict, got {type(meta).__name__}")
    keys = [_check_key(k) for k in arrays]
    header = {"format": ARRAYS_FORMAT, "format_version": FORMAT_VERSION,
              "morphlab_version": _morphlab_version(), "arrays": keys, "meta": meta}
    _write_atomic(path, header, arrays)


def load_arrays(path) -> tuple[dict, dict]:
    """Load a file written by :func:`save_arrays`: ``(arrays, meta)``.

    On a result file (written by :func:`save`) it returns all of its members and its whole
    metadata, for inspection.
    """
    meta, arrays = _read(path)
    if meta["format"] == ARRAYS_FORMAT:
        return arrays, meta.get("meta", {})
    return arrays, meta


# ---------------------------------------------------------------------------------------------
# results
def _body_params(body) -> tuple[str, dict]:
    if isinstance(body, RigidBody):
        names = ("mass", "inertia", "position", "angle", "velocity", "angular_velocity")
        return "rigid", {k: getattr(body, k) for k in names}
    if isinstance(body, Beam):
        names = ("nodes", "E", "rho", "area", "second_moment", "fibre", "damping",
                 "reference_node", "thickness", "width", "frames", "reference")
        return "beam", {k: getattr(body, k) for k in names}
    raise FormatError(f"body {body.name!r} of type {type(body).__name__} cannot be saved")


def _frame_params(p: dict) -> dict:
    """The frame arguments of a saved beam; a file from before several frames existed holds
    ``reference_node`` only (a single tangent frame)."""
    if p.get("reference_node") is not None:
        return {"reference_node": int(p["reference_node"])}
    return {"frames": int(p["frames"]), "reference": p["reference"]}


def _rebuild_model(meta: dict, arrays: dict) -> Model:
    model = Model(gravity=decode(meta["gravity"], arrays), name=meta["model"])
    for entry in meta["bodies"]:
        p = decode(entry["params"], arrays)
        if entry["kind"] == "rigid":
            body = RigidBody(p["mass"], p["inertia"], p["position"], p["angle"],
                             velocity=p["velocity"], angular_velocity=p["angular_velocity"],
                             name=entry["name"])
        elif entry["kind"] == "beam":
            fibre = p["fibre"] if np.all(np.real(p["fibre"]) != 0) else None
            body = Beam(p["nodes"], E=p["E"], rho=p["rho"], area=p["area"],
                        second_moment=p["second_moment"], fibre=fibre, damping=p["damping"],
                        name=entry["name"], **_frame_params(p))
            body.thickness, body.width = p["thickness"], p["width"]
            body.fibre = p["fibre"]
        else:
            raise FormatError(f"unknown body kind {entry['kind']!r} in the file")
        model.add_body(body)
    return model


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
        ``result`` is neither, or holds a value the format cannot represent; nothing is
        written then.
    OSError
        The file cannot be written (disk full, no permission): the message names it, an
        existing file at ``path`` is left untouched.

    Notes
    -----
    The format is described in the module docstring.
    """
    from .results.result import Result
    from .sensitivity.api import SensitivityResult

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
    _write_atomic(path, header, w.arrays)


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


def _result_header(result, w: Writer) -> dict:
    """The metadata of ``result`` (its arrays go to ``w``)."""
    system: System = result.system
    model = system.model
    # ---- result fields
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
    st = result.settings
    if dataclasses.is_dataclass(st) and not isinstance(st, type):
        settings = {"class": type(st).__name__,
                    "fields": w.value(dataclasses.asdict(st), "settings", "Result.settings")}
    else:
        settings = None
    # ---- system fields
    sys_meta = {"dtype": np.dtype(system.dtype).str}
    for f in dataclasses.fields(system):
        val = getattr(system, f.name)
        if f.name in _SYSTEM_SPECIAL:
            continue
        if isinstance(val, np.ndarray):
            w.array(f"system/{f.name}", val)
        else:
            sys_meta[f.name] = w.value(val, f"system/{f.name}", f"System.{f.name}")
    bodies = []
    for i, (name, info) in enumerate(system.bodies.items()):
        entry = {}
        for f in dataclasses.fields(info):
            entry[f.name] = w.value(getattr(info, f.name), f"system/bodies/{i}/{f.name}",
                                    f"BodyInfo {name!r}.{f.name}")
        bodies.append(entry)
    sys_meta["bodies"] = bodies
    sys_meta["con_drive"] = [[int(row), w.profile(p, f"system/con_drive/{k}")]
                             for k, (row, p) in enumerate(system.con_drive)]
    sys_meta["load_prof"] = [w.profile(p, f"system/load_prof/{k}")
                             for k, p in enumerate(system.load_prof)]
    sys_meta["torque_prof"] = [w.profile(p, f"system/torque_prof/{k}")
                               for k, p in enumerate(system.torque_prof)]
    # ---- model bodies
    model_bodies = []
    for i, body in enumerate(model.bodies):
        kind, params = _body_params(body)
        model_bodies.append({"kind": kind, "name": body.name, "params": {
            k: w.value(v, f"model/bodies/{i}/{k}", f"body {body.name!r}.{k}")
            for k, v in params.items()}})
    header = {
        "format": RESULT_FORMAT, "format_version": FORMAT_VERSION,
        "morphlab_version": _morphlab_version(), "model": model.name,
        "gravity": w.value(np.asarray(model.gravity), "model/gravity", "Model.gravity"),
        "settings": settings, "result": res_meta, "system": sys_meta, "bodies": model_bodies,
    }
    return header


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
    meta, arrays = _read(path)
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
    from .sensitivity.api import SensitivityResult

    return SensitivityResult(
        method=sm["method"], variables=list(sm["variables"]), result=result,
        values=decode(sm["values"], arrays), gradients=decode(sm["gradients"], arrays),
        state={k: decode(v, arrays) for k, v in sm["state"].items()},
        timing=decode(sm["timing"], arrays), stats=decode(sm["stats"], arrays),
        design=decode(sm["design"], arrays))


def _result_from(meta: dict, arrays: dict):
    from .results.result import Result
    from .solve.stepper import Settings

    sm = meta["system"]
    model = _rebuild_model(meta, arrays)
    bodies = {}
    for entry in sm["bodies"]:
        d = decode(entry, arrays)
        known = {f.name for f in dataclasses.fields(BodyInfo)}
        info = BodyInfo(**{k: v for k, v in d.items() if k in known})
        bodies[info.name] = info
    kwargs = {}
    for f in dataclasses.fields(System):
        key = f"system/{f.name}"
        if key in arrays:
            kwargs[f.name] = arrays[key]
        elif f.name in sm and f.name not in _SYSTEM_SPECIAL:
            kwargs[f.name] = decode(sm[f.name], arrays)
    kwargs.update(
        model=model, dtype=np.dtype(sm["dtype"]), bodies=bodies,
        con_drive=[(row, decode_profile(p, arrays)) for row, p in sm["con_drive"]],
        load_prof=[decode_profile(p, arrays) for p in sm["load_prof"]],
        torque_prof=[decode_profile(p, arrays) for p in sm["torque_prof"]],
    )
    for f in dataclasses.fields(System):  # a field newer than the file: unknown
        if f.name not in kwargs and f.default is dataclasses.MISSING \
                and f.default_factory is dataclasses.MISSING:
            kwargs[f.name] = None
    system = System(**kwargs)

    st = meta.get("settings")
    settings = None
    if st is not None:
        fields = decode(st["fields"], arrays)
        if st.get("class") == "Settings":
            names = {f.name for f in dataclasses.fields(Settings)}
            settings = Settings(**{k: v for k, v in fields.items() if k in names})
        else:
            settings = types.SimpleNamespace(**fields)

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
