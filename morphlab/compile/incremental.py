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
per design grows with the number of changed frames, not with the beam. Where a beam's nodes
are the nominal's and only its section values changed (a thickness, a modulus), every entry is
copied and the changed frames' numbers — their mass invariants, summed element invariants and
element matrices, formed for all of them in one stack — replace the copies (:func:`rewrite`):
their DOFs, connectivity and frame joints do not depend on the sections.

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
    ``s0`` and ``s1``; noted in ``b.copied`` when they land at the same positions."""
    if b.copied is not None and snapshot(b) == s0:
        b.copied.append((s0, s1))
    elif b.copied is not None:
        b.copied = None
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


def nodes_changed(body, rec: BeamRecord) -> bool:
    """Whether any node of ``body`` differs from the record's (by more than round-off)."""
    return bool(np.any(_differ(body.nodes, rec.nodes)))


#: The numbers of a frame that depend on the section values only (with the nodes unchanged,
#: everything else a frame adds — DOFs, connectivity, frame joints — is the nominal's): one
#: entry of each of these lists per frame.
SECTION_LISTS = (("body_scal", None), *(("flex", k) for k in ("IS", "I0S", "I0IS")),
                 *(("elem", k) for k in ("M", "St", "K", "B")))
_INDEX = {ak: j for j, ak in enumerate(_LISTS)}


def one_entry_per_frame(rec: BeamRecord, frames) -> bool:
    """Whether each of ``frames`` added exactly one entry to every :data:`SECTION_LISTS` list
    (then :func:`rewrite` can replace them in place)."""
    return all(rec.marks[f + 1][_INDEX[ak]] - rec.marks[f][_INDEX[ak]] == 1
               for f in frames for ak in SECTION_LISTS)


def frame_start(rec: BeamRecord, f: int, attr: str, key=None) -> int:
    """Where frame ``f``'s entries begin in the nominal's list ``(attr, key)``."""
    return rec.marks[f][_INDEX[attr, key]]


def rewrite(b, rec: BeamRecord, f: int, values: dict) -> None:
    """Replace the :data:`SECTION_LISTS` entries of frame ``f`` (copied from the nominal,
    at the nominal's positions) by ``values`` ((attr, key) -> entry), noted in
    ``b.rewritten`` so that :func:`patched_arrays` forms those rows afresh."""
    for (attr, key), value in values.items():
        j = _INDEX[attr, key]
        i = rec.marks[f][j]
        _list(b, attr, key)[i] = value
        b.rewritten.append((j, i, i + 1))


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


# what is kept per system, by id (a System is unhashable): (weak reference, value); the
# records of nominal systems and the rows perturbed systems compiled afresh
_RECORDS: dict = {}
_FRESH: dict = {}


def _keep(store: dict, system, value) -> None:
    for key in [k for k, (ref, _) in store.items() if ref() is None]:
        del store[key]
    store[id(system)] = (weakref.ref(system), value)


def _kept(store: dict, system):
    entry = store.get(id(system))
    return entry[1] if entry is not None and entry[0]() is system else None


def remember(system, record: dict) -> None:
    """Keep ``record`` (beam name -> BeamRecord) for ``system`` while it lives."""
    _keep(_RECORDS, system, record)


def record_of(system) -> dict | None:
    """The record kept for ``system`` (None if it was compiled without one)."""
    return _kept(_RECORDS, system)


def remember_fresh(system, fresh: dict) -> None:
    """Keep ``fresh`` (:func:`patched_arrays`) for the perturbed ``system`` while it lives."""
    _keep(_FRESH, system, fresh)


def fresh_rows(system) -> dict | None:
    """For a system compiled by patching the nominal's arrays: field -> the rows (int64,
    along the first axis) compiled afresh; every other row holds the nominal's entry, cast.
    None for a system compiled in full."""
    return _kept(_FRESH, system)


