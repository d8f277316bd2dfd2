"""The arrays every whole-system kernel reads, as named tuples.

A compiled model reaches the kernels as one :class:`SystemArrays` (built by
``morphlab.compile.kernel_arrays``), read by field name: ``S.elem_M``, ``S.con_dofs``. Its
fields come in three groups:

* the **design data** (float64, or complex128 for a complex-step perturbation): everything a
  design variable can change — gravity, body invariants and damping, flexible invariants,
  element matrices, the body-frame points of joints and loads. :data:`DESIGN_FIELDS` lists
  them once; a sensitivity run keeps, per design variable, only the rows of them its design
  changes (:class:`DesignRows`), and evaluates the residual of design ``i`` on a working copy of
  the nominal data with those rows written in and out again (:func:`set_design`);
* the **topology** (int64): DOF numbers of bodies, flexible coordinates, elements, constraint
  rows and loads;
* the **pattern** (int64): where each contribution goes in the CSC data of the step matrix
  (``-1``: skipped);
* one **switch**, ``extra_items``: ``True`` when the model has items beyond bodies, the
  point joints (revolute, weld, fix, driving constraints) and torques — prismatic joints, point
  forces, spring-dampers or line loads — and ``None`` otherwise. Numba compiles a kernel for
  the types of its arguments and drops a branch ``if extra is not None`` of an argument typed
  ``None``. The kernels take the switch as an argument
  (``kernels.joints.constraint_residual(S.extra_items, S, ...)``,
  ``kernels.assemble.applied_residual``), so the code of those items is compiled only for
  models that have some: a shorter first run for the others, such as the morphing leading
  edge. One switch, not one per kind: each combination of switches is a separate compilation
  of every kernel.

Array shapes (``morphlab.compile`` fills them; ``docs/theory.md`` §2-§4 the formulation):

========== ==================== =============================================================
field      shape                meaning
========== ==================== =============================================================
gravity    (2,)                 gravitational acceleration
body_scal  (n_body, 4)          ``m, I_u_x, I_u_y, I_00`` of each body
body_damp  (n_body,)            stiffness-proportional damping ``beta_d`` of each body
flex_IS    (n_flex, 2)          ``I_S`` of each flexible coordinate
flex_I0S   (n_flex,)            ``I_0S``
flex_I0IS  (n_flex,)            ``I_0ĨS``
elem_M     (n_elem, 6, 6)       element ``M_ff``
elem_St    (n_elem, 6, 6)       element ``S̃``
elem_K     (n_elem, 6, 6)       element stiffness
con_u0     (n_con, 2, 3)        body-frame point of each side of a row, and an angle (slide)
load_u0    (n_load, 2)          body-frame point of each point load (zeros: a line load)
spring_u0  (n_spring, 2, 2)     body-frame point of each side of a spring (ground: global)
spring_par (n_spring, 4)        ``k, c, s0, f0`` of each spring-damper (``kernels.forces``)
line_u0    (n_line, 3)          ``int ds, int u0 ds`` of each loaded element of a line load
line_N     (n_line, 2, 6)       ``int S_e ds`` of each loaded element (``kernels.loads``)
body_ref   (n_body, 3)          DOFs ``R_x, R_y, theta`` of each body
flex_off   (n_body + 1,)        each body's range of flexible coordinates
flex_dof   (n_flex,)            DOF of each flexible coordinate
elem_body  (n_elem,)            body of each element
elem_fdof  (n_elem, 6)          flexible coordinate of each element DOF (``-1``: removed)
con_kind   (n_con,)             row kind (:data:`morphlab.kernels.joints.ROW_X`, ...)
con_dofs   (n_con, 2, 6)        DOFs ``R_x, R_y, theta, u, v, phi`` of each side of a row
load_dofs  (n_load, 6)          the same for the point of each point load (``-1``: a line load)
torque_dofs (n_torque, 2)       DOF of the body angle and of a nodal rotation (``-1``)
spring_kind (n_spring,)         :data:`morphlab.kernels.forces.SPRING_LENGTH` or ``_ANGLE``
spring_dofs (n_spring, 2, 6)    DOFs of each side of a spring, as ``con_dofs``
line_off   (n_load + 1,)        each load's range of line entries (empty: a point load)
line_elem  (n_line,)            element of each line entry
border_*   ...                  positions of the body border entries (``ffrf.body_jacobian``)
elem_map   (n_elem, 6, 6)       positions of the element entries
con_map_*  ...                  positions of the constraint row, column and Hessian entries
load_map   (n_load, 6, 6)       positions of the point-load Hessian entries
spring_map (n_spring, 2,2,6,6)  positions of the spring entries (row side, column side)
line_map   (n_line, 7, 7)       positions of the line-load entries (theta, then ``d``)
extra_items  True or None       whether the model has slide rows, point forces, spring-dampers
                                or line loads
========== ==================== =============================================================
"""

from typing import NamedTuple

import numpy as np
from numba import njit


