"""Perturbed designs, compiled in one place for every sensitivity method (and the bench).

A design variable ``p_i`` is differentiated through the user's ``build(p)``: its perturbed
design ``p + delta e_i`` (``delta = i h`` with ``h = 1e-30`` for a complex step, a real step for
finite differences) is built and compiled like the nominal one. This module checks that the
perturbation keeps the model's structure and changes something, and forms what the direct
method's pseudo-loads read: the design data of every perturbed design stacked, the parts of the
model each variable changes, the time tables and the initial sensitivities.
"""

from __future__ import annotations

import sys
import threading
import time
from collections.abc import Callable
from contextlib import contextmanager
from typing import NamedTuple

import numpy as np

from ..compile import System, compile_model, kernel_arrays, time_table
from ..compile.incremental import fresh_rows
from ..compile.system import SystemArrays, TimeTable
from ..errors import MorphlabError, SensitivityError
from ..kernels.system import DESIGN_FIELDS, DesignRows
from ..model import Model

#: The complex step (Martins, Sturdza & Alonso 2003): exact to round-off for ``h`` this small.
CS_STEP = 1e-30
#: Every array of a System a design variable can change: the kernels' design data, the initial
#: state, the stress maps and the time-dependent data's constants.
DESIGN_DEPENDENT = DESIGN_FIELDS + ("q0", "v0", "elem_B", "con_c0", "load_F0", "torque_T0")


def relative_steps(p0: dict, names: list[str], step: float) -> dict[str, float]:
    """Finite-difference steps ``step |p_i|`` (``step`` where ``p_i = 0``): relative, so that a
    density of 2.7e-9 t/mm³ does not get an absolute step."""
    return {v: step * (abs(p0[v]) if p0[v] != 0.0 else 1.0) for v in names}


# what a design variable must not change, item by item: (array, the items it describes, the
# System list naming them)
_TOPOLOGY = (("load_dofs", "force", "load_names"), ("torque_dofs", "torque", "torque_names"),
             ("con_dofs", "constraint row", "con_names"), ("con_kind", "constraint row",
                                                           "con_names"),
             ("elem_dofs", "element", None), ("body_ref", "body", None),
             ("spring_dofs", "spring", "spring_names"), ("spring_kind", "spring", "spring_names"),
             ("line_off", "line-load range", None), ("line_elem", "line-load element", None))


def check_same_layout(a: System, b: System, name: str) -> None:
    """Raise :class:`SensitivityError` if ``b`` (a perturbed design) has another structure
    than ``a``: other DOFs, constraints or sparsity, or any load, torque, joint row, element
    or body acting on other DOFs (a node another, a body another) — the derivative of a
    change of topology does not exist."""
    same = (a.n_dof == b.n_dof and a.n_con == b.n_con and a.nnz == b.nnz
            and np.array_equal(a.indices, b.indices) and np.array_equal(a.indptr, b.indptr))
    if not same:
        raise SensitivityError(
            f"changing design variable {name!r} changes the model's structure (DOFs, "
            "constraints or sparsity pattern); build(p) must keep the topology fixed")
    for field, kind, names in _TOPOLOGY:
        x, y = getattr(a, field), getattr(b, field)
        if x.shape != y.shape or not np.array_equal(x, y):
            rows = np.flatnonzero(np.any((x != y).reshape(x.shape[0], -1), axis=1)) \
                if x.shape == y.shape else [0]
            i = int(rows[0])
            item = f"{kind} {getattr(a, names)[i]!r}" if names else f"{kind} {i}"
            raise SensitivityError(
                f"changing design variable {name!r} moves {item} to other coordinates (another "
                "node or body): build(p) must keep every load, joint and element where it is")


def uses_variable(sys_p: System, sys0: System, t_end: float) -> bool:
    """Does the perturbed system differ from the nominal one anywhere: its arrays, or its time
    profiles (compared as objects where they compare equal, else by their values at three
    times)?"""
    if any(not np.array_equal(getattr(sys_p, k), getattr(sys0, k)) for k in DESIGN_DEPENDENT):
        return True
    profiles = [(a, b) for a, b in zip(sys_p.load_prof + sys_p.torque_prof,
                                       sys0.load_prof + sys0.torque_prof)]
    profiles += [(a[1], b[1]) for a, b in zip(sys_p.con_drive, sys0.con_drive)]
    if all(_equal(a, b) for a, b in profiles):
        return False
    return any(not np.array_equal(x, y)
               for t in (0.0, 0.37 * t_end, t_end)
               for x, y in zip(sys_p.time_arrays(t), sys0.time_arrays(t)))


