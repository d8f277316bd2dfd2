"""Compile functions of the bodies: rigid bodies and flexible beams (FFRF).

Each adds the body's reference coordinates ``x, y, theta``, its invariants and, for a beam, its
flexible coordinates and elements to the :class:`~morphlab.compile.builder.Builder`, and tells
the builder how to find a material point of the body (``builder.locate``).
Formulation: ``docs/theory.md`` §2 (body) and §3 (element).
"""

from __future__ import annotations

from types import SimpleNamespace
from typing import NamedTuple

import numpy as np

from ..kernels.joints import ROW_ANGLE, ROW_X, ROW_Y
from ..model import Beam, RigidBody
from ..model.frames import holding_frame, specs_of
from .beam import Units, element_data, element_units
from .builder import Builder, compiles
from .system import BodyInfo


def rotation(th):
    """``[[cos th, -sin th], [sin th, cos th]]`` (complex-safe)."""
    c, s = np.cos(th), np.sin(th)
    return np.array([[c, -s], [s, c]])


@compiles(RigidBody)
def compile_rigid(body: RigidBody, b: Builder) -> None:
    """Reference point at the centre of mass: ``M = diag(m, m, J)``, no flexible coordinates."""
    index, ref = b.add_body(body.name, [body.position[0], body.position[1], body.angle],
                            [body.velocity[0], body.velocity[1], body.angular_velocity],
                            [body.mass, 0.0, 0.0, body.inertia], 0.0)
    b.bodies[body.name] = BodyInfo(body.name, index, ref, body.angle, "rigid")

    def locate(at):
        dofs = -np.ones(6, dtype=np.int64)
        dofs[:3] = ref
        u0 = rotation(body.angle).T @ (np.asarray(at) - body.position)
        return dofs, u0, body.angle

    b.locate[body.name] = locate


def _axis_angle(Xa, Xb):
    """Angle of the direction from ``Xa`` to ``Xb``. For complex nodes (a complex step through
    ``build``) the analytic continuation, so the frame follows the perturbation exactly."""
    dc = Xb - Xa
    d = np.real(dc)
    th0 = float(np.arctan2(d[1], d[0]))
    if np.iscomplexobj(dc):
        th0 = th0 + np.arctan((d[0] * dc[1] - d[1] * dc[0]) / (d[0] * dc[0] + d[1] * dc[1]))
    return th0


class _FrameJoint(NamedTuple):
    """The rigid connection of two neighbouring frames of a beam (named like a joint)."""

    name: str


class Frame(NamedTuple):
    """One compiled frame of a beam: the DOFs of its reference coordinates ``ref`` (3,), of
    its nodes ``node_dofs`` (n_nodes, 3), the nodes in its frame ``X`` (n_nodes, 2), its
    initial angle and its rows of the elements table."""

    ref: np.ndarray
    node_dofs: np.ndarray
    X: np.ndarray
    angle0: object
    elements: slice


@compiles(Beam)
def compile_beam(body: Beam, b: Builder) -> None:
    """A beam as one linear FFRF body per frame (``docs/frames.md``), neighbours joined at
    their shared node by three rows ``<beam>.frame<f>.x|y|r``; a single frame keeps the
    beam's own name for its DOFs, several are named ``<beam>#<f>``."""
    specs = specs_of(body)
    n_node, n_fr = body.nodes.shape[0], len(specs)
    node_dofs = -np.ones((n_node, 3), dtype=np.int64)
    node_ref = np.zeros((n_node, 3), dtype=np.int64)
    Xc = np.zeros((n_node, 2), dtype=np.result_type(body.nodes, float))
    angle0 = np.zeros(n_node, dtype=object)
    frames = []
    units = b.units[body.name] = beam_units(body, specs, b.dtype)  # kept by the record
    for f, elem in enumerate(_element_arrays(body, specs, b.dtype, units)):
        spec = specs[f]
        name = body.name if n_fr == 1 else f"{body.name}#{f}"
        frame = _compile_frame(body, spec, name, b, elem)
        frames.append(frame)
        last = spec.last if f == n_fr - 1 else spec.last - 1
        rows = slice(spec.first, last + 1)
        node_dofs[rows] = frame.node_dofs[: last + 1 - spec.first]
        node_ref[rows] = frame.ref
        Xc[rows] = frame.X[: last + 1 - spec.first]
        angle0[rows] = frame.angle0
    for f in range(1, n_fr):
        _join(b, _FrameJoint(f"{body.name}.frame{f}"), frames[f - 1], frames[f])
    elements = slice(frames[0].elements.start, frames[-1].elements.stop)
    b.bodies[body.name] = BodyInfo(
        body.name, b.bodies_count - n_fr, frames[0].ref, frames[0].angle0, "beam", node_dofs,
        Xc if n_fr > 1 else frames[0].X, elements, node_ref, np.array(angle0.tolist()),
        np.array([fr.ref for fr in frames], dtype=np.int64), body.frame_offsets)
    offsets = body.frame_offsets

    def locate(at):
        dofs = -np.ones(6, dtype=np.int64)
        k, _ = body.nearest_node(at)
        f = holding_frame(offsets, k)
        fr = frames[f]
        dofs[:3] = fr.ref
        dofs[3:] = fr.node_dofs[k - specs[f].first]
        return dofs, fr.X[k - specs[f].first], fr.angle0

    b.locate[body.name] = locate


