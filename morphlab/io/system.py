"""The compiled System and the model's bodies in a result file: the ``"system"``,
``"bodies"`` and ``"gravity"`` entries of the metadata and their members (format in
:mod:`morphlab.io`). The kinds' tables are written field by field as the schema declares them
(:mod:`morphlab.kernels.schema`), so a new kind of item needs nothing here."""

from __future__ import annotations

import dataclasses

import numpy as np

from ..compile.design import flatten
from ..compile.system import BodyInfo, System
from ..errors import FormatError
from ..kernels.schema import KINDS, TIME
from ..kernels.system import KIND_NAMES, SystemArrays
from ..model import Beam, Model, RigidBody, units
from .encoding import Writer, decode, decode_profile

# System fields with their own representation (everything else: arrays or plain JSON values)
_SYSTEM_SPECIAL = ("model", "dtype", "bodies", "arrays", "design", "time_base",
                   "time_profiles", "names")
# System fields that are not part of the file: the compile record is a cache of the compile
# (a loaded System compiles its designs from scratch)
_NOT_SAVED = ("record",)


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


def bodies_meta(model: Model, w: Writer) -> list:
    """The ``"bodies"`` entry: kind, name and constructor parameters of every body."""
    out = []
    for i, body in enumerate(model.bodies):
        kind, params = _body_params(body)
        out.append({"kind": kind, "name": body.name, "params": {
            k: w.value(v, f"model/bodies/{i}/{k}", f"body {body.name!r}.{k}")
            for k, v in params.items()}})
    return out


def units_meta(model) -> str | dict | None:
    """The unit system a model declares (``model.units``): its name, or its fields for a
    system of the user's own; None when it declares none."""
    u = units.of(getattr(model, "units", None))
    if u is None or isinstance(u, str) or u in units.SYSTEMS:
        return u if not isinstance(u, units.UnitSystem) else u.name
    return dataclasses.asdict(u)


def rebuild_model(meta: dict, arrays: dict) -> Model:
    """The model of a file: its bodies, gravity and declared units, no joints or loads."""
    model = Model(gravity=decode(meta["gravity"], arrays), name=meta["model"])
    declared = meta.get("units")  # files written before units were stored have none
    if declared is not None:
        model.units = (units.UnitSystem(**declared) if isinstance(declared, dict)
                       else units.of(declared))
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


def system_meta(system: System, w: Writer) -> dict:
    """The ``"system"`` entry: every field of ``system`` but its model; the kinds' arrays as
    members ``system/arrays/<kind>/<field>`` (``system/arrays/gravity``), their time
    constants as ``system/time_base/<kind>``."""
    sys_meta = {"dtype": np.dtype(system.dtype).str}
    for f in dataclasses.fields(system):
        val = getattr(system, f.name)
        if f.name in _SYSTEM_SPECIAL or f.name in _NOT_SAVED:
            continue
        if isinstance(val, np.ndarray):
            w.array(f"system/{f.name}", val)
        else:
            sys_meta[f.name] = w.value(val, f"system/{f.name}", f"System.{f.name}")
    w.array("system/arrays/gravity", np.asarray(system.arrays.gravity))
    present = []
    for kind in KIND_NAMES:
        table = system.table(kind)
        if table is None:
            continue
        present.append(kind)
        for name, a in zip(table._fields, table):
            w.array(f"system/arrays/{kind}/{name}", np.asarray(a))
    sys_meta["kinds"] = present
    for kind, base in system.time_base.items():
        w.array(f"system/time_base/{kind}", np.asarray(base))
    sys_meta["time_profiles"] = {
        kind: [[int(i), w.profile(p, f"system/time_profiles/{kind}/{k}")]
               for k, (i, p) in enumerate(items)]
        for kind, items in system.time_profiles.items()}
    sys_meta["names"] = {kind: list(v) for kind, v in system.names.items()}
    bodies = []
    for i, (name, info) in enumerate(system.bodies.items()):
        entry = {}
        for f in dataclasses.fields(info):
            entry[f.name] = w.value(getattr(info, f.name), f"system/bodies/{i}/{f.name}",
                                    f"BodyInfo {name!r}.{f.name}")
        bodies.append(entry)
    sys_meta["bodies"] = bodies
    return sys_meta


def system_from(meta: dict, arrays: dict) -> System:
    """The System of a file, its model rebuilt with the bodies only (:func:`rebuild_model`)."""
    sm = meta["system"]
    if meta.get("format_version", 1) < 2:
        raise FormatError("the file holds a compiled system of format version 1 (an earlier "
                          "morphlab): run the analysis again to write it in this version")
    model = rebuild_model(meta, arrays)
    bodies = {}
    for entry in sm["bodies"]:
        d = decode(entry, arrays)
        known = {f.name for f in dataclasses.fields(BodyInfo)}
        info = BodyInfo(**{k: v for k, v in d.items() if k in known})
        bodies[info.name] = info
    dt = np.dtype(sm["dtype"])
    tables = {}
    for kind in KIND_NAMES:
        if kind not in sm["kinds"]:
            if not KINDS[kind].optional:
                raise FormatError(f"the file's system has no table of {kind!r}")
            tables[kind] = None
            continue
        fields = [f.name for f in KINDS[kind].fields if f.role != TIME]
        try:
            tables[kind] = KINDS[kind].arrays(*(arrays[f"system/arrays/{kind}/{f}"]
                                               for f in fields))
        except KeyError as exc:
            raise FormatError(f"the file's system lacks {exc.args[0]!r}") from None
    sys_arrays = SystemArrays(arrays["system/arrays/gravity"], **tables)
    design, sys_arrays = flatten(sys_arrays, dt)
    kwargs = {}
    for f in dataclasses.fields(System):
        key = f"system/{f.name}"
        if key in arrays:
            kwargs[f.name] = arrays[key]
        elif f.name in sm and f.name not in _SYSTEM_SPECIAL:
            kwargs[f.name] = decode(sm[f.name], arrays)
    kwargs.update(
        model=model, dtype=dt, bodies=bodies, arrays=sys_arrays, design=design,
        time_base={k: arrays[f"system/time_base/{k}"] for k in sm["time_profiles"]},
        time_profiles={k: [(int(i), decode_profile(p, arrays)) for i, p in v]
                       for k, v in sm["time_profiles"].items()},
        names={k: list(v) for k, v in sm["names"].items()})
    return System(**kwargs)
