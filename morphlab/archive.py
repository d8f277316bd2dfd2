"""The ``.npz`` container of :mod:`morphlab.io`: atomic writing and verified reading.

Writing goes to a temporary file next to the target, flushed and moved over it with
:func:`os.replace`, so there is never a partial file under the final name; an ``OSError``
(disk full, no permission) names the file.

Reading trusts nothing in the file: every member is read to its end, so the ZIP layer checks
its CRC-32 against the directory, and its ``.npy`` header must describe exactly the bytes that
follow (dtype without Python objects, a shape whose size matches the data). Whatever is wrong
-- not a ZIP archive, a damaged directory or header, a flipped bit in the data, a member
announced but absent, an unsupported compression or encryption flag -- ends as one
:class:`~morphlab.errors.FormatError` naming the file.
"""

from __future__ import annotations

import ast
import dataclasses
import os
import tempfile
import zipfile

import numpy as np

from .errors import FormatError, MorphlabError
from .model import profiles as _profiles
from .model.profiles import Profile

NPY_MAGIC = b"\x93NUMPY"


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


def _named(exc: OSError, path: str, doing: str) -> OSError:
    """The same kind of ``OSError`` (``errno`` kept: PermissionError, ...) naming ``path``."""
    err = OSError(exc.errno, f"{doing} {path!r} failed: {exc.strerror or exc}", path)
    return err


def write_members(path, members) -> None:
    """Write ``members`` (an iterable of ``(name, array)``, converted one at a time) as an
    uncompressed ``.npz`` archive at ``path``, atomically; object arrays are refused."""
    path = os.fspath(path)
    if not path:
        raise FormatError("the file name is empty")
    folder = os.path.dirname(os.path.abspath(path))
    try:
        fd, tmp = tempfile.mkstemp(prefix=f".{os.path.basename(path)}.", suffix=".tmp",
                                   dir=folder)
    except OSError as exc:
        raise _named(exc, path, "writing") from exc
    try:
        with os.fdopen(fd, "wb") as fh:
            with zipfile.ZipFile(fh, mode="w", compression=zipfile.ZIP_STORED,
                                 allowZip64=True) as zf:
                for key, value in members:
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
    except BaseException as exc:
        try:
            os.unlink(tmp)
        except FileNotFoundError:
            pass
        if isinstance(exc, OSError):
            raise _named(exc, path, "writing") from exc
        raise


def _parse_npy(data: bytes, where: str) -> np.ndarray:
    """The array of one ``.npy`` member (its bytes, CRC already verified), refusing any header
    that does not describe exactly the bytes that follow."""
    if not data.startswith(NPY_MAGIC) or len(data) < 10:
        raise FormatError(f"{where}: not a .npy member")
    major = data[6]
    if major == 1:
        hlen, start = int.from_bytes(data[8:10], "little"), 10
    elif major in (2, 3):
        hlen, start = int.from_bytes(data[8:12], "little"), 12
    else:
        raise FormatError(f"{where}: unknown .npy version {major}")
    text = data[start:start + hlen].decode("utf-8" if major == 3 else "latin1")
    try:
        head = ast.literal_eval(text)
        descr, fortran, shape = head["descr"], head["fortran_order"], tuple(head["shape"])
        dtype = np.dtype(np.lib.format.descr_to_dtype(descr))
    except Exception as exc:  # whatever a damaged header text raises
        raise FormatError(f"{where}: damaged .npy header: {exc}") from exc
    if (dtype.hasobject or not isinstance(fortran, bool)
            or not all(isinstance(n, int) and n >= 0 for n in shape)):
        raise FormatError(f"{where}: invalid .npy header {text.strip()!r}")
    body = memoryview(data)[start + hlen:]
    count = int(np.prod(shape, dtype=object))
    if count * dtype.itemsize != len(body):
        raise FormatError(f"{where}: the header announces shape {shape} of {dtype} "
                          f"({count * dtype.itemsize} bytes) but the member holds {len(body)}")
    arr = np.frombuffer(body, dtype=dtype, count=count)  # writable: ``data`` is a bytearray
    if dtype.alignment > 1 and arr.ctypes.data % dtype.alignment:
        arr = arr.copy()  # compiled kernels want aligned arrays
    return arr.reshape(shape, order="F" if fortran else "C")


def read_members(path, names=None) -> dict:
    """``{name: array}`` of the members of the archive at ``path`` (all, or those in
    ``names``; each ``name`` without its ``.npy``), every one verified (module docstring).

    Raises
    ------
    FileNotFoundError, OSError
        The file cannot be opened (the message names it).
    FormatError
        Anything wrong inside the file.
    """
    name = os.fspath(path)
    if not os.path.isfile(name):
        raise FileNotFoundError(f"no such file: {name!r}")
    try:
        fh = open(name, "rb")
        size = os.fstat(fh.fileno()).st_size
        head = fh.read(len(NPY_MAGIC))
        fh.seek(0)
    except OSError as exc:
        raise _named(exc, name, "reading") from exc
    if head == NPY_MAGIC:
        fh.close()
        raise FormatError(f"{name!r} is not a morphlab file (a single .npy array)")
    try:
        with fh, zipfile.ZipFile(fh) as zf:
            return _verified(zf, name, size, names)
    except MorphlabError as exc:
        if repr(name) in str(exc):
            raise
        raise FormatError(f"{name!r}: {exc}") from exc
    except Exception as exc:  # the zip layer of a damaged file raises many kinds of errors
        raise FormatError(f"{name!r} is not a morphlab file or is damaged: "
                          f"{type(exc).__name__}: {exc}") from exc


def _verified(zf: zipfile.ZipFile, name: str, size: int, names) -> dict:
    infos = {i.filename[:-4]: i for i in zf.infolist() if i.filename.endswith(".npy")}
    if len(infos) != len(zf.infolist()):
        raise FormatError(f"{name!r} is not a morphlab file (members other than .npy)")
    out = {}
    for key in (list(infos) if names is None else list(names)):
        if key not in infos:
            raise FormatError(f"{name!r} is incomplete: no member {key!r}")
        info = infos[key]
        if info.compress_type != zipfile.ZIP_STORED or info.flag_bits & 0x1:
            raise FormatError(f"{name!r}: member {key!r} is compressed or encrypted "
                              "(morphlab files are stored plain)")
        if info.file_size != info.compress_size or info.file_size > size:
            raise FormatError(f"{name!r}: member {key!r} has a damaged size in the directory")
        data = bytearray(info.file_size)
        with zf.open(info) as member:
            n = member.readinto(data)
            rest = member.read()  # at the end: zipfile compares the CRC-32 there
        if n != info.file_size or rest:
            raise FormatError(f"{name!r}: member {key!r} is truncated or too long")
        out[key] = _parse_npy(data, f"{name!r}, member {key!r}")
    return out


# ---------------------------------------------------------------------------------------------
# encoding of values: JSON where exact, array members otherwise
# profiles of morphlab.model.profiles built from numbers and other such profiles
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
