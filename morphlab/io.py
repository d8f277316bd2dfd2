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
:mod:`morphlab.profiles` with numeric parameters (``Constant, Ramp, SmoothStep, Sine,
Linear``). A user callable (``Custom`` or a user subclass) cannot be stored without pickling
code: it is written as ``{"$profile": null, "repr": "..."}`` and loads as an
:class:`UnsavedProfile`, which raises :class:`~morphlab.errors.FormatError` when evaluated, so
everything except ``energy`` and ``System.time_arrays`` still works.

On load, the model is rebuilt with its bodies only (for the accessors that look bodies up by
name); to simulate again, build the model anew.

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
import pickle
import tempfile
import types
import zipfile

import numpy as np

from .compile.system import BodyInfo, System
from .errors import FormatError
from .model import profiles as _profiles
from .model.model import Beam, Model, RigidBody
from .model.profiles import Profile

FORMAT_VERSION = 1
RESULT_FORMAT = "morphlab-result"
ARRAYS_FORMAT = "morphlab-arrays"
METADATA = "metadata"

# profiles of morphlab.profiles whose parameters are plain numbers, so they can be rebuilt
_STORABLE_PROFILES = ("Constant", "Ramp", "SmoothStep", "Sine", "Linear")
# System fields with their own representation (everything else: arrays or plain JSON values)
_SYSTEM_SPECIAL = ("model", "dtype", "bodies", "con_drive", "load_prof", "torque_prof")


def _morphlab_version() -> str:
    from . import __version__

    return __version__


class UnsavedProfile(Profile):
    """Stand-in for a time profile that could not be stored (a Python callable).

    Evaluating it raises :class:`~morphlab.errors.FormatError`.
    """

    def __init__(self, description: str):
        self.description = description

    def _fail(self, t):
        raise FormatError(
            f"the time profile {self.description} was a Python callable and was not saved in "
            "the file; quantities that need it (energy, System.time_arrays) are not available "
            "from a loaded result"
        )

    value = d1 = d2 = _fail

    def __repr__(self) -> str:
        return f"UnsavedProfile({self.description})"


# ---------------------------------------------------------------------------------------------
# encoding of values: JSON where exact, array members otherwise
class _Writer:
    """Collects the array members while the metadata is encoded."""

    def __init__(self):
        self.arrays: dict[str, object] = {}

    def array(self, key: str, value, scalar=False) -> dict:
        if key in self.arrays:  # pragma: no cover - keys are built to be unique
            raise FormatError(f"duplicate member {key!r}")
        self.arrays[key] = value
        return {"$array": key, "scalar": True} if scalar else {"$array": key}

    def value(self, v, key: str, where: str):
        """JSON-able form of ``v``; arrays and complex numbers become members under ``key``."""
        if v is None or isinstance(v, (bool, str)):
            return v
        if isinstance(v, np.bool_):
            return bool(v)
        if isinstance(v, (int, np.integer)) and not isinstance(v, np.bool_):
            return int(v)
        if isinstance(v, (float, np.floating)):
            return float(v)
        if isinstance(v, (complex, np.complexfloating)):
            return self.array(key, np.asarray(v), scalar=True)
        if isinstance(v, np.ndarray):
            return self.array(key, v)
        if isinstance(v, slice):
            return {"$slice": [v.start, v.stop, v.step]}
        if isinstance(v, (list, tuple)):
            return [self.value(x, f"{key}/{i}", where) for i, x in enumerate(v)]
        if isinstance(v, dict) and all(isinstance(k, str) and not k.startswith("$") for k in v):
            return {k: self.value(x, f"{key}/{k}", where) for k, x in v.items()}
        raise FormatError(
            f"{where}: a value of type {type(v).__name__} has no representation in the morphlab "
            "file format (morphlab.io needs to learn it)"
        )

    def profile(self, p, key: str) -> dict:
        name = type(p).__name__
        if (name in _STORABLE_PROFILES and type(p) is getattr(_profiles, name)
                and dataclasses.is_dataclass(p)):
            fields = {}
            try:
                for f in dataclasses.fields(p):
                    val = getattr(p, f.name)
                    if isinstance(val, (list, tuple, slice, str)) or val is None:
                        raise FormatError("not a number")
                    fields[f.name] = self.value(val, f"{key}/{f.name}", "profile")
            except FormatError:
                pass
            else:
                return {"$profile": name, "fields": fields}
        return {"$profile": None, "repr": repr(p)[:200]}


