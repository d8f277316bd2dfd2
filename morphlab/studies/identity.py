"""What a sweep's task is, as plain JSON data: the identity a checkpoint is matched on.

A checkpoint may only give its rows to the task that wrote them. :func:`task_identity`
describes a task by what decides its rows: for a :class:`~.tasks.SimulationTask` its build
function, its responses, the run's settings and other options, the gradients asked for and
the sensitivity method; for any other callable its qualified name and code. A function is
described by its qualified name and a fingerprint (SHA-256) of its compiled code (bytecode,
constants, names), its default arguments and the values its closure holds, so that an edited
function or another closure parameter reads as another task while comments, docstrings and
line numbers do not count. The fingerprint covers the function itself, not the functions it
calls by name, and it is computed by the running Python (bytecode differs between Python
versions, which therefore read as other code).

Values are described when they are immutable (numbers, strings, tuples, frozensets, frozen
dataclasses such as :class:`~morphlab.Settings`), NumPy arrays (by content), paths, classes,
modules and callables; a list, dict or set held by a closure or an object is usually a
counter or a cache, so only its type counts; any other object counts by its class and, a few
levels deep, its attributes. :func:`differences` names what differs between two identities.
"""

from __future__ import annotations

import dataclasses
import functools
import hashlib
import json
import os
import types

import numpy as np

DEPTH = 4  # levels of attributes, closures and containers described
MAX_ITEMS = 200  # items of a tuple or frozenset described one by one (the rest by a hash)


def _digest(data) -> str:
    text = json.dumps(data, sort_keys=True, allow_nan=True, default=str)
    return hashlib.sha256(text.encode()).hexdigest()


def _qualname(obj) -> str:
    module = getattr(obj, "__module__", None) or "?"
    return f"{module}.{getattr(obj, '__qualname__', getattr(obj, '__name__', '?'))}"


def _code(co: types.CodeType, depth: int, skip_doc: bool = False) -> list:
    consts = list(co.co_consts[1:] if skip_doc else co.co_consts)
    return [co.co_code.hex(), co.co_names, co.co_varnames, co.co_freevars, co.co_argcount,
            co.co_kwonlyargcount, [_code(c, depth) if isinstance(c, types.CodeType)
                                   else state(c, depth) for c in consts]]


def _function(fn: types.FunctionType, depth: int) -> dict:
    co = fn.__code__
    # the first constant of a function's code is its docstring (None without one)
    doc = bool(co.co_consts) and (co.co_consts[0] is None or co.co_consts[0] == fn.__doc__)
    cells = []
    for cell in fn.__closure__ or ():
        try:
            cells.append(state(cell.cell_contents, depth + 1))
        except ValueError:  # an empty cell (a name assigned after the function was made)
            cells.append(None)
    code = [_code(co, depth, skip_doc=doc), state(fn.__defaults__, depth + 1),
            state(fn.__kwdefaults__, depth + 1), cells]
    return {"name": _qualname(fn), "code": _digest(code)}


def callable_identity(fn, depth: int = 0) -> dict:
    """``{"name": qualified name, "code": fingerprint or None}`` of a callable: a function
    (its code, defaults, closure), a bound method (its function and its object), a
    ``functools.partial`` (its function and arguments) or an object with ``__call__`` (its
    class's ``__call__`` and the object's attributes); builtins by name only."""
    if depth > DEPTH:
        return {"name": _qualname(fn), "code": None}
    if isinstance(fn, types.FunctionType):
        return _function(fn, depth)
    if isinstance(fn, types.MethodType):
        inner = callable_identity(fn.__func__, depth + 1)
        return {"name": inner["name"], "code": _digest([inner, state(fn.__self__, depth + 1)])}
    if isinstance(fn, functools.partial):
        inner = callable_identity(fn.func, depth + 1)
        return {"name": f"partial({inner['name']})", "code": _digest(
            [inner, state(fn.args, depth + 1), state(fn.keywords, depth + 1)])}
    if isinstance(fn, types.BuiltinFunctionType | type):
        return {"name": _qualname(fn), "code": None}
    call = next((vars(k)["__call__"] for k in type(fn).__mro__ if "__call__" in vars(k)),
                None)
    if isinstance(call, types.FunctionType):
        return {"name": _qualname(type(fn)), "code": _digest(
            [_function(call, depth + 1), _attribute_state(fn, depth + 1)])}
    return {"name": _qualname(type(fn)), "code": None}