def _join(b: Builder, joint, fa: Frame, fb: Frame) -> None:
    """Position and angle of the last node of frame ``fa`` and the first of ``fb`` equal."""
    pa = (np.concatenate([fa.ref, fa.node_dofs[-1]]), fa.X[-1], fa.angle0)
    pb = (np.concatenate([fb.ref, fb.node_dofs[0]]), fb.X[0], fb.angle0)
    b.add_row("rows", ROW_X, joint, "x", pa, pb, 0.0)
    b.add_row("rows", ROW_Y, joint, "y", pa, pb, 0.0)
    b.add_row("rows", ROW_ANGLE, joint, "r", pa, pb, pa[2] - pb[2])


def _frame_nodes(body: Beam, spec) -> tuple:
    """``(o, th0, Xb)``: the origin and angle of a frame of ``body`` and its nodes in it."""
    X = body.nodes[spec.first: spec.last + 1]
    o = body.nodes[spec.origin]
    th0 = _axis_angle(body.nodes[spec.axis[0]], body.nodes[spec.axis[1]])
    return o, th0, (X - o) @ rotation(th0)  # A0^T (X - X_o) for each row


def _compile_frame(body: Beam, spec, name: str, b: Builder, elem: tuple) -> Frame:
    """One frame of ``body``: its body, flexible coordinates and elements (``elem``: their
    arrays, :func:`_element_arrays`)."""
    dt = b.dtype
    o, th0, Xb = _frame_nodes(body, spec)
    scal, IS, I0S, I0IS, Me, Se, Ke, Be = elem
    n_node = Xb.shape[0]
    removed = set(spec.removed)
    keep = np.array([[(spec.first + j, c) not in removed for c in range(3)]
                     for j in range(n_node)])
    nf = int(keep.sum())
    index, ref = b.add_body(name, [o[0], o[1], th0], [0.0, 0.0, 0.0], scal, body.damping,
                            n_flex=nf)
    node_dofs = -np.ones((n_node, 3), dtype=np.int64)
    for j in range(n_node):
        comps = np.flatnonzero(keep[j])
        if comps.size:
            names = [f"{name}.node{spec.first + j}.{('u', 'v', 'phi')[c]}" for c in comps]
            node_dofs[j, comps] = b.add_dofs(names, [0.0] * comps.size, [0.0] * comps.size)
    flat = node_dofs.ravel()
    f0 = b.table("flex").n
    flex_index = -np.ones(flat.shape, dtype=np.int64)
    flex_index[flat >= 0] = f0 + np.arange(nf)
    n_el = n_node - 1
    conn = np.stack([np.arange(n_el), np.arange(1, n_node)], axis=1)
    fi = flex_index.reshape(n_node, 3)
    efd = np.stack([fi[conn[:, 0]], fi[conn[:, 1]]], axis=1).reshape(n_el, 6)
    edofs = np.stack([node_dofs[conn[:, 0]], node_dofs[conn[:, 1]]], axis=1).reshape(n_el, 6)
    fIS, fI0S, fI0IS = _frame_invariants(efd, f0, nf, IS, I0S, I0IS, dt)
    b.table("flex").add(name, count=nf, IS=fIS, I0S=fI0S, I0IS=fI0IS, dof=flat[flat >= 0])
    e0 = b.table("elements").add(name, count=n_el, M=Me, St=Se, K=Ke, B=Be,
                                 body=np.full(n_el, index, dtype=np.int64), fdof=efd,
                                 dofs=edofs)
    return Frame(ref, node_dofs, Xb, th0, slice(e0, e0 + n_el))