def _decode(j, arrays):
    """Inverse of :meth:`_Writer.value`."""
    if isinstance(j, dict):
        if "$array" in j:
            key = j["$array"]
            if key not in arrays:
                raise FormatError(f"member {key!r} named in the metadata is missing")
            a = arrays[key]
            return a[()] if j.get("scalar") else a
        if "$slice" in j:
            return slice(*j["$slice"])
        return {k: _decode(v, arrays) for k, v in j.items()}
    if isinstance(j, list):
        return [_decode(x, arrays) for x in j]
    return j


def _decode_profile(j, arrays) -> Profile:
    name = j.get("$profile")
    if name is None:
        return UnsavedProfile(j.get("repr", "?"))
    if name not in _STORABLE_PROFILES:
        raise FormatError(f"unknown time profile {name!r} in the file")
    return getattr(_profiles, name)(**_decode(j["fields"], arrays))


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


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


def _write_atomic(path, metadata: dict, arrays: dict) -> None:
    """Write ``metadata`` (JSON) and ``arrays`` as an ``.npz`` archive, atomically.

    Each array is converted (``np.asanyarray``) only when its member is written, like
    ``numpy.savez`` does, and object arrays are refused (they would need pickle).
    """
    try:
        text = json.dumps(metadata, allow_nan=True)
    except (TypeError, ValueError) as exc:
        raise FormatError(f"metadata cannot be written as JSON: {exc}") from exc
    path = os.fspath(path)
    folder = os.path.dirname(os.path.abspath(path))
    fd, tmp = tempfile.mkstemp(prefix=f".{os.path.basename(path)}.", suffix=".tmp", dir=folder)
    try:
        with os.fdopen(fd, "wb") as fh:
            with zipfile.ZipFile(fh, mode="w", compression=zipfile.ZIP_STORED,
                                 allowZip64=True) as zf:
                entries = [(METADATA, np.array(text))] + list(arrays.items())
                for key, value in entries:
                    arr = np.asanyarray(value)
                    if arr.dtype.hasobject:
                        raise FormatError(
                            f"array {key!r} has dtype object (e.g. None or mixed types); only "
                            "numeric, boolean and string arrays can be stored")
                    with zf.open(key + ".npy", "w", force_zip64=True) as member:
                        np.lib.format.write_array(member, np.asarray(arr), allow_pickle=False)
            fh.flush()
            os.fsync(fh.fileno())
        os.chmod(tmp, 0o666 & ~_umask())  # mkstemp creates 0600; give the usual permissions
        os.replace(tmp, path)
    except BaseException:
        try:
            os.unlink(tmp)
        except FileNotFoundError:
            pass
        raise


