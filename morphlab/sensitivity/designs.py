"""Perturbed designs and what the sensitivity methods read of them.

A design variable ``p_i`` is differentiated through the user's ``build(p)``: its perturbed
design ``p + delta e_i`` (``delta = i h`` with ``h = 1e-30`` for a complex step, a real step for
finite differences) is built and compiled like the nominal one, or, where it changes beams'
sections alone, only its changed frames' rows are formed (:func:`section_change`). This module
checks that the perturbation keeps the model's structure and changes something, and forms what
the pseudo-loads read (:class:`~morphlab.kernels.pseudo.Pseudo`): per variable the entries of
the flat design data it changes (:mod:`morphlab.compile.design`) with their derivatives and
perturbed values, the items each kind of item must evaluate, along the linear path or the
perturbed one, the derivatives of the time values and of the initial state. Which variables
the adjoint evaluates together: :mod:`morphlab.sensitivity.units`.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from dataclasses import field as _field
from functools import cached_property

import numpy as np

from ..compile import System, compile_model
from ..compile.compile import SectionDelta, compile_like, section_system
from ..compile.design import owners, views
from ..compile.system import time_table
from ..errors import MorphlabError, SensitivityError
from ..kernels.ffrf import scratch
from ..kernels.pseudo import Pseudo
from ..kernels.schema import DESIGN, KINDS, TIME, TOPOLOGY
from ..kernels.system import KIND_NAMES, TIMED_NAMES, Times, pack_parts
from ..model import Model
from ..results.gradients import system_data

#: The complex step (Martins, Sturdza & Alonso 2003): exact to round-off for ``h`` this small.
CS_STEP = 1e-30


def relative_steps(p0: dict, names: list[str], step: float) -> dict[str, float]:
    """Finite-difference steps ``step |p_i|`` (``step`` where ``p_i = 0``): relative, so that a
    density of 2.7e-9 t/mm³ does not get an absolute step."""
    return {v: step * (abs(p0[v]) if p0[v] != 0.0 else 1.0) for v in names}


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


def check_same_layout(a: System, b: System, name: str) -> None:
    """Raise :class:`SensitivityError` if ``b`` (a perturbed design) has another structure
    than ``a``: other DOFs, constraints or sparsity, or any item acting on other DOFs (a node
    another, a body another) — the derivative of a change of topology does not exist."""
    same = (a.n_dof == b.n_dof and a.n_con == b.n_con and a.nnz == b.nnz
            and np.array_equal(a.indices, b.indices) and np.array_equal(a.indptr, b.indptr))
    if not same:
        raise SensitivityError(
            f"changing design variable {name!r} changes the model's structure (DOFs, "
            "constraints or sparsity pattern); build(p) must keep the topology fixed")
    for kind in KIND_NAMES:
        ta, tb = a.table(kind), b.table(kind)
        if (ta is None) != (tb is None):
            raise SensitivityError(f"changing design variable {name!r} adds or removes items "
                                   f"of kind {kind!r}: build(p) must keep the topology fixed")
        if ta is None:
            continue
        for f in KINDS[kind].by_role(TOPOLOGY):
            x, y = getattr(ta, f.name), getattr(tb, f.name)
            if x.shape != y.shape or not np.array_equal(x, y):
                rows = np.flatnonzero(np.any((x != y).reshape(x.shape[0], -1), axis=1)) \
                    if x.shape == y.shape else [0]
                i = int(rows[0]) if len(rows) else 0
                raise SensitivityError(
                    f"changing design variable {name!r} moves {a.owner(kind, i)} to other "
                    "coordinates "
                    "(another node or body): build(p) must keep every load, joint and element "
                    "where it is")


def perturbed_model(build: Callable, p0: dict, name: str, delta) -> Model:
    """``build(p0 + delta e_name)``."""
    p = dict(p0)
    p[name] = p0[name] + delta
    return call_build(build, p, f"with {name!r} perturbed by {delta!r}")


def compile_perturbed(build: Callable, p0: dict, name: str, delta, sys0: System) -> System:
    """``build(p0 + delta e_name)`` compiled like ``sys0`` (complex128 for a complex
    ``delta``), its structure checked."""
    dtype = np.complex128 if isinstance(delta, complex) else np.float64
    sys_p = compile_model(perturbed_model(build, p0, name, delta), dtype=dtype, like=sys0)
    check_same_layout(sys0, sys_p, name)
    return sys_p


@dataclass(eq=False)
class Change:
    """What one perturbed design changes against the nominal: ``positions`` of the flat design
    data and there the derivative ``derivative`` (real) and the perturbed ``values``; the
    derivatives of the time values ``time`` (a :data:`~morphlab.kernels.system.Times` of
    (n_t, n, ...) arrays, None where nothing changes) and of the initial state ``dq0``,
    ``dv0``; ``system``: the perturbed system, built when first read where the design differs
    from the nominal in beams' sections alone (``make``, :func:`section_change`; then
    ``sections`` is set)."""

    positions: np.ndarray
    derivative: np.ndarray
    values: np.ndarray
    time: Times | None
    dq0: np.ndarray
    dv0: np.ndarray
    make: Callable[[], System] = _field(repr=False)
    sections: bool = False

    @cached_property
    def system(self) -> System:
        return self.make()

    def data_derivative(self, sys0: System, key: str) -> np.ndarray:
        """The complex-step derivative of the system data ``key`` (keyed as
        :func:`~morphlab.results.gradients.system_data`; ``sys0`` the nominal system), in its
        shape. A sections-alone change has it without its system: the design field's
        positions it changes, and zero for the rest (geometry, initial state)."""
        if not self.sections:
            return np.imag(system_data(self.system, key)) / CS_STEP
        out = np.zeros(np.shape(system_data(sys0, key)))
        kind, _, name = key.partition(".")
        slot = next((s for s in sys0.slots if (s.kind, s.field) == (kind, name)),
                    None)
        if slot is not None:
            at = (self.positions >= slot.start) & (self.positions < slot.start + out.size)
            out.reshape(-1)[self.positions[at] - slot.start] = self.derivative[at]
        return out


def data_terms(vjps: list, sys0: System, changes: list) -> np.ndarray:
    """The responses' own derivatives through the system data they read (``vjps``: their
    :class:`~morphlab.results.gradients.ResponseVJP`), mapped to the variables with the
    data's complex-step derivatives (n_x, m); ``changes``: the variables' complex-step
    :class:`Change` (:meth:`Change.data_derivative`)."""
    out = np.zeros((len(changes), len(vjps)))
    for r, vj in enumerate(vjps):
        for key, g in vj.data.items():
            for i, ch in enumerate(changes):
                out[i, r] += np.sum(np.real(g) * ch.data_derivative(sys0, key))
    return out


def change_of(sys0: System, sys_p: System, pert, T0: Times, times: np.ndarray) -> Change:
    """The :class:`Change` of the perturbed system ``sys_p`` (perturbation ``pert``: ``1j *
    CS_STEP`` or a real step), ``T0`` the nominal time values at ``times``."""
    complex_step = np.iscomplexobj(pert)

    def deriv(xp, x0):
        return np.imag(xp) / CS_STEP if complex_step else (np.real(xp) - np.real(x0)) / pert

    d = deriv(sys_p.design, sys0.design)
    pos = np.flatnonzero(d != 0.0).astype(np.int64)
    time = None
    if not same_time_inputs(sys0, sys_p):  # else the time values are equal at every time
        # a kind whose values are equal at every time has no derivative (None)
        Tp = time_table(sys_p, times)
        kinds = [None if a is None or all(np.array_equal(x, y) for x, y in zip(a, b)) else
                 type(a)(*(deriv(x, y)[0] for x, y in zip(a, b))) for a, b in zip(Tp, T0)]
        if any(k is not None for k in kinds):
            time = Times(*kinds)
    return Change(pos, d[pos], sys_p.design[pos], time, deriv(sys_p.q0, sys0.q0),
                  deriv(sys_p.v0, sys0.v0), lambda: sys_p)


def section_change(sys0: System, delta: SectionDelta, pert) -> Change:
    """The :class:`Change` of a perturbed design that differs from the nominal in beams'
    sections alone (``delta``: :func:`~morphlab.compile.compile.section_delta`; ``pert``: the
    perturbation): the changed frames' rows only, no copy of the system (built when
    ``system`` is first read); the structure, time values and initial state are the
    nominal's."""
    v0 = sys0.design[delta.positions]
    if np.iscomplexobj(pert):
        d = np.imag(delta.values) / CS_STEP
    else:
        d = (np.real(delta.values) - np.real(v0)) / pert
    keep = d != 0.0
    pos = delta.positions[keep]
    order = np.argsort(pos, kind="stable")
    return Change(pos[order], d[keep][order], delta.values[keep][order], None,
                  np.zeros(sys0.n_dof), np.zeros(sys0.n_dof), lambda: section_system(sys0, delta),
                  sections=True)