def _equal(a, b) -> bool:
    try:
        return bool(a == b)
    except Exception:  # a user profile whose comparison fails: compare values instead
        return False


def compile_perturbed(build: Callable, p0: dict, name: str, delta, sys0: System) -> System:
    """``build(p0 + delta e_name)`` compiled like ``sys0`` (complex128 for a complex
    ``delta``), its structure checked."""
    p = dict(p0)
    p[name] = p0[name] + delta
    dtype = np.complex128 if isinstance(delta, complex) else np.float64
    what = f"with {name!r} perturbed by {delta!r}"
    sys_p = compile_model(call_build(build, p, what), dtype=dtype, like=sys0)
    check_same_layout(sys0, sys_p, name)
    return sys_p


def call_build(build: Callable, p: dict, what: str):
    """``build(p)``; a user's exception becomes a :class:`SensitivityError` saying for which
    design (its cause the exception), and a non-Model result is refused."""
    try:
        model = build(dict(p))
    except MorphlabError:
        raise
    except Exception as exc:
        raise SensitivityError(f"build(p) raised {type(exc).__name__}: {exc} ({what}; a "
                               "complex-step perturbation needs build to accept complex "
                               "values)") from exc
    if not isinstance(model, Model):
        raise SensitivityError(f"build(p) must return a morphlab Model, got "
                               f"{type(model).__name__} ({what})")
    return model


def complex_systems(build: Callable, p0: dict, names: list[str], sys0: System,
                    t_end: float, stop: threading.Event | None = None) -> list[System]:
    """The complex-step designs of every variable; a variable ``build`` does not use raises.
    ``stop``: checked before each design (set, the compile ends early with what it has)."""
    out = []
    for v in names:
        if stop is not None and stop.is_set():
            break
        sys_p = compile_perturbed(build, p0, v, 1j * CS_STEP, sys0)
        if not uses_variable(sys_p, sys0, t_end):
            raise SensitivityError(
                f"design variable {v!r} is not used by build: no compiled array, initial "
                "state or load changes with it, so its gradient would be silently zero")
        out.append(sys_p)
    return out


#: Python's thread switch interval [s] while the designs compile on a thread (see
#: :meth:`ComplexDesigns._background`).
SWITCH_INTERVAL = 1e-4


_SWITCH = {"lock": threading.Lock(), "users": 0, "saved": None}


@contextmanager
def _short_switch_interval():
    """Python's thread switch interval at most :data:`SWITCH_INTERVAL` while any background
    compile runs (counted, so that concurrent sensitivity runs of one process restore the
    interval once, when the last ends). The primal's thread returns from each Newton loop (a
    millisecond) wanting the GIL back; at the default interval (5 ms) it would wait about that
    long every step."""
    with _SWITCH["lock"]:
        if _SWITCH["users"] == 0:
            _SWITCH["saved"] = sys.getswitchinterval()
            sys.setswitchinterval(min(_SWITCH["saved"], SWITCH_INTERVAL))
        _SWITCH["users"] += 1
    try:
        yield
    finally:
        with _SWITCH["lock"]:
            _SWITCH["users"] -= 1
            if _SWITCH["users"] == 0:
                sys.setswitchinterval(_SWITCH["saved"])