def _read(path, arrays_too=True) -> tuple[dict, dict]:
    """``(metadata, arrays)`` of a morphlab file (all members read into memory, or none)."""
    name = os.fspath(path)
    if not os.path.isfile(name):
        raise FileNotFoundError(f"no such file: {name!r}")
    try:
        npz = np.load(name, allow_pickle=False)
    except (ValueError, EOFError, zipfile.BadZipFile, pickle.UnpicklingError) as exc:
        raise FormatError(f"{name!r} is not a morphlab file: {exc}") from exc
    if not isinstance(npz, np.lib.npyio.NpzFile):
        raise FormatError(f"{name!r} is not a morphlab file (a single .npy array)")
    with npz:
        if METADATA not in npz.files:
            raise FormatError(f"{name!r} is not a morphlab file (no {METADATA!r} member)")
        try:
            keys = npz.files if arrays_too else [METADATA]
            arrays = {k: npz[k] for k in keys}
        except (ValueError, EOFError, zipfile.BadZipFile) as exc:
            raise FormatError(f"{name!r} is damaged: {exc}") from exc
    try:
        meta = json.loads(str(arrays.pop(METADATA)[()]))
    except (ValueError, TypeError) as exc:
        raise FormatError(f"{os.fspath(path)!r}: the metadata is not valid JSON: {exc}") from exc
    if not isinstance(meta, dict) or meta.get("format") not in (RESULT_FORMAT, ARRAYS_FORMAT):
        raise FormatError(f"{os.fspath(path)!r} is not a morphlab file (format "
                          f"{meta.get('format') if isinstance(meta, dict) else None!r})")
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
    model = Model(gravity=_decode(meta["gravity"], arrays), name=meta["model"])
    for entry in meta["bodies"]:
        p = _decode(entry["params"], arrays)
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
    """Save a :class:`~morphlab.results.result.Result` to ``path`` (``.npz``, atomic write).

    Parameters
    ----------
    result : Result
        From :func:`morphlab.simulate` or :func:`morphlab.static` (also the partial
        ``error.result`` of a failed run).
    path : str or os.PathLike
        Destination, used as given (``.npz`` is customary).

    Raises
    ------
    FormatError
        ``result`` is not a Result, or holds a value the format cannot represent; nothing is
        written then.

    Notes
    -----
    The format is described in the module docstring.
    """
    from .results.result import Result

    if not isinstance(result, Result):
        raise FormatError(f"save expects a Result, got {type(result).__name__}; use "
                          "save_arrays for a dict of arrays")
    w = _Writer()
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
    _write_atomic(path, header, w.arrays)


def load(path):
    """Load a :class:`~morphlab.results.result.Result` saved by :func:`save`.

    Returns
    -------
    Result
        Bitwise the same arrays as the saved one; ``result.system`` is a System rebuilt from
        the file whose ``model`` holds the bodies only (see the module docstring).

    Raises
    ------
    FormatError
        Not a morphlab result file (a :func:`save_arrays` file: use :func:`load_arrays`), or
        a newer format version.
    """
    from .results.result import Result
    from .solve.stepper import Settings

    meta, arrays = _read(path)
    if meta["format"] != RESULT_FORMAT:
        raise FormatError(f"{os.fspath(path)!r} holds plain arrays ({meta['format']!r}); "
                          "read it with morphlab.io.load_arrays")
    sm = meta["system"]
    model = _rebuild_model(meta, arrays)
    bodies = {}
    for entry in sm["bodies"]:
        d = _decode(entry, arrays)
        known = {f.name for f in dataclasses.fields(BodyInfo)}
        info = BodyInfo(**{k: v for k, v in d.items() if k in known})
        bodies[info.name] = info
    kwargs = {}
    for f in dataclasses.fields(System):
        key = f"system/{f.name}"
        if key in arrays:
            kwargs[f.name] = arrays[key]
        elif f.name in sm and f.name not in _SYSTEM_SPECIAL:
            kwargs[f.name] = _decode(sm[f.name], arrays)
    kwargs.update(
        model=model, dtype=np.dtype(sm["dtype"]), bodies=bodies,
        con_drive=[(row, _decode_profile(p, arrays)) for row, p in sm["con_drive"]],
        load_prof=[_decode_profile(p, arrays) for p in sm["load_prof"]],
        torque_prof=[_decode_profile(p, arrays) for p in sm["torque_prof"]],
    )
    for f in dataclasses.fields(System):  # a field newer than the file: unknown
        if f.name not in kwargs and f.default is dataclasses.MISSING \
                and f.default_factory is dataclasses.MISSING:
            kwargs[f.name] = None
    system = System(**kwargs)

    st = meta.get("settings")
    settings = None
    if st is not None:
        fields = _decode(st["fields"], arrays)
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
            rkw[f.name] = _decode(rm[f.name], arrays)
    return Result(system=system, settings=settings, **rkw)