# ---------------------------------------------------- the arrays, patched from the nominal's
#: The array fields formed from the Builder's lists (``Builder.list_arrays``): the list, whether
#: its entries are chunks of rows (else one row each), and the dtype ("f": the System's,
#: "i": int64, "r": float64).
_FIELDS = {"q0": ("q0", None, False, "f"), "v0": ("v0", None, False, "f"),
           "body_ref": ("body_ref", None, False, "i"),
           "body_scal": ("body_scal", None, False, "f"),
           "body_damp": ("body_damp", None, False, "f"),
           "flex_off": ("flex_off", None, False, "i"),
           "flex_dof": ("flex_dof", None, False, "i"),
           **{f"flex_{k}": ("flex", k, True, "f") for k in ("IS", "I0S", "I0IS")},
           **{f"elem_{k}": ("elem", k, True, "i") for k in ("body", "fdof", "dofs")},
           **{f"elem_{k}": ("elem", k, True, "f") for k in ("M", "St", "K", "B")},
           **{f"con_{k}": ("con", k, False, "i") for k in ("kind", "dofs")},
           **{f"con_{k}": ("con", k, False, "f") for k in ("u0", "c0")},
           "con_sign": ("con", "sign", False, "r")}


def keep_formed(b, arrays: dict) -> None:
    """Keep copies of the nominal's arrays (``b`` its Builder) for :func:`patched_arrays`."""
    b.formed = {k: np.array(arrays[k]) for k in _FIELDS}


def _fresh_spans(copied: list, j: int, n: int, rewritten: dict) -> list:
    """The ranges of list ``j`` (``n`` entries) formed afresh: the complement of ``copied``,
    and the copied entries rewritten since (``rewritten``: list -> ranges)."""
    spans, at = [], 0
    for i0, i1 in sorted((s0[j], s1[j]) for s0, s1 in copied if s1[j] > s0[j]):
        if i0 > at:
            spans.append((at, i0))
        at = max(at, i1)
    spans = spans + [(at, n)] if n > at else spans
    spans += rewritten.get(j, [])
    merged: list = []
    for i0, i1 in sorted(spans):
        if merged and i0 <= merged[-1][1]:
            merged[-1] = (merged[-1][0], max(merged[-1][1], i1))
        else:
            merged.append((i0, i1))
    return merged


def _offsets(src, attr: str, key) -> np.ndarray:
    """First row of every chunk of a list of ``src`` (the nominal's Builder), and the end."""
    cache = src.__dict__.setdefault("chunk_offsets", {})
    if (attr, key) not in cache:
        cache[attr, key] = np.concatenate(
            [[0], np.cumsum([len(x) for x in _list(src, attr, key)])]).astype(np.int64)
    return cache[attr, key]


def patched_arrays(b) -> tuple[dict, dict] | None:
    """``(Builder.list_arrays(), fresh)`` of a perturbed design's Builder ``b`` formed from
    the nominal's arrays, overwritten only at the entries ``b`` did not copy (its changed
    frames, their frame joints and the items compiled in full): the same arrays as the
    Builder's, at the cost of the changed entries. ``fresh``: field -> the rows overwritten.
    None where the copies are not at the nominal's positions (then the arrays are formed in
    full)."""
    rec = next(iter(b.prior.values()), None) if b.prior else None
    src = rec.builder if rec is not None else None
    if not b.copied or src is None or src.formed is None or snapshot(b) != snapshot(src):
        return None
    index = {ak: j for j, ak in enumerate(_LISTS)}
    out = dict(n_dof=len(b.dof_names), n_con=len(b.con["kind"]), con_drive=b.con_drive,
               dof_names=b.dof_names, con_names=b.con["names"], con_joint=b.con["joint"])
    fresh, rewritten = {}, {}
    for j, i0, i1 in b.rewritten:
        rewritten.setdefault(j, []).append((i0, i1))
    for field, (attr, key, chunked, kind) in _FIELDS.items():
        lst = _list(b, attr, key)
        dtype = {"f": b.dtype, "i": np.int64, "r": np.float64}[kind]
        arr = src.formed[field].astype(dtype)
        off = _offsets(src, attr, key) if chunked else None
        rows = []
        for i0, i1 in _fresh_spans(b.copied, index[attr, key], len(lst), rewritten):
            r0, r1 = (int(off[i0]), int(off[i1])) if chunked else (i0, i1)
            val = np.concatenate(lst[i0:i1]) if chunked else np.array(lst[i0:i1], dtype=dtype)
            if val.size != arr[r0:r1].size:
                return None
            arr[r0:r1] = val.reshape(arr[r0:r1].shape)
            rows.append(np.arange(r0, r1, dtype=np.int64))
        out[field] = arr
        fresh[field] = np.concatenate(rows) if rows else np.zeros(0, np.int64)
    return out, fresh