class ComplexDesigns:
    """The complex-step designs of every variable (:func:`complex_systems`), compiled now or,
    with ``background=True``, on a thread while the caller runs the primal: the compile is
    Python and the primal's Newton loop runs without the GIL (``kernels.newton``), so on two
    cores the two overlap. :meth:`result` waits for them and raises what the compile raised;
    :meth:`check` raises it as soon as it is known (the adjoint's step observer calls it, so a
    bad variable stops the primal early); :meth:`stop` ends a compile nobody will wait for.
    ``seconds``: the compile's own wall time."""

    def __init__(self, build: Callable, p0: dict, names: list[str], sys0: System,
                 t_end: float, *, background: bool = False):
        self._args = (build, p0, names, sys0, t_end)
        self._systems: list[System] | None = None
        self._error: BaseException | None = None
        self._stop = threading.Event()
        self.seconds = 0.0
        self.background = background
        self._thread = None
        if background:
            self._thread = threading.Thread(target=self._background, daemon=True,
                                            name="morphlab-designs")
            self._thread.start()
        else:
            self._compile()
            self.check()

    def _compile(self) -> None:
        t0 = time.perf_counter()
        try:
            self._systems = complex_systems(*self._args, stop=self._stop)
        except BaseException as exc:  # handed to the caller's thread by check()/result()
            self._error = exc
        self.seconds = time.perf_counter() - t0

    def _background(self) -> None:
        with _short_switch_interval():
            self._compile()

    @property
    def n_variables(self) -> int:
        return len(self._args[2])

    def done(self) -> bool:
        """Whether the compile has ended (without waiting)."""
        return self._thread is None or not self._thread.is_alive()

    def check(self) -> None:
        """Raise the compile's error if it has failed (without waiting)."""
        if self._error is not None:
            raise self._error

    def result(self) -> list[System]:
        """The complex-step systems, in the order of the variables (waits for the thread)."""
        if self._thread is not None:
            self._thread.join()
        self.check()
        return self._systems

    def stop(self) -> None:
        """Ask a background compile to end after the design it is compiling."""
        self._stop.set()


def shifted_systems(build: Callable, p0: dict, names: list[str], sys0: System,
                    steps: dict[str, float], sign: float = 1.0) -> list[System]:
    """The designs ``p0 + sign steps[v] e_v`` of every variable (finite differences)."""
    return [compile_perturbed(build, p0, v, sign * steps[v], sys0) for v in names]


# ------------------------------------------------------------------ what the pseudo-loads read
class PseudoLoadData(NamedTuple):
    """What the direct method's pseudo-load kernels (:mod:`morphlab.kernels.direct`) read.

    ``S_nom``: the nominal kernel arrays in the perturbation's dtype; ``W``: the same with its
    own copy of the design data, into which the kernels write one design at a time; ``D``: the
    rows of the design data each of the n_x perturbed designs changes
    (:class:`~morphlab.kernels.system.DesignRows`); ``parts``: the parts of the model each
    variable changes (CSR
    over the variables, :func:`pack_parts`); ``TAB``: the distinct time tables of the designs
    (leading axes (n_t, n_tab)), table 0 the nominal one, and ``tab_of`` (n_x,) int64 the table
    of each variable (0 for most: a thickness or a link point changes no profile or constant);
    ``pert`` (n_x,): ``i h`` or the steps; ``dq0``, ``dv0`` (n_dof, n_x): the initial
    sensitivities; ``touched``: the residual rows each variable's parts can change (CSR over
    the variables, :func:`touched_rows`); ``lin``: the variables that change element
    stiffnesses and nothing else, with the derivatives of those stiffnesses
    (:func:`stiffness_split`).
    """

    S_nom: SystemArrays
    W: SystemArrays
    D: DesignRows
    parts: tuple
    TAB: TimeTable
    tab_of: np.ndarray
    pert: np.ndarray
    dtype: np.dtype
    dq0: np.ndarray
    dv0: np.ndarray
    touched: tuple
    lin: tuple


