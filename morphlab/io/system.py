"""The compiled System and the model's bodies in a result file: the ``"system"``,
``"bodies"`` and ``"gravity"`` entries of the metadata and their members (format in
:mod:`morphlab.io`)."""

from __future__ import annotations

import dataclasses

import numpy as np

from ..compile.system import BodyInfo, System
from ..errors import FormatError
from ..model import Beam, Model, RigidBody
from .encoding import Writer, decode, decode_profile

# System fields with their own representation (everything else: arrays or plain JSON values)
_SYSTEM_SPECIAL = ("model", "dtype", "bodies", "con_drive", "load_prof", "torque_prof")


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


def rebuild_model(meta: dict, arrays: dict) -> Model:
    """The model of a file: its bodies and gravity, no joints or loads."""
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


def system_meta(system: System, w: Writer) -> dict:
    """The ``"system"`` entry: every field of ``system`` but its model."""
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
    return sys_meta


def system_from(meta: dict, arrays: dict) -> System:
    """The System of a file, its model rebuilt with the bodies only (:func:`rebuild_model`);
    a field newer than the file is None."""
    sm = meta["system"]
    model = rebuild_model(meta, arrays)
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
    return System(**kwargs)