def _attribute_state(obj, depth: int) -> dict | None:
    """``{attribute: state}`` of an object (a dataclass: its fields), None without any."""
    if dataclasses.is_dataclass(obj):
        attrs = {f.name: getattr(obj, f.name, None) for f in dataclasses.fields(obj)}
    elif hasattr(obj, "__dict__"):
        attrs = dict(vars(obj))
    else:
        return None
    return {str(k): state(v, depth) for k, v in attrs.items()}


def state(value, depth: int = 0):
    """JSON data that stands for ``value`` in a fingerprint (module docstring); the same for
    equal values in any process."""
    try:
        return _state(value, depth)
    except Exception:  # a value that resists description counts by its type only
        return {"type": _qualname(type(value))}


def _state(value, depth: int):
    if value is None or isinstance(value, bool | int | str):
        return value
    if isinstance(value, float):  # JSON writes finite floats exactly; NaN never equals itself
        return value if np.isfinite(value) else {"type": "float", "repr": repr(value)}
    if isinstance(value, complex | bytes | np.generic):
        return {"type": _qualname(type(value)), "repr": repr(value)}
    if isinstance(value, np.ndarray):
        if value.dtype.hasobject:
            return {"type": "ndarray", "dtype": "object", "shape": list(value.shape)}
        data = np.ascontiguousarray(value)
        return {"type": "ndarray", "dtype": str(value.dtype), "shape": list(value.shape),
                "sha256": hashlib.sha256(data.tobytes()).hexdigest()}
    if isinstance(value, os.PathLike):
        return {"type": "path", "path": os.fspath(value)}
    if depth > DEPTH:
        return {"type": _qualname(type(value))}
    if isinstance(value, tuple | frozenset):
        items = [state(v, depth + 1) for v in list(value)[:MAX_ITEMS]]
        if isinstance(value, frozenset):
            items.sort(key=lambda s: json.dumps(s, sort_keys=True, default=str))
        if len(value) > MAX_ITEMS:
            items.append({"more": len(value) - MAX_ITEMS})
        return {"type": type(value).__name__, "items": items}
    if isinstance(value, list | dict | set | bytearray):
        return {"type": type(value).__name__}  # a counter or cache as a rule: its type only
    if isinstance(value, types.ModuleType):
        return {"module": value.__name__}
    if callable(value):
        return {"callable": callable_identity(value, depth + 1)}
    attrs = _attribute_state(value, depth + 1)
    if attrs is None:
        return {"type": _qualname(type(value))}
    return {"type": _qualname(type(value)), "attributes": attrs}


def task_identity(task) -> dict:
    """The identity of any task: ``task.identity()`` where the task defines it (a
    :class:`~.tasks.SimulationTask`), else its kind and :func:`callable_identity`."""
    own = getattr(task, "identity", None)
    if callable(own) and not isinstance(task, types.FunctionType):
        return own()
    kind = "function" if isinstance(task, types.FunctionType) else "callable"
    return {"kind": kind, "task": callable_identity(task)}


def as_json(data):
    """``data`` as it reads back from JSON (tuples become lists), for comparisons."""
    return json.loads(json.dumps(data, allow_nan=True))


def differences(old, new, path: str = "") -> list[str]:
    """What differs between two identities (JSON data), one line per item:
    ``"settings.t_end: 0.01 in the checkpoint, 0.02 for this sweep"``."""
    if isinstance(old, dict) and isinstance(new, dict):
        if old.get("kind", new.get("kind")) != new.get("kind", old.get("kind")):
            return differences(old["kind"], new["kind"], f"{path}.kind")  # all else differs
        out = []
        for key in list(old) + [k for k in new if k not in old]:
            sub = f"{path}.{key}" if path else str(key)
            if key not in old or key not in new:
                where = "only for this sweep" if key not in old else "only in the checkpoint"
                out.append(f"{sub}: {where}")
            else:
                out += differences(old[key], new[key], sub)
        return out
    if old == new:
        return []
    if path.endswith(".code") and isinstance(old, str) and isinstance(new, str):
        return [f"{path[:-5]}: its code, defaults or closure values differ (fingerprint "
                f"{old[:12]} in the checkpoint, {new[:12]} for this sweep)"]
    return [f"{path}: {_short(old)} in the checkpoint, {_short(new)} for this sweep"]


def _short(value) -> str:
    text = json.dumps(value, allow_nan=True, default=str)
    return text if len(text) <= 80 else text[:77] + "..."