def same_time_inputs(sys0: System, sys_p: System) -> bool:
    """Whether ``sys_p`` has the time constants and profiles of ``sys0`` (then its time values
    equal the nominal's at every time, which need not be evaluated). False where a profile
    cannot be compared (then the time values are evaluated and compared)."""
    for name, base in sys0.time_base.items():
        if not np.array_equal(sys_p.time_base[name], base):
            return False
        p0, pp = sys0.time_profiles.get(name, []), sys_p.time_profiles.get(name, [])
        if len(p0) != len(pp):
            return False
        for (i, a), (j, b) in zip(p0, pp):
            try:
                if i != j or not (a is b or bool(a == b)):
                    return False
            except (TypeError, ValueError):  # e.g. a profile holding arrays
                return False
    return True


def changes(build: Callable, p0: dict, names: list[str], sys0: System, times: np.ndarray,
            steps: dict | None = None) -> list[Change]:
    """The :class:`Change` of every variable: complex step (``steps`` None) or forward
    differences with ``steps``; a variable ``build`` does not use raises."""
    T0 = None
    out = []
    for v in names:
        delta = 1j * CS_STEP if steps is None else steps[v]
        dtype = np.dtype(np.complex128 if steps is None else np.float64)
        compiled = compile_like(perturbed_model(build, p0, v, delta), sys0, dtype)
        if isinstance(compiled, SectionDelta):  # sections alone: the changed rows, no system
            ch = section_change(sys0, compiled, delta)
        else:
            sys_p = compiled
            check_same_layout(sys0, sys_p, v)
            T0 = time_table(sys0, times) if T0 is None else T0
            ch = change_of(sys0, sys_p, delta, T0, times)
        if not (ch.positions.size or ch.time is not None or np.any(ch.dq0)
                or np.any(ch.dv0)):
            raise SensitivityError(
                f"design variable {v!r} is not used by build: no compiled array, initial "
                "state or load changes with it, so its gradient would be silently zero")
        out.append(ch)
    return out


