"""Incremental compilation of a perturbed design: unchanged beam frames copied from the nominal.

A sensitivity run compiles one perturbed design ``p + delta e_i`` per variable. A variable
changes a few items of the model (the thickness of a group of elements, a link point, a
modulus), but a beam with one floating frame per element is hundreds of frames, each compiled
in Python. With a record of the nominal compile (``compile_model(..., record=True)``), the
compile of a perturbed design (``like=`` the nominal system) copies the Builder entries of
every frame whose inputs — its nodes, the section values of its elements, the beam's damping
and frame layout — equal the nominal ones, compiles only the others (and the frame joints next
to them), and compiles every other item (rigid bodies, joints, loads: few and cheap) as usual.
Runs of unchanged frames are copied as whole slices of the Builder's lists, so the Python cost
per design grows with the number of changed frames, not with the beam.

The copied entries are the nominal compile's own numbers; where the perturbed design carries
complex numbers (a complex step) they are cast when the arrays are formed, as a full compile's
would hold them. Where the design's inputs equal the nominal's bit for bit, the System equals a
full compile's bit for bit; inputs equal only to round-off (:data:`ROUND_OFF`) are taken as
unchanged, so the copied frames hold the nominal's values where a full compile would hold
values a few ulp off (``tests/test_incremental_compile.py`` checks both).
"""

from __future__ import annotations

import weakref
from dataclasses import dataclass

import numpy as np

#: The Builder's lists, by attribute and key (``None``: the attribute is the list).
_LISTS = (("dof_names", None), ("q0", None), ("v0", None), ("body_ref", None),
          ("body_scal", None), ("body_damp", None), ("flex_off", None), ("flex_dof", None),
          *(("flex", k) for k in ("IS", "I0S", "I0IS")),
          *(("elem", k) for k in ("body", "fdof", "dofs", "M", "St", "K", "B")),
          *(("con", k) for k in ("kind", "dofs", "u0", "c0", "names", "joint", "sign")),
          ("con_drive", None))


def _list(b, attr, key):
    x = getattr(b, attr)
    return x if key is None else x[key]


def snapshot(b) -> tuple:
    """The lengths of every list of the Builder ``b`` (and its element count)."""
    return tuple(len(_list(b, a, k)) for a, k in _LISTS) + (b.n_elem,)


def extend_from(b, src, s0: tuple, s1: tuple) -> None:
    """Append to ``b`` the entries ``src`` (another Builder) added between its snapshots
    ``s0`` and ``s1``."""
    for (a, k), i0, i1 in zip(_LISTS, s0, s1):
        if i1 > i0:
            _list(b, a, k).extend(_list(src, a, k)[i0:i1])
    b.n_elem += s1[-1] - s0[-1]


def section_values(body, n_el: int) -> np.ndarray:
    """The section values the elements of ``body`` are compiled from, (5, n_el):
    ``rho A, E A, E I, E, fibre`` (``bodies._element_arrays``)."""
    out = np.empty((5, n_el), dtype=np.result_type(body.rho, body.area, body.E,
                                                   body.second_moment, body.fibre, float))
    for r, v in enumerate((body.rho * body.area, body.E * body.area,
                           body.E * body.second_moment, body.E, body.fibre)):
        out[r] = v
    return out


@dataclass
class BeamRecord:
    """What the nominal compile of a beam leaves for the perturbed designs: the Builder (its
    lists), snapshots before the beam, after each frame and after the frame joints, the
    frames' outputs, the inputs compared (nodes, section values, damping, frame layout) and
    the beam's BodyInfo."""

    builder: object
    marks: list
    end: tuple
    frames: list
    nodes: np.ndarray
    sections: np.ndarray
    damping: object
    layout: tuple
    first: np.ndarray
    last: np.ndarray
    origin: np.ndarray
    axis: np.ndarray
    info: object


def layout_of(body) -> tuple:
    """What the frame specs of a beam are made from (``model.frames.specs_of``)."""
    return (body.n_elements, body.frames, body.reference, body.reference_node)


def record_beam(b, body, specs, frames, marks, info) -> None:
    """Keep the nominal compile of ``body`` in ``b.record`` (module docstring)."""
    b.record[body.name] = BeamRecord(
        b, marks, snapshot(b), frames, np.array(body.nodes), section_values(body, body.n_elements),
        body.damping, layout_of(body), np.array([s.first for s in specs]),
        np.array([s.last for s in specs]), np.array([s.origin for s in specs]),
        np.array([s.axis for s in specs]).reshape(-1, 2), info)


#: Inputs within this relative difference of the nominal's, with no imaginary part, count as
#: unchanged: a ``build`` that computes in complex arithmetic (a complex step of another
#: variable) reproduces the nominal's values only to round-off (NumPy divides a complex number
#: by a real one through its reciprocal), and such a frame is copied, not recompiled. Set to 0
#: for a System bit for bit equal to a full compile (a full compile then also differs from the
#: nominal in those frames, by round-off).
ROUND_OFF = 4.0 * np.finfo(float).eps


def _differ(x, x0) -> np.ndarray:
    """Entries of ``x`` that differ from the nominal ``x0`` by more than round-off."""
    d = x != x0
    if ROUND_OFF > 0 and d.any():
        near = np.abs(np.real(x) - x0) <= ROUND_OFF * np.abs(x0)
        d &= ~(near & (np.imag(x) == 0))
    return d


def changed_frames(body, rec: BeamRecord) -> np.ndarray | None:
    """Indices of the frames of ``body`` whose inputs differ from the record's, or None if
    the beam cannot be patched (another layout, damping or node count)."""
    if (layout_of(body) != rec.layout or body.nodes.shape != rec.nodes.shape
            or not bool(body.damping == rec.damping)):
        return None
    node = np.any(_differ(body.nodes, rec.nodes), axis=1)
    elem = np.any(_differ(section_values(body, body.n_elements), rec.sections), axis=0)
    cn = np.concatenate([[0], np.cumsum(node)])
    ce = np.concatenate([[0], np.cumsum(elem)])
    hit = ((cn[rec.last + 1] - cn[rec.first]) > 0) | ((ce[rec.last] - ce[rec.first]) > 0)
    hit |= node[rec.origin] | node[rec.axis[:, 0]] | node[rec.axis[:, 1]]
    return np.flatnonzero(hit)


# the records of nominal systems, by id (a System is unhashable): (weak reference, records)
_RECORDS: dict = {}


def remember(system, record: dict) -> None:
    """Keep ``record`` (beam name -> BeamRecord) for ``system`` while it lives."""
    for key in [k for k, (ref, _) in _RECORDS.items() if ref() is None]:
        del _RECORDS[key]
    _RECORDS[id(system)] = (weakref.ref(system), record)


def record_of(system) -> dict | None:
    """The record kept for ``system`` (None if it was compiled without one)."""
    entry = _RECORDS.get(id(system))
    return entry[1] if entry is not None and entry[0]() is system else None
