"""Encoding of values in the metadata of a morphlab file: JSON where it is exact, array members
otherwise; time profiles of :mod:`morphlab.model.profiles` as data."""

from __future__ import annotations

import dataclasses

import numpy as np

from ..errors import FormatError
from ..model import profiles as _profiles
from ..model.profiles import Profile

#: Profiles of morphlab.model.profiles built from numbers and other such profiles.
STORABLE_PROFILES = ("Constant", "Ramp", "SmoothStep", "Sine", "Linear", "Polynomial", "Sum",
                     "Scaled", "Product", "Integral")


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


class Writer:
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
        """``{"$profile": class, "fields": ...}`` of a library profile of numbers and library
        profiles; ``{"$profile": None, "repr": ...}`` for anything else (a user's callable)."""
        name = type(p).__name__
        if (name in STORABLE_PROFILES and type(p) is getattr(_profiles, name)
                and dataclasses.is_dataclass(p)):
            fields = {}
            for f in dataclasses.fields(p):
                val = getattr(p, f.name)
                if isinstance(val, Profile):
                    fields[f.name] = self.profile(val, f"{key}/{f.name}")
                    if fields[f.name]["$profile"] is None:
                        break
                elif isinstance(val, tuple) and all(_is_number(x) for x in val):
                    fields[f.name] = [self.value(x, f"{key}/{f.name}/{i}", "profile")
                                      for i, x in enumerate(val)]
                elif _is_number(val):
                    fields[f.name] = self.value(val, f"{key}/{f.name}", "profile")
                else:
                    break
            else:
                return {"$profile": name, "fields": fields}
        return {"$profile": None, "repr": repr(p)[:200]}


def _is_number(x) -> bool:
    return isinstance(x, (int, float, complex, np.number)) and not isinstance(x, (bool, np.bool_))


def decode(j, arrays):
    """Inverse of :meth:`Writer.value`."""
    if isinstance(j, dict):
        if "$array" in j:
            key = j["$array"]
            if key not in arrays:
                raise FormatError(f"member {key!r} named in the metadata is missing")
            a = arrays[key]
            return a[()] if j.get("scalar") else a
        if "$slice" in j:
            return slice(*j["$slice"])
        return {k: decode(v, arrays) for k, v in j.items()}
    if isinstance(j, list):
        return [decode(x, arrays) for x in j]
    return j


def decode_profile(j, arrays) -> Profile:
    """Inverse of :meth:`Writer.profile`."""
    name = j.get("$profile")
    if name is None:
        return UnsavedProfile(j.get("repr", "?"))
    if name not in STORABLE_PROFILES:
        raise FormatError(f"unknown time profile {name!r} in the file")
    fields = {k: decode_profile(v, arrays) if isinstance(v, dict) and "$profile" in v
              else decode(v, arrays) for k, v in j["fields"].items()}
    return getattr(_profiles, name)(**{k: tuple(v) if isinstance(v, list) else v
                                       for k, v in fields.items()})