def _linear_fields() -> set:
    """``(kind, field)`` of every design and time field the residual is linear in
    (:attr:`~morphlab.kernels.schema.Field.linear`)."""
    return {(k, f.name) for k, kind in KINDS.items() for f in kind.fields if f.linear}


def _items(sys0: System, ch: Change) -> tuple[dict, dict, set]:
    """Per kind, the items a variable's change touches and whether every changed field of the
    kind is linear: ``(items {kind: set}, linear {kind: bool}, flex coordinates)``."""
    linear_fields = _linear_fields()
    items: dict = {}
    linear: dict = {}
    for kind, field, rows in owners(sys0.arrays, ch.positions, sys0.slots):
        if kind is None:  # the gravity: every body and coordinate, along the perturbed path
            for k in ("bodies", "flex", "elements"):
                items.setdefault(k, set()).update(range(sys0.count(k)))
                linear[k] = False
            continue
        items.setdefault(kind, set()).update(rows.tolist())
        linear[kind] = linear.get(kind, True) and (kind, field) in linear_fields
    if ch.time is not None:
        T0 = ch.time
        for kind, tt in zip(TIMED_NAMES, T0):
            if tt is None:
                continue
            for f, x in zip(KINDS[kind].by_role(TIME), tt):
                rows = np.flatnonzero(np.any(x.reshape(x.shape[0], x.shape[1], -1) != 0,
                                             axis=(0, 2)))
                if rows.size:
                    # a kind whose design data and time values both change is not linear
                    # in them together
                    both = kind in items and any(
                        (kind, g.name) in linear_fields for g in KINDS[kind].by_role(DESIGN))
                    items.setdefault(kind, set()).update(rows.tolist())
                    linear[kind] = (linear.get(kind, True) and (kind, f.name) in linear_fields
                                    and not both)
    # the bodies' three tables: a changed element or coordinate brings its body and the
    # coordinates it writes; a body whose damping or gravity changes, all of its own
    A = sys0.arrays
    flex = set(items.get("flex", ()))
    bodies = set(items.get("bodies", ()))
    for e in items.get("elements", ()):
        bodies.add(int(A.elements.body[e]))
        flex.update(int(f) for f in A.elements.fdof[e] if f >= 0)
    owner = np.repeat(np.arange(A.bodies.ref.shape[0]), A.bodies.flex[:, 1] - A.bodies.flex[:, 0])
    bodies.update(int(owner[f]) for f in flex)
    if not linear.get("bodies", True):
        for b in list(bodies):
            f0, f1 = A.bodies.flex[b]
            flex.update(range(f0, f1))
            items.setdefault("elements", set()).update(
                np.flatnonzero(A.elements.body == b).tolist())
    if bodies:
        items["bodies"] = bodies
        lin = all(linear.get(k, True) for k in ("bodies", "flex", "elements"))
        for k in ("bodies", "flex", "elements"):
            linear[k] = lin
    return items, linear, flex