class SystemArrays(NamedTuple):
    """Everything a whole-system kernel reads (module docstring)."""

    # design data
    gravity: np.ndarray
    body_scal: np.ndarray
    body_damp: np.ndarray
    flex_IS: np.ndarray
    flex_I0S: np.ndarray
    flex_I0IS: np.ndarray
    elem_M: np.ndarray
    elem_St: np.ndarray
    elem_K: np.ndarray
    con_u0: np.ndarray
    load_u0: np.ndarray
    spring_u0: np.ndarray
    spring_par: np.ndarray
    line_u0: np.ndarray
    line_N: np.ndarray
    # topology
    body_ref: np.ndarray
    flex_off: np.ndarray
    flex_dof: np.ndarray
    elem_body: np.ndarray
    elem_fdof: np.ndarray
    con_kind: np.ndarray
    con_dofs: np.ndarray
    load_dofs: np.ndarray
    torque_dofs: np.ndarray
    spring_kind: np.ndarray
    spring_dofs: np.ndarray
    line_off: np.ndarray
    line_elem: np.ndarray
    # pattern
    border_off: np.ndarray
    border_map: np.ndarray
    elem_map: np.ndarray
    con_map_row: np.ndarray
    con_map_col: np.ndarray
    con_map_H: np.ndarray
    load_map: np.ndarray
    spring_map: np.ndarray
    line_map: np.ndarray
    # switch (module docstring)
    extra_items: bool | None


class DesignRows(NamedTuple):
    """The design data of several designs as the rows each changes: for every design field of
    :class:`SystemArrays`, ``(off, rows, vals)`` with ``off`` (n_x + 1,) and ``rows`` (nnz,)
    int64 (CSR over the designs) and ``vals`` (nnz, *row shape): design ``i`` holds
    ``vals[k]`` in row ``rows[k]`` for ``off[i] <= k < off[i + 1]`` and the nominal's entry in
    every other row. Memory grows with what the variables change, not with n_x times the
    model."""

    gravity: tuple
    body_scal: tuple
    body_damp: tuple
    flex_IS: tuple
    flex_I0S: tuple
    flex_I0IS: tuple
    elem_M: tuple
    elem_St: tuple
    elem_K: tuple
    con_u0: tuple
    load_u0: tuple
    spring_u0: tuple
    spring_par: tuple
    line_u0: tuple
    line_N: tuple


#: The fields of :class:`SystemArrays` a design variable can change (the floating-point ones).
DESIGN_FIELDS = DesignRows._fields


class Parts(NamedTuple):
    """What a residual evaluation covers: index arrays of the bodies, elements, constraint
    rows, loads (point and line loads), torques and spring-dampers, and a mask over the
    flexible coordinates. The residual covers everything; a sensitivity pseudo-load only what
    one design variable changes."""

    bodies: np.ndarray
    elements: np.ndarray
    flex: np.ndarray
    rows: np.ndarray
    loads: np.ndarray
    torques: np.ndarray
    springs: np.ndarray


@njit(cache=True, inline="always")
def all_parts(S):
    """:class:`Parts` covering the whole system."""
    return Parts(np.arange(S.body_ref.shape[0]), np.arange(S.elem_fdof.shape[0]),
                 np.ones(S.flex_dof.shape[0], dtype=np.bool_), np.arange(S.con_kind.shape[0]),
                 np.arange(S.load_dofs.shape[0]), np.arange(S.torque_dofs.shape[0]),
                 np.arange(S.spring_kind.shape[0]))


@njit(cache=True, inline="always")
def _set_rows(w, s, d, i, on):
    """Rows of design ``i`` (``d = (off, rows, vals)``) into ``w`` (``on``), or ``s``'s back."""
    off, rows, vals = d
    for k in range(off[i], off[i + 1]):
        r = rows[k]
        if on:
            w[r] = vals[k]
        else:
            w[r] = s[r]


@njit(cache=True)
def set_design(W, S, D, i, on):
    """Write the rows design ``i`` of ``D`` (:class:`DesignRows`) changes into the design data
    of ``W`` (``on`` True), or the nominal ``S``'s entries of those rows back (``on`` False):
    ``W`` is then design ``i``, or the nominal again. ``W`` and ``S`` have equal shapes and
    dtypes; only the design data of ``W`` is written."""
    _set_rows(W.gravity, S.gravity, D.gravity, i, on)
    _set_rows(W.body_scal, S.body_scal, D.body_scal, i, on)
    _set_rows(W.body_damp, S.body_damp, D.body_damp, i, on)
    _set_rows(W.flex_IS, S.flex_IS, D.flex_IS, i, on)
    _set_rows(W.flex_I0S, S.flex_I0S, D.flex_I0S, i, on)
    _set_rows(W.flex_I0IS, S.flex_I0IS, D.flex_I0IS, i, on)
    _set_rows(W.elem_M, S.elem_M, D.elem_M, i, on)
    _set_rows(W.elem_St, S.elem_St, D.elem_St, i, on)
    _set_rows(W.elem_K, S.elem_K, D.elem_K, i, on)
    _set_rows(W.con_u0, S.con_u0, D.con_u0, i, on)
    _set_rows(W.load_u0, S.load_u0, D.load_u0, i, on)
    _set_rows(W.spring_u0, S.spring_u0, D.spring_u0, i, on)
    _set_rows(W.spring_par, S.spring_par, D.spring_par, i, on)
    _set_rows(W.line_u0, S.line_u0, D.line_u0, i, on)
    _set_rows(W.line_N, S.line_N, D.line_N, i, on)