def _frame_invariants(efd, f0: int, nf: int, IS, I0S, I0IS, dt) -> tuple:
    """The element invariants summed into the frame's ``nf`` flexible coordinates (the first
    ``f0``; ``efd`` (n_el, 6) each element DOF's coordinate, -1 where removed):
    ``(IS (nf, 2), I0S (nf,), I0IS (nf,))``."""
    fIS = np.zeros((nf, 2), dtype=dt)
    fI0S = np.zeros(nf, dtype=dt)
    fI0IS = np.zeros(nf, dtype=dt)
    m_ok = efd >= 0
    loc = efd - f0
    np.add.at(fIS[:, 0], loc[m_ok], IS[:, 0, :][m_ok])
    np.add.at(fIS[:, 1], loc[m_ok], IS[:, 1, :][m_ok])
    np.add.at(fI0S, loc[m_ok], I0S[m_ok])
    np.add.at(fI0IS, loc[m_ok], I0IS[m_ok])
    return fIS, fI0S, fI0IS


def beam_units(body: Beam, specs: list, dt) -> Units:
    """The element units (:class:`.beam.Units`) of the elements of the frames ``specs`` of
    ``body``, each in its frame, in one stack in the frames' order."""
    ends = [np.asarray(_frame_nodes(body, spec)[2], dtype=dt) for spec in specs]
    return element_units(np.concatenate([X[:-1] for X in ends]),
                         np.concatenate([X[1:] for X in ends]), dt)


def _element_arrays(body: Beam, specs: list, dt, units: Units | None = None) -> list:
    """Invariants, matrices and stress maps of the elements of the frames ``specs`` of
    ``body``, each in its frame, in one stack (:func:`.beam.element_data`); per frame
    ``(scal (4,), IS, I0S, I0IS, M, St, K, B)``. ``units``: the units of all the beam's
    elements (:func:`beam_units`; computed for ``specs`` when None). The units of a real
    geometry serve a complex section too: a float and a complex evaluation of real data agree
    bit for bit (:mod:`.beam`)."""
    if not specs:
        return []
    rows = np.concatenate([np.arange(spec.first, spec.last) for spec in specs])
    u = beam_units(body, specs, dt) if units is None else Units(*(a[rows] for a in units))

    def part(value):  # a section value: a scalar or one per element of the beam
        value = np.asarray(value)
        return (value[rows] if value.ndim == 1 else np.full(rows.shape, value)).astype(dt)

    arrays = element_data(u, part(body.rho * body.area), part(body.E * body.area),
                          part(body.E * body.second_moment), part(body.E), part(body.fibre))
    out, k = [], 0
    for spec in specs:
        n = spec.last - spec.first
        scal, *rest = (a[k:k + n] for a in arrays)
        out.append((scal.sum(axis=0), *rest))
        k += n
    return out


def _element_section(beam, n_el: int) -> np.ndarray:
    """What each element's data are computed from, (5, n_el): ``rho A, E A, E I, E`` and the
    fibre distance (``beam``: a Beam, or any object with its section attributes)."""
    values = (beam.rho * beam.area, beam.E * beam.area, beam.E * beam.second_moment, beam.E,
              beam.fibre)
    out = np.empty((5, n_el), dtype=np.result_type(np.float64, *values))
    for row, v in zip(out, values):
        row[:] = v  # a scalar or one value per element
    return out


