"""What compiling a model accumulates, and the registry of compile functions per item kind.

:func:`morphlab.compile.compile_model` hands every body, joint and load of a model to the
function registered for its class (:func:`compiles`); that function adds the item's DOFs, body
data, elements, constraint rows or loads to a :class:`Builder`. A new kind of body, joint or
load is one model class, one compile function registered here and, where it adds new physics,
one kernel.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from ..errors import ModelError
from ..model import Body, Ground
from ..model.profiles import Profile
from .system import BodyInfo

_COMPILERS: dict[type, Callable] = {}


def compiles(kind: type) -> Callable:
    """Register the decorated ``f(item, builder)`` as the compile function of ``kind``."""

    def register(fn: Callable) -> Callable:
        _COMPILERS[kind] = fn
        return fn

    return register


def compile_item(item, builder: Builder) -> None:
    """Add ``item`` to ``builder`` with the function registered for its class (or a base)."""
    for cls in type(item).__mro__:
        fn = _COMPILERS.get(cls)
        if fn is not None:
            fn(item, builder)
            return
    known = ", ".join(sorted(k.__name__ for k in _COMPILERS))
    name = getattr(item, "name", "")
    raise ModelError(f"{type(item).__name__} {name!r}: no compile function for this kind of "
                     f"item (known kinds: {known})")


class Builder:
    """DOF numbering and the arrays of a System, filled item by item.

    Attributes (lists until :meth:`arrays`; see :class:`morphlab.kernels.system.SystemArrays`
    for the meaning of each): ``dof_names``, ``q0``, ``v0``; per body ``body_ref``,
    ``body_scal``, ``body_damp``, ``flex_off``; per flexible coordinate ``flex_dof``,
    ``flex_IS``, ``flex_I0S``, ``flex_I0IS``; per element ``elem_*``; per constraint row
    ``con_*`` (with its name, joint and the profile of a driven row); per load (point or line
    load) ``load_*``; per loaded element of a line load ``line_*``; per torque ``torque_*``;
    per spring-damper ``spring_*``; ``bodies`` (name -> :class:`BodyInfo`) and
    ``locate`` (name -> the function that finds a material point of the body, set by the
    body's compile function; :meth:`point`).
    """

    def __init__(self, model, dtype: np.dtype, *, record: bool = False,
                 prior: dict | None = None):
        self.model = model
        self.dtype = dtype
        # beam name -> the nominal compile's record (morphlab.compile.incremental): kept when
        # ``record``, read from ``prior`` when compiling a perturbed design
        self.record: dict | None = {} if record else None
        self.prior = prior
        # the snapshots between which entries were copied from the prior's Builder (None: not
        # at the same positions), and the nominal's formed arrays (incremental.patched_arrays)
        self.copied: list | None = [] if prior is not None else None
        self.rewritten: list = []  # copied entries replaced since: (list, i0, i1)
        self.formed: dict | None = None
        self.bodies: dict[str, BodyInfo] = {}
        self.locate: dict[str, Callable] = {}  # body name -> f(at) -> (dofs, u0, angle0)
        self._points: dict = {}  # (body name, at) -> what locate gave (read only)
        self.dof_names: list[str] = []
        self.q0: list = []
        self.v0: list = []
        self.body_ref: list = []
        self.body_scal: list = []
        self.body_damp: list = []
        self.flex_off = [0]
        self.flex_dof: list = []
        self.flex = {"IS": [], "I0S": [], "I0IS": []}
        self.elem = {k: [] for k in ("body", "fdof", "dofs", "M", "St", "K", "B")}
        self.n_elem = 0
        self.con = {k: [] for k in ("kind", "dofs", "u0", "c0", "names", "joint", "sign")}
        self.con_drive: list = []
        self.load = {k: [] for k in ("dofs", "u0", "F0", "prof", "name")}
        self.torque = {k: [] for k in ("dofs", "T0", "prof", "name")}
        self.spring = {k: [] for k in ("kind", "dofs", "u0", "par", "name")}
        self.line = {k: [] for k in ("load", "elem", "u0", "N")}

    # ---- DOFs and bodies
    def add_dofs(self, names: list[str], q0, v0) -> np.ndarray:
        """New DOFs with their initial values; returns their global numbers."""
        first = len(self.dof_names)
        self.dof_names += names
        self.q0 += list(q0)
        self.v0 += list(v0)
        return np.arange(first, first + len(names), dtype=np.int64)

    def add_body(self, name: str, q0, v0, scal, damping) -> tuple[int, np.ndarray]:
        """A body frame (reference coordinates ``x, y, theta`` at ``q0`` (3,) moving with
        ``v0``) with its invariants ``scal = (m, I_u_x, I_u_y, I_00)`` and damping; returns
        its index and the DOFs of its frame."""
        ref = self.add_dofs([f"{name}.x", f"{name}.y", f"{name}.theta"], q0, v0)
        self.body_ref.append(ref)
        self.body_scal.append(list(scal))
        self.body_damp.append(damping)
        return len(self.body_ref) - 1, ref

    def close_body(self, flex_dofs, IS, I0S, I0IS) -> int:
        """The flexible coordinates of the body added last (its global DOFs and invariants,
        possibly none); returns the index of its first flexible coordinate."""
        first = self.flex_off[-1]
        self.flex_dof += list(flex_dofs)
        self.flex_off.append(first + len(flex_dofs))
        for key, value in (("IS", IS), ("I0S", I0S), ("I0IS", I0IS)):
            if value is not None:
                self.flex[key].append(value)
        return first

    def add_elements(self, body: int, fdof, dofs, M, St, K, B) -> slice:
        """Elements of body ``body`` (its flexible coordinate and global DOF of each element
        DOF, -1 where removed, and the element matrices); returns their rows."""
        n = fdof.shape[0]
        for key, value in (("body", np.full(n, body, dtype=np.int64)), ("fdof", fdof),
                           ("dofs", dofs), ("M", M), ("St", St), ("K", K), ("B", B)):
            self.elem[key].append(value)
        self.n_elem += n
        return slice(self.n_elem - n, self.n_elem)

    @property
    def bodies_count(self) -> int:
        """Number of (kernel) bodies added so far."""
        return len(self.body_ref)

    # ---- points, constraint rows and loads
    def point(self, body: Body, at):
        """``(dofs (6,), u0 (2,), angle0)`` of the material point of ``body`` at the global
        point ``at``: the DOFs ``R_x, R_y, theta, u, v, phi`` (-1 where absent; all -1 for the
        ground), its position in the body frame and the frame's initial angle."""
        if isinstance(body, Ground):
            return -np.ones(6, dtype=np.int64), np.zeros(2, dtype=self.dtype), 0.0
        # a joint's point is looked up for its rows and again for its reaction sign
        key = (body.name, tuple(np.asarray(at).ravel().tolist()))
        hit = self._points.get(key)
        if hit is None:
            hit = self._points[key] = self.locate[body.name](at)
        return hit

    def add_row(self, kind: int, joint, label: str, pa, pb, c0, profile: Profile | None = None,
                beta=0.0):
        """A constraint row ``g(q) - c(t) = 0`` of ``kind`` between the points ``pa`` and
        ``pb`` (:meth:`point`), ``c = c0`` (+ ``profile(t)`` for a driven row); ``beta``: the
        angle in ``pb``'s body frame of a slide row's normal (``kernels.joints``)."""
        u0 = np.zeros((2, 3), dtype=self.dtype)
        u0[0, :2], u0[1, :2], u0[1, 2] = pa[1], pb[1], beta
        for key, value in (("kind", kind), ("dofs", np.stack([pa[0], pb[0]])),
                           ("u0", u0), ("c0", c0),
                           ("names", f"{joint.name}.{label}"), ("joint", joint.name),
                           ("sign", self._reaction_sign(joint, pa))):
            self.con[key].append(value)
        if profile is not None:
            self.con_drive.append((len(self.con["kind"]) - 1, profile))

    def _reaction_sign(self, joint, pa) -> float:
        """The sign with which a row's multiplier pushes the body the joint holds
        (``morphlab.results.reactions``): ``-1`` if that body is side 0 (``pa``), ``+1`` if side
        1; negated when the held body ``b`` is the ground (the action on ``a`` is measured)."""
        held, flip = getattr(joint, "b", None), 1.0
        if held is None:
            held = getattr(joint, "body", None)
        if isinstance(held, Ground):
            held, flip = joint.a, -1.0
        at = getattr(joint, "at", None)
        if at is None:
            at = getattr(held, "position", None)
        if held is None or at is None:
            return float("nan")  # a kind of joint without a held body: no reaction
        return flip * (-1.0 if np.array_equal(pa[0], self.point(held, at)[0]) else 1.0)

    def add_load(self, point, force, profile: Profile, name: str) -> None:
        """A point force ``force * profile(t)`` (global direction) at ``point``."""
        dofs, u0, _ = point
        for key, value in (("dofs", dofs), ("u0", u0), ("F0", np.asarray(force)),
                           ("prof", profile), ("name", name)):
            self.load[key].append(value)

    def add_line(self, load: int, element: int, u0, N) -> None:
        """A loaded element of the line load ``load`` (its index among the loads): the
        element's row and its integrals ``u0 = (int ds, int u0 ds)`` (3,) and
        ``N = int S_e ds`` (2, 6) (``morphlab.kernels.loads``)."""
        for key, value in (("load", load), ("elem", element), ("u0", u0), ("N", N)):
            self.line[key].append(value)

    def add_spring(self, kind: int, pa, pb, u0, par, name: str) -> None:
        """A spring-damper of ``kind`` (``morphlab.kernels.forces``) between the points ``pa``
        and ``pb`` (:meth:`point`; their body-frame points ``u0`` (2, 2)) with
        ``par = (k, c, s0, f0)``."""
        for key, value in (("kind", kind), ("dofs", np.stack([pa[0], pb[0]])), ("u0", u0),
                           ("par", par), ("name", name)):
            self.spring[key].append(value)

    def add_torque(self, dofs, magnitude, profile: Profile, name: str) -> None:
        """A torque ``magnitude * profile(t)`` on the DOFs ``dofs`` (2,): a body angle and a
        nodal rotation (-1 if none)."""
        for key, value in (("dofs", dofs), ("T0", magnitude), ("prof", profile),
                           ("name", name)):
            self.torque[key].append(value)

    # ---- the result
    def arrays(self, lists: dict | None = None) -> dict:
        """The System fields accumulated (arrays of the right dtype and shape); ``lists``:
        those of :meth:`list_arrays` when already formed (a perturbed design's, patched from
        the nominal's by :func:`morphlab.compile.incremental.patched_arrays`)."""
        dt, i64 = self.dtype, np.int64
        ld, tq, sp, li = self.load, self.torque, self.spring, self.line
        # line loads are rows of the load table: the range of each load's element entries
        line_off = np.zeros(len(ld["name"]) + 1, dtype=i64)
        np.add.at(line_off, np.array(li["load"], dtype=i64) + 1, 1)
        return dict(
            **(self.list_arrays() if lists is None else lists),
            gravity=np.asarray(self.model.gravity, dtype=dt),
            load_dofs=_arr(ld["dofs"], (-1, 6), i64), load_u0=_arr(ld["u0"], (-1, 2), dt),
            load_F0=_arr(ld["F0"], (-1, 2), dt), load_prof=ld["prof"], load_names=ld["name"],
            torque_dofs=_arr(tq["dofs"], (-1, 2), i64), torque_T0=np.array(tq["T0"], dtype=dt),
            torque_prof=tq["prof"], torque_names=tq["name"], bodies=self.bodies,
            spring_kind=np.array(sp["kind"], dtype=i64),
            spring_dofs=_arr(sp["dofs"], (-1, 2, 6), i64),
            spring_u0=_arr(sp["u0"], (-1, 2, 2), dt), spring_par=_arr(sp["par"], (-1, 4), dt),
            spring_names=sp["name"], line_off=np.cumsum(line_off),
            line_elem=np.array(li["elem"], dtype=i64), line_u0=_arr(li["u0"], (-1, 3), dt),
            line_N=_arr(li["N"], (-1, 2, 6), dt),
        )

    def list_arrays(self) -> dict:
        """The System fields formed from the lists an incremental compile copies from the
        nominal's (:data:`morphlab.compile.incremental._LISTS`): DOFs, bodies, flexible
        coordinates, elements and constraint rows."""
        dt, i64 = self.dtype, np.int64
        e, c = self.elem, self.con
        return dict(
            n_dof=len(self.dof_names), n_con=len(c["kind"]),
            q0=np.array(self.q0, dtype=dt), v0=np.array(self.v0, dtype=dt),
            body_ref=_arr(self.body_ref, (-1, 3), i64),
            body_scal=_arr(self.body_scal, (-1, 4), dt),
            body_damp=np.array(self.body_damp, dtype=dt),
            flex_off=np.array(self.flex_off, dtype=i64), flex_dof=np.array(self.flex_dof, i64),
            flex_IS=_cat(self.flex["IS"], (0, 2), dt), flex_I0S=_cat(self.flex["I0S"], (0,), dt),
            flex_I0IS=_cat(self.flex["I0IS"], (0,), dt),
            elem_body=_cat(e["body"], (0,), i64), elem_fdof=_cat(e["fdof"], (0, 6), i64),
            elem_dofs=_cat(e["dofs"], (0, 6), i64), elem_M=_cat(e["M"], (0, 6, 6), dt),
            elem_St=_cat(e["St"], (0, 6, 6), dt), elem_K=_cat(e["K"], (0, 6, 6), dt),
            elem_B=_cat(e["B"], (0, 2, 2, 6), dt),
            con_kind=np.array(c["kind"], dtype=i64), con_dofs=_arr(c["dofs"], (-1, 2, 6), i64),
            con_u0=_arr(c["u0"], (-1, 2, 3), dt), con_c0=np.array(c["c0"], dtype=dt),
            con_sign=np.array(c["sign"], dtype=np.float64), con_drive=self.con_drive,
            dof_names=self.dof_names, con_names=c["names"], con_joint=c["joint"],
        )


def _cat(lst: list, shape: tuple, dtype) -> np.ndarray:
    """The chunks ``lst`` concatenated (``shape``, empty, if there are none)."""
    return np.ascontiguousarray(np.concatenate(lst) if lst else np.zeros(shape, dtype),
                                dtype=dtype)


def _arr(lst: list, shape: tuple, dtype) -> np.ndarray:
    """The entries ``lst`` as one array of ``shape``."""
    return np.array(lst, dtype=dtype).reshape(shape)