def _tables(sys0: System, T0: Times, per_variable: list, dtype, add_nominal: bool,
            kinds=TIMED_NAMES):
    """Time values of one path, a table per variable with a change (0: none): the derivative
    tables (``add_nominal`` False: the linear path, table 0 zeros) or the perturbed ones (the
    nominal plus the change times the perturbation); None for the kinds not in ``kinds``."""
    index = np.zeros(len(per_variable), dtype=np.int64)
    stacks = []
    for i, extra in enumerate(per_variable):
        if extra is not None:
            index[i] = len(stacks) + 1
            stacks.append(extra)
    out = []
    for j, name in enumerate(TIMED_NAMES):
        tt = T0[j]
        if tt is None or name not in kinds:
            out.append(None)
            continue
        fields = []
        for m, x in enumerate(tt):
            layers = np.zeros((1 + len(stacks),) + x.shape[1:], dtype=dtype)
            if add_nominal:
                layers[:] = x[0]
            for layer, (extra, scale) in enumerate(stacks, 1):
                if extra[j] is not None:
                    if add_nominal:
                        layers[layer] += scale * extra[j][m]
                    else:
                        layers[layer] = extra[j][m]
            fields.append(layers)
        out.append(type(tt)(*fields))
    return Times(*out), index


def system_read(stepper, refine: int | None, w_old, ps: Pseudo | None = None) -> tuple:
    """``(M, T)``, the system and time values of ``stepper``, as a sensitivity kernel called
    from Python takes them: None where it reads neither, as it forms no matrix (the reuse
    variant, ``refine`` None, without an old level's share, ``w_old`` None) and evaluates no
    perturbed path of ``ps`` (None: the kernel evaluates none, as the adjoint's sweep). Its
    Python entry then unboxes neither (about 6 ms of compile an array: ``kernels/_jit.py``)."""
    if refine is None and w_old is None and (ps is None or ps.MN is None):
        return None, None
    return stepper.M, stepper.T