def pseudo_load_data(sys0: System, psys: list[System], pert: np.ndarray,
                     times: np.ndarray) -> PseudoLoadData:
    """Built once per run from the perturbed systems ``psys`` (their perturbations ``pert``)."""
    complex_step = np.iscomplexobj(pert)
    dt = np.dtype(np.complex128 if complex_step else np.float64)
    S_nom = kernel_arrays(sys0, dt)  # integer tables shared with the primal's
    S_all = [kernel_arrays(s, dt) for s in psys]
    masks = [changed_rows(S_nom, Sk, fresh_rows(s)) for Sk, s in zip(S_all, psys)]
    D = design_rows(S_nom, S_all, masks)
    W = S_nom._replace(**{k: getattr(S_nom, k).copy() for k in DESIGN_FIELDS})
    del S_all
    tab_of, tables = distinct_tables(sys0, psys, times, dt)
    each = [variable_parts(sys0, S_nom, None, tables[0], tables[t] if t else None, masks=m)
            for m, t in zip(masks, tab_of)]
    parts = pack_parts(each)
    rows = [touched_rows(sys0, p) for p in each]
    off = np.zeros(len(rows) + 1, dtype=np.int64)
    off[1:] = np.cumsum([len(r) for r in rows])
    touched = (off, np.concatenate(rows).astype(np.int64) if rows else np.zeros(0, np.int64))
    TAB = TimeTable(*(np.ascontiguousarray(np.stack([tb[k] for tb in tables], axis=1))
                      for k in range(5)))
    if complex_step:
        dq0 = np.stack([np.imag(s.q0) / CS_STEP for s in psys], axis=1)
        dv0 = np.stack([np.imag(s.v0) / CS_STEP for s in psys], axis=1)
    else:
        dq0 = np.stack([(s.q0 - sys0.q0) / e for s, e in zip(psys, pert)], axis=1)
        dv0 = np.stack([(s.v0 - sys0.v0) / e for s, e in zip(psys, pert)], axis=1)
    lin = stiffness_split(S_nom, D, masks, tab_of, pert)
    return PseudoLoadData(S_nom, W, D, parts, TAB, tab_of, pert, dt, dq0, dv0, touched, lin)


#: Form the partial derivatives of variables that change only element stiffnesses and
#: stiffness-proportional damping (a Young's modulus, a damping coefficient) as real products
#: (:func:`stiffness_split`); False takes them through the complex residual like every other
#: variable (the tests compare both).
STIFFNESS_SPLIT = True


def stiffness_split(S_nom: SystemArrays, D: DesignRows, masks: list, tab_of: np.ndarray,
                    pert: np.ndarray) -> tuple:
    """The variables whose designs change the element stiffness matrices ``K_e`` and the
    bodies' stiffness-proportional damping ``beta`` and nothing else the residual reads, as
    ``(off, elems, dK, dC)``: CSR over the variables (``off`` (n_x + 1,) int64, empty ranges
    for the others), their elements (int64: those whose ``K_e`` changes and every element of
    a body whose ``beta`` changes) and ``dK``, ``dC`` (nnz, 6, 6) float64, the derivatives of
    ``K_e`` and ``beta K_e``, ``(X_i - X_0) / pert_i`` (``Im X_i / h`` for a complex step).
    The residual is linear in both, so their pseudo-load is ``w_f (dK_e q_e + dC_e q_e')`` per
    element, a few real products in place of a residual of complex data over the elements'
    bodies (:func:`~morphlab.kernels.direct.explicit_loads`); with a forward difference the
    products are the number the difference of two residuals would give."""
    n_x = len(masks)
    off = np.zeros(n_x + 1, dtype=np.int64)
    elems, dks, dcs = [], [], []
    K0, beta0, body_of = S_nom.elem_K, S_nom.body_damp, S_nom.elem_body
    k_off, k_rows, k_vals = D.elem_K
    b_off, b_rows, b_vals = D.body_damp
    allowed = ("elem_K", "body_damp")
    for i, m in enumerate(masks):
        if not (STIFFNESS_SPLIT and tab_of[i] == 0 and any(m[f].any() for f in allowed)
                and not any(m[f].any() for f in DESIGN_FIELDS if f not in allowed)):
            off[i + 1] = off[i]
            continue
        K = K0.copy()
        K[k_rows[k_off[i]:k_off[i + 1]]] = k_vals[k_off[i]:k_off[i + 1]]
        beta = beta0.copy()
        beta[b_rows[b_off[i]:b_off[i + 1]]] = b_vals[b_off[i]:b_off[i + 1]]
        e = np.flatnonzero(m["elem_K"] | m["body_damp"][body_of])
        dK = (K[e] - K0[e]) / pert[i]
        dC = (beta[body_of[e], None, None] * K[e] - beta0[body_of[e], None, None] * K0[e]) / pert[i]
        elems.append(e)
        dks.append(dK.real)
        dcs.append(dC.real)
        off[i + 1] = off[i] + e.size
    if not elems:
        return off, np.zeros(0, np.int64), np.zeros((0, 6, 6)), np.zeros((0, 6, 6))
    return (off, np.concatenate(elems).astype(np.int64),
            np.ascontiguousarray(np.concatenate(dks), dtype=np.float64),
            np.ascontiguousarray(np.concatenate(dcs), dtype=np.float64))