def section_blocks(body: Beam, dt, like, starts: dict) -> list:
    """The rows of ``body`` that a new section changes, for a copy of its compile in the
    system ``like`` (:mod:`morphlab.compile.record`) whose rows begin at ``starts[table]``:
    ``[(table, field, first row, values)]`` over the frames holding an element whose section
    changed, each computed as :func:`compile_beam` computes it (each element's data depend on
    its own section and nodes only): the frame's invariants (``bodies.scal``; ``flex.IS, I0S,
    I0IS``) and its elements' matrices and stress maps (``elements.M, St, K, B``). Rows are
    absolute (rows of ``like``'s tables); the other frames' rows are ``like``'s."""
    specs = specs_of(body)
    n_el = body.nodes.shape[0] - 1
    before = SimpleNamespace(**like.record[body.name].inputs)
    changed = np.any(_element_section(body, n_el) != _element_section(before, n_el), axis=0)
    # the frames holding a changed element (frame f holds elements first_f .. first_{f+1} - 1)
    first = np.array([spec.first for spec in specs])
    redo = np.unique(np.searchsorted(first, np.flatnonzero(changed), side="right") - 1).tolist()
    bodies, elements = like.table("bodies"), like.table("elements")
    b0, e0 = starts["bodies"], starts["elements"]
    out = []
    for f, (scal, IS, I0S, I0IS, Me, Se, Ke, Be) in zip(
            redo, _element_arrays(body, [specs[f] for f in redo], dt,
                                  like.record[body.name].units)):
        spec = specs[f]
        f0, f1 = (int(i) for i in bodies.flex[b0 + f])
        efd = elements.fdof[e0 + spec.first:e0 + spec.last]
        out.append(("bodies", "scal", b0 + f, scal[None]))
        for key, value in zip(("IS", "I0S", "I0IS"),
                              _frame_invariants(efd, f0, f1 - f0, IS, I0S, I0IS, dt)):
            out.append(("flex", key, f0, value))
        for key, value in zip(("M", "St", "K", "B"), (Me, Se, Ke, Be)):
            out.append(("elements", key, e0 + spec.first, value))
    return out


def section_rows(body: Beam, dt, like, starts: dict) -> dict:
    """All rows of ``body`` that its section sets, ``{table: {field: values}}``, for a copy
    of its compile in the system ``like`` whose rows begin at ``starts[table]``:
    ``like``'s rows with those of :func:`section_blocks` written over them."""
    specs = specs_of(body)
    n_el = body.nodes.shape[0] - 1
    bodies, flex, elements = (like.table(k) for k in ("bodies", "flex", "elements"))
    b0, x0, e0 = starts["bodies"], starts["flex"], starts["elements"]
    x1 = int(bodies.flex[b0 + len(specs) - 1, 1])

    def rows(table, name, lo, hi):  # like's rows, as a new array of the compile's dtype
        return np.array(getattr(table, name)[lo:hi], dtype=np.result_type(dt, np.float64))

    out = {"bodies": {"scal": rows(bodies, "scal", b0, b0 + len(specs))},
           "flex": {k: rows(flex, k, x0, x1) for k in ("IS", "I0S", "I0IS")},
           "elements": {k: rows(elements, k, e0, e0 + n_el) for k in ("M", "St", "K", "B")}}
    for table, name, row, values in section_blocks(body, dt, like, starts):
        lo = row - starts[table]
        out[table][name][lo:lo + values.shape[0]] = values
    return out


def loaded_elements(b: Builder, beam: Beam, elements):
    """For each element ``k`` of ``elements`` of ``beam``: ``(k, ref (3,), X1, X2, dofs
    (6,))``, the DOFs of the frame that holds it, its end nodes in that frame and its DOFs
    (the element loads: line loads, pressures)."""
    info = b.bodies[beam.name]
    E, B = b.table("elements"), b.table("bodies")
    elem_body = np.concatenate(E.columns["body"])
    elem_dofs = np.concatenate(E.columns["dofs"])
    body_ref = np.concatenate(B.columns["ref"])
    nodes = np.asarray(beam.nodes)
    for k in elements:
        e = info.elements.start + int(k)
        ref = body_ref[elem_body[e]]
        origin = np.array([b.q0[ref[0]], b.q0[ref[1]]])
        At = rotation(b.q0[ref[2]]).T
        yield (int(k), ref, At @ (nodes[k] - origin), At @ (nodes[k + 1] - origin),
               elem_dofs[e])