def pseudo_data(sys0: System, chs: list[Change], pert: np.ndarray, T0: Times) -> Pseudo:
    """The pseudo-load data of the changes ``chs`` (:class:`~morphlab.kernels.pseudo.Pseudo`):
    the linear path in real arithmetic, the perturbed path by complex step (``pert`` complex)
    or forward difference; ``T0``: the nominal time values of the run."""
    forward = not np.iscomplexobj(pert)
    lin_parts, nl_parts, fparts = [], [], []
    need = set()  # kinds the perturbed path evaluates
    lin_time, nl_time = [], []
    for ch in chs:
        items, linear, flex = _items(sys0, ch)
        lp = {k: sorted(v) for k, v in items.items() if linear.get(k, True)}
        np_ = {k: sorted(v) for k, v in items.items() if not linear.get(k, True)}
        need.update(np_)
        lin_parts.append(lp)
        nl_parts.append(np_)
        fparts.append(sorted(flex))
        lin_time.append((ch.time, 1.0) if ch.time is not None else None)
        nl_time.append((ch.time, pert[len(nl_time)]) if ch.time is not None else None)
    A = sys0.arrays
    OFF, IDX, _, _ = pack_parts(A, lin_parts)
    OFFN, IDXN, _, _ = pack_parts(A, nl_parts)
    OFFN = OFFN + IDX.size
    IDX = np.concatenate([IDX, IDXN])
    FOFF = np.zeros(len(chs) + 1, dtype=np.int64)
    FOFF[1:] = np.cumsum([len(f) for f in fparts])
    FIDX = np.array([f for fs in fparts for f in fs], dtype=np.int64)
    PO = np.zeros(len(chs) + 1, dtype=np.int64)
    PO[1:] = np.cumsum([ch.positions.size for ch in chs])
    PP = np.concatenate([ch.positions for ch in chs] + [np.zeros(0, np.int64)])
    PV = np.concatenate([ch.derivative for ch in chs] + [np.zeros(0)])
    n_flex = sys0.count("flex")
    # the linear path: the linear design fields as views of a zero vector
    ZL = np.zeros(sys0.design.shape)
    ML = views(A, ZL, {(k, f.name) for k, kind in KINDS.items() for f in kind.fields
                       if f.linear and f.role == DESIGN})
    TL, tl = _tables(sys0, T0, lin_time, np.float64, add_nominal=False)
    WL = scratch(n_flex, np.zeros(1))
    # the perturbed path: the kinds it evaluates, as views of a copy of the design data, in
    # complex arrays for both perturbations (a forward difference evaluates its perturbed
    # residual in complex arithmetic with zero imaginary parts, so it shares every compiled
    # kernel with the complex step instead of compiling its own); none of its data when no
    # variable takes the path: then the kernels compile none of its code
    # (:func:`~morphlab.kernels.pseudo.explicit`) and their Python entries unbox none of it
    VN = D0 = MN = DN = TN = tn = WN = None
    if need:
        dt = np.dtype(np.complex128)
        VN = np.concatenate([np.asarray(ch.values) for ch in chs] + [np.zeros(0)]).astype(dt)
        DN = sys0.design.astype(dt)
        D0 = DN[PP]
        if "bodies" in need:
            need.update(("flex", "elements"))
        MN = views(sys0.arrays_as(dt), DN)
        MN = MN._replace(**{k: None for k in KIND_NAMES if k not in need})
        TN, tn = _tables(sys0, T0, nl_time, dt, add_nominal=True, kinds=need)
        WN = scratch(n_flex, np.zeros(1, dt))
    pert = np.asarray(pert, dtype=np.complex128) if need else None
    return Pseudo(OFF, OFFN, IDX, FOFF, FIDX, PO, PP, PV, VN, D0, ML, ZL, TL, tl, MN, DN, TN,
                  tn, pert, forward, WL, WN)