def _same_time_data(a: System, b: System) -> bool:
    """Do ``a`` and ``b`` have the same time-dependent data: equal constants (drive offsets,
    force and torque magnitudes) and equal profiles on the same rows?"""
    if not (np.array_equal(a.con_c0, b.con_c0) and np.array_equal(a.load_F0, b.load_F0)
            and np.array_equal(a.torque_T0, b.torque_T0)):
        return False
    if len(a.con_drive) != len(b.con_drive) or any(
            x[0] != y[0] for x, y in zip(a.con_drive, b.con_drive)):
        return False
    profiles = list(zip(a.load_prof + a.torque_prof, b.load_prof + b.torque_prof))
    profiles += [(x[1], y[1]) for x, y in zip(a.con_drive, b.con_drive)]
    return all(x is y or _equal(x, y) for x, y in profiles)


def distinct_tables(sys0: System, psys: list[System], times: np.ndarray, dt
                    ) -> tuple[np.ndarray, list[TimeTable]]:
    """The time tables of the designs without repeats: ``(tab_of (n_x,) int64, tables)``,
    ``tables[0]`` the nominal one and ``tables[tab_of[i]]`` design ``i``'s. A design with the
    nominal's constants and profiles shares table 0 without evaluating its own; one whose
    table comes out equal to the nominal's (a profile equal in value only) shares it too."""
    shared: dict = {}
    tables = [time_table(sys0, times, dt, cache=shared)]
    tab_of = np.zeros(len(psys), dtype=np.int64)
    for i, s in enumerate(psys):
        if _same_time_data(s, sys0):
            continue
        tb = time_table(s, times, dt, cache=shared)
        if not all(np.array_equal(x, y) for x, y in zip(tb, tables[0])):
            tab_of[i] = len(tables)
            tables.append(tb)
    return tab_of, tables


def _changed(a, b, axis_keep: int = 0) -> np.ndarray:
    """Per entry along axis ``axis_keep``: does any value of ``a`` differ from ``b``?"""
    d = np.asarray(a) != np.asarray(b)
    if d.ndim == 0:
        return d
    if axis_keep:
        d = np.moveaxis(d, axis_keep, 0)
    return d.reshape(d.shape[0], -1).any(axis=1) if d.size else np.zeros(d.shape[0], bool)


def changed_rows(S0: SystemArrays, Si: SystemArrays, fresh: dict | None = None) -> dict:
    """Per design field: the rows (a mask along the first axis) where a perturbed design's
    ``Si`` differs from the nominal ``S0``. ``fresh``: the rows of each array the design's
    compile formed afresh (``incremental.fresh_rows``; the others are the nominal's), compared
    alone; None: every row is compared."""
    out = {}
    for name in DESIGN_FIELDS:
        a, b = getattr(Si, name), getattr(S0, name)
        rows = fresh.get(name) if fresh is not None else None
        if rows is None:
            out[name] = _changed(a, b)
        else:
            out[name] = np.zeros(len(b), dtype=bool)
            if len(rows):
                out[name][rows] = _changed(a[rows], b[rows])
    return out


def design_rows(S0: SystemArrays, S_all: list, masks: list) -> DesignRows:
    """The rows of the design data the designs ``S_all`` change (``masks`` of
    :func:`changed_rows`), with their values (:class:`~morphlab.kernels.system.DesignRows`)."""
    fields = []
    for name in DESIGN_FIELDS:
        idx = [np.flatnonzero(m[name]) for m in masks]
        off = np.zeros(len(idx) + 1, dtype=np.int64)
        off[1:] = np.cumsum([r.size for r in idx])
        nominal = getattr(S0, name)
        vals = np.empty((off[-1],) + nominal.shape[1:], dtype=nominal.dtype)
        for k, (Sk, r) in enumerate(zip(S_all, idx)):
            vals[off[k]:off[k + 1]] = getattr(Sk, name)[r]
        rows = np.concatenate(idx).astype(np.int64) if idx else np.zeros(0, np.int64)
        fields.append((off, rows, vals))
    return DesignRows(*fields)


