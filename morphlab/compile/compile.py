"""Model -> System: DOF numbering, invariants, constraint rows and the fixed CSC pattern.

Compiling is done once per model (and once per perturbed model in a sensitivity run). The
:class:`System` holds flat NumPy arrays only, all of one floating dtype (float64, or complex128
when a design variable carries a complex-step perturbation), plus the index tables that map
names to DOFs. Nothing here is in an inner loop: this is model-building code, kept in NumPy.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from ..errors import ModelError
from ..model import Beam, Model
from ..model.profiles import Profile
from . import bodies, forces, incremental, joints, loads  # noqa: F401 - they register the compile functions
from .builder import Builder, compile_item
from .checks import check_initial, check_rank
from .initial import initial_velocities, needs_initial_velocities
from .pattern import newton_pattern
from .system import System


def _is_complex(value) -> bool:
    """Does ``value`` (a number, an array, or a profile's parameters) hold a complex number?"""
    if isinstance(value, Profile):
        return any(_is_complex(getattr(value, k))
                   for k in getattr(value, "__dataclass_fields__", {}))
    if isinstance(value, (int, float, complex, np.ndarray, np.number)):
        return isinstance(value, complex) or np.iscomplexobj(value)
    return False


def _items(model: Model) -> list:
    """Every body, joint, load and force element of ``model``, in the order they compile
    (point forces before line loads: the load table's order)."""
    return [*model.bodies, *model.joints, *model.forces, *getattr(model, "line_loads", ()),
            *model.torques, *getattr(model, "springs", ())]


def _dtype_of(model: Model):
    """complex128 if any number of the model is complex (a complex-step perturbation of a
    design variable), else float64. Every attribute of every body, joint and load is looked
    at, so a new kind of item needs nothing here."""
    items = _items(model)
    if _is_complex(model.gravity) or any(_is_complex(v) for item in items
                                         for v in vars(item).values()):
        return np.dtype(np.complex128)
    return np.dtype(np.float64)


# what the Newton pattern is built from, and what it consists of (morphlab.pattern)
_TOPOLOGY_KEYS = ("n_dof", "n_con", "body_ref", "flex_off", "flex_dof", "elem_fdof", "con_kind",
                  "con_dofs", "load_dofs", "spring_kind", "spring_dofs", "line_off", "line_elem")
_PATTERN_KEYS = ("indptr", "indices", "border_off", "border_map", "elem_map", "con_map_row",
                 "con_map_col", "con_map_H", "load_map", "spring_map", "line_map")


def _same_topology(sysd: dict, like: System) -> bool:
    return all(np.array_equal(sysd[k], getattr(like, k)) for k in _TOPOLOGY_KEYS)


def compile_model(model: Model, dtype=None, *, like: System | None = None,
                  record: bool = False, on_built: Callable[[System], None] | None = None
                  ) -> System:
    """Compile ``model`` into a :class:`System`.

    Parameters
    ----------
    model : Model
    dtype : numpy dtype, optional
        Force float64 or complex128; by default complex128 exactly when the model holds complex
        numbers (a complex-step perturbation).
    like : System, optional
        A system of the same topology (a perturbed design of a sensitivity run): its Newton
        pattern and scatter maps are reused when the DOF, element, joint and load tables are
        equal (they are compared, and the pattern is built afresh when they are not). If
        ``like`` was compiled with ``record=True``, the beam frames whose inputs equal its
        own are copied from it, not compiled (:mod:`morphlab.compile.incremental`).
    record : bool
        Keep what the perturbed designs of a sensitivity run need to compile incrementally
        (held while the returned system lives).
    on_built : callable, optional
        Called with the system as soon as its arrays are built, before the checks below run
        the first kernels (:func:`morphlab.simulate` starts compiling kernels on a second
        process there, ``morphlab.solve.precompile``).

    Raises
    ------
    ModelError
        Empty model; initial configuration violating the constraints beyond ``1e-9`` of the
        model size, or initial velocities violating them (when the model gives none, they are
        computed from the drives, :mod:`morphlab.compile.initial`); redundant or conflicting
        constraints (rank-deficient constraint Jacobian at the initial configuration, see
        :func:`constraint_rank`).
    """
    if not isinstance(model, Model):
        raise ModelError(f"compile_model expects a Model, got {type(model).__name__}")
    if not model.bodies:
        raise ModelError(f"model {model.name!r} has no bodies")
    dt = np.dtype(dtype) if dtype is not None else _dtype_of(model)
    builder = Builder(model, dt, record=record,
                      prior=incremental.record_of(like) if like is not None else None)
    for item in _items(model):
        compile_item(item, builder)
    patched = incremental.patched_arrays(builder) if builder.copied else None
    sysd = dict(model=model, dtype=dt, **builder.arrays(patched[0] if patched else None))
    if record:
        incremental.keep_formed(builder, sysd)
    extent = np.concatenate([np.real(np.asarray(b.nodes)) if isinstance(b, Beam)
                             else np.real(np.asarray(b.position))[None] for b in model.bodies])
    for j in model.joints:
        if getattr(j, "at", None) is not None:
            extent = np.vstack([extent, np.real(np.asarray(j.at))[None]])
    # model size for the Newton test; a model whose bodies and joints share one point has no
    # extent: fall back to 1 (a unit-agnostic "no scale")
    size = float(np.ptp(extent, axis=0).max())
    sysd["length_scale"] = size if size > 0 else 1.0
    same = like is not None and _same_topology(sysd, like)
    if same:
        sysd.update({k: getattr(like, k) for k in _PATTERN_KEYS})
    else:
        sysd.update(newton_pattern(sysd))
    system = System(**sysd)
    if on_built is not None:
        on_built(system)
    # a complex-step perturbation of ``like``: its real parts are those of ``like`` (to
    # O(h^2) = 1e-60), so the checks of the initial configuration and of the constraint rank,
    # which read real parts only, would repeat those of ``like``
    checked = not (same and dt.kind == "c" and like.dtype.kind == "f")
    if checked:
        check_initial(system, velocities=False)
        check_rank(system)
    if needs_initial_velocities(system):
        system.v0 = initial_velocities(system)
    if checked:
        check_initial(system, positions=False)
    if record:
        incremental.remember(system, builder.record)
    if patched:
        incremental.remember_fresh(system, patched[1])
    return system
