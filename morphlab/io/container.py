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
import os
import tempfile
import zipfile

import numpy as np

from ..errors import FormatError, MorphlabError

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