def variable_parts(sys0: System, S0: SystemArrays, Si: SystemArrays | None, tab0: TimeTable,
                   tabi: TimeTable | None, fresh: dict | None = None, *,
                   masks: dict | None = None) -> tuple:
    """The bodies, elements, flexible coordinates, constraint rows, loads, torques and
    spring-dampers whose data differ between the nominal arrays ``S0`` / time table ``tab0``
    and a perturbed design's ``Si`` / ``tabi`` (None: the nominal table): the parts its
    explicit pseudo-load must evaluate. A changed element brings its body and its coordinates;
    a changed element entry of a line load brings its load. ``fresh``: as for
    :func:`changed_rows`; ``masks``: its result, if already formed (``Si`` is then not read)."""
    n_body, n_elem = len(sys0.body_ref), len(sys0.elem_body)
    if masks is None:
        masks = changed_rows(S0, Si, fresh)

    def changed(name):
        return masks[name].copy()

    damp = changed("body_damp")
    elem = (changed("elem_M") | changed("elem_St") | changed("elem_K")
            | damp[sys0.elem_body]) if n_elem else np.zeros(0, bool)
    flex = changed("flex_IS") | changed("flex_I0S") | changed("flex_I0IS")
    fdof = sys0.elem_fdof[elem]
    flex[fdof[fdof >= 0]] = True
    body = changed("body_scal") | damp
    if masks["gravity"].any():  # gravity acts on every body and every coordinate
        body[:] = True
        flex[:] = True
    owner = np.repeat(np.arange(n_body), np.diff(sys0.flex_off))  # body of each coordinate
    body |= np.bincount(owner[flex], minlength=n_body) > 0
    flex |= damp[owner]
    body[sys0.elem_body[elem]] = True
    rows, loads = changed("con_u0"), changed("load_u0")
    torques = np.zeros(tab0.T.shape[1], dtype=bool)
    if tabi is not None:  # time tables (n_t, ...): a row changes if it changes at any time
        rows |= (_changed(tabi.C, tab0.C, 1) | _changed(tabi.CD, tab0.CD, 1)
                 | _changed(tabi.CDD, tab0.CDD, 1))
        loads |= _changed(tabi.F, tab0.F, 1)
        torques |= _changed(tabi.T, tab0.T, 1)
    line = changed("line_u0") | changed("line_N")
    if line.any():
        owner = np.repeat(np.arange(loads.size), np.diff(sys0.line_off))
        loads[owner[line]] = True
    springs = changed("spring_u0") | changed("spring_par")
    return tuple(np.flatnonzero(m).astype(np.int64)
                 for m in (body, elem, flex, rows, loads, torques, springs))


def touched_rows(sys0: System, parts: tuple) -> np.ndarray:
    """The residual rows a residual over ``parts`` (of :func:`variable_parts`) can change,
    sorted: the reference rows of its bodies and the rows of its flexible coordinates (the
    body kernel masks the others), each constraint row with the coordinates of both its sides
    (the multiplier term), the coordinates of its point loads, torques and spring-dampers, and
    the frame and element coordinates of its line loads' elements."""
    bodies, _, flex, rows, loads, torques, springs = parts
    n_dof = sys0.n_dof
    entries = np.concatenate([np.arange(sys0.line_off[i], sys0.line_off[i + 1])
                              for i in loads] + [np.zeros(0, np.int64)]).astype(np.int64)
    elem = sys0.line_elem[entries]
    pieces = [sys0.body_ref[bodies].ravel(), sys0.flex_dof[flex], n_dof + rows,
              sys0.con_dofs[rows].ravel(), sys0.load_dofs[loads].ravel(),
              sys0.torque_dofs[torques].ravel(), sys0.spring_dofs[springs].ravel(),
              sys0.body_ref[sys0.elem_body[elem]].ravel(), sys0.elem_dofs[elem].ravel()]
    out = np.unique(np.concatenate([np.asarray(x, dtype=np.int64) for x in pieces]))
    return out[out >= 0]


def pack_parts(parts: list) -> tuple:
    """Per-variable index lists as ``(offsets, indices)`` pairs (CSR over the variables)."""
    out = []
    for kind in range(7):
        lists = [p[kind] for p in parts]
        off = np.zeros(len(lists) + 1, dtype=np.int64)
        off[1:] = np.cumsum([len(x) for x in lists])
        idx = np.concatenate(lists).astype(np.int64) if lists else np.zeros(0, np.int64)
        out += [off, idx]
    return tuple(out)
