"""Compile functions of the bodies: rigid bodies and flexible beams (FFRF).

Each adds the body's reference coordinates ``x, y, theta``, its invariants and, for a beam, its
flexible coordinates and elements to the :class:`~morphlab.compile.builder.Builder`, and tells
the builder how to find a material point of the body (``builder.locate``).
Formulation: ``docs/theory.md`` §2 (body) and §3 (element).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from ..kernels.joints import ROW_ANGLE, ROW_X, ROW_Y
from ..model import Beam, RigidBody
from ..model.frames import holding_frame, specs_of
from . import incremental as inc
from .beam import element_arrays
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
    b.close_body([], None, None, None)
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


@compiles(Beam)
def compile_beam(body: Beam, b: Builder) -> None:
    """A beam as one linear FFRF body per frame (``docs/frames.md``), neighbours joined at
    their shared node by three rows ``<beam>.frame<f>.x|y|r``; a single frame keeps the
    beam's own name for its DOFs, several are named ``<beam>#<f>``. With a record of the
    nominal compile (a perturbed design, :mod:`morphlab.compile.incremental`) only the
    frames whose inputs changed are compiled, the others copied."""
    specs = specs_of(body)
    n_node, n_fr = body.nodes.shape[0], len(specs)
    rec = b.prior.get(body.name) if b.prior is not None else None
    redo = None
    if rec is not None and inc.snapshot(b) == rec.marks[0]:
        redo = inc.changed_frames(body, rec)
    if redo is None:  # every frame compiled
        redo, frames = range(n_fr), [None] * n_fr
        node_dofs = -np.ones((n_node, 3), dtype=np.int64)
        node_ref = np.zeros((n_node, 3), dtype=np.int64)
        Xc = np.zeros((n_node, 2), dtype=np.result_type(body.nodes, float))
        angle0 = np.zeros(n_node, dtype=object)
        rec = None
    else:  # the nominal's frames and node tables, the changed frames' entries replaced
        frames = list(rec.frames)
        node_dofs, node_ref = rec.info.node_dofs.copy(), rec.info.node_ref.copy()
        X0 = rec.info.X if n_fr > 1 else rec.frames[0][2]
        Xc = np.array(X0, dtype=np.result_type(body.nodes, float))
        angle0 = np.array(rec.info.node_angle0, dtype=object)
    marks = [inc.snapshot(b)] if b.record is not None else None
    done = 0
    arrays = _element_arrays(body, [specs[f] for f in redo], b.dtype)
    sections = ()
    if (rec is not None and len(redo) and marks is None and not inc.nodes_changed(body, rec)
            and inc.one_entry_per_frame(rec, redo)):
        # only section values changed: every entry copied, the changed frames' numbers
        # replaced after (_rewrite_sections); the DOFs, elements and joints are the nominal's
        sections, redo, arrays = (redo, arrays), (), []
    for f, elem in zip(redo, arrays):
        if rec is not None:
            inc.extend_from(b, rec.builder, rec.marks[done], rec.marks[f])
        spec = specs[f]
        name = body.name if n_fr == 1 else f"{body.name}#{f}"
        frames[f] = frame = _compile_frame(body, spec, name, b, elem)
        done = f + 1
        if marks is not None:
            marks.append(inc.snapshot(b))
        ref, nd, Xb, th0, _ = frame
        last = spec.last if f == n_fr - 1 else spec.last - 1
        rows = slice(spec.first, last + 1)
        node_dofs[rows] = nd[: last + 1 - spec.first]
        node_ref[rows] = ref
        Xc[rows] = Xb[: last + 1 - spec.first]
        angle0[rows] = th0
    if rec is not None:
        inc.extend_from(b, rec.builder, rec.marks[done], rec.marks[n_fr])
    _join_frames(body, b, frames, rec, redo, marks)
    if sections:
        _rewrite_sections(b, rec, *sections)
    index = b.bodies_count - len(frames)
    offsets = body.frame_offsets
    elements = slice(frames[0][4].start, frames[-1][4].stop)
    if rec is not None and np.iscomplexobj(body.nodes):  # complex, as from complex nodes
        ref, nd, Xb, th0, rows = frames[0]
        frames[0] = (ref, nd, Xb.astype(np.complex128), np.complex128(th0), rows)
        angle0 = angle0.astype(np.complex128)
    b.bodies[body.name] = info = BodyInfo(
        body.name, index, frames[0][0], frames[0][3], "beam", node_dofs,
        Xc if len(frames) > 1 else frames[0][2], elements, node_ref,
        np.array(angle0.tolist()), np.array([fr[0] for fr in frames], dtype=np.int64), offsets)
    if b.record is not None:
        inc.record_beam(b, body, specs, frames, marks, info)

    def locate(at):
        dofs = -np.ones(6, dtype=np.int64)
        k, _ = body.nearest_node(at)
        f = holding_frame(offsets, k)
        ref, nd, Xb, th0, _ = frames[f]
        dofs[:3] = ref
        dofs[3:] = nd[k - specs[f].first]
        return dofs, Xb[k - specs[f].first], th0

    b.locate[body.name] = locate


def _join_frames(body: Beam, b: Builder, frames: list, rec, redo, marks) -> None:
    """The rows joining neighbouring frames: all of them, or (with a nominal record ``rec``)
    those next to a recompiled frame, the others copied."""
    n_fr = len(frames)
    joins = range(1, n_fr) if rec is None else sorted(
        {g for f in redo for g in (f, f + 1) if 1 <= g < n_fr})
    done = 1
    for f in joins:
        if rec is not None:
            inc.extend_from(b, rec.builder, rec.marks[n_fr + done - 1], rec.marks[n_fr + f - 1])
        _join(b, _FrameJoint(f"{body.name}.frame{f}"), frames[f - 1], frames[f])
        done = f + 1
        if marks is not None:
            marks.append(inc.snapshot(b))
    if rec is not None:
        inc.extend_from(b, rec.builder, rec.marks[n_fr + done - 1], rec.marks[2 * n_fr - 1])


def _join(b: Builder, joint, fa, fb) -> None:
    """Position and angle of the last node of frame ``fa`` and the first of ``fb`` equal."""
    pa = (np.concatenate([fa[0], fa[1][-1]]), fa[2][-1], fa[3])
    pb = (np.concatenate([fb[0], fb[1][0]]), fb[2][0], fb[3])
    b.add_row(ROW_X, joint, "x", pa, pb, 0.0)
    b.add_row(ROW_Y, joint, "y", pa, pb, 0.0)
    b.add_row(ROW_ANGLE, joint, "r", pa, pb, pa[2] - pb[2])


def _frame_nodes(body: Beam, spec) -> tuple:
    """``(o, th0, Xb)``: the origin and angle of a frame of ``body`` and its nodes in it."""
    X = body.nodes[spec.first: spec.last + 1]
    o = body.nodes[spec.origin]
    th0 = _axis_angle(body.nodes[spec.axis[0]], body.nodes[spec.axis[1]])
    return o, th0, (X - o) @ rotation(th0)  # A0^T (X - X_o) for each row


def _compile_frame(body: Beam, spec, name: str, b: Builder, elem: tuple):
    """One frame of ``body``: its body, flexible coordinates and elements (``elem``: their
    arrays, :func:`_element_arrays`).

    Returns ``(ref (3,), node_dofs (n_group_nodes, 3), Xb (n_group_nodes, 2), angle0,
    element rows)``."""
    dt = b.dtype
    o, th0, Xb = _frame_nodes(body, spec)
    index, ref = b.add_body(name, [o[0], o[1], th0], [0.0, 0.0, 0.0],
                            np.zeros(4, dtype=dt), body.damping)
    n_node = Xb.shape[0]
    removed = set(spec.removed)
    node_dofs = -np.ones((n_node, 3), dtype=np.int64)
    for j in range(n_node):
        k = spec.first + j
        comps = [c for c in range(3) if (k, c) not in removed]
        if comps:
            names = [f"{name}.node{k}.{('u', 'v', 'phi')[c]}" for c in comps]
            node_dofs[j, comps] = b.add_dofs(names, [0.0] * len(comps), [0.0] * len(comps))
    flat = node_dofs.ravel()
    keep = flat >= 0
    nf = int(keep.sum())
    f0 = b.flex_off[-1]
    flex_index = -np.ones(flat.shape, dtype=np.int64)
    flex_index[keep] = f0 + np.arange(nf)
    n_el = n_node - 1
    conn = np.stack([np.arange(n_el), np.arange(1, n_node)], axis=1).astype(np.int64)
    scal, IS, I0S, I0IS, Me, Se, Ke, Be = elem
    b.body_scal[index] = list(scal)
    efd = np.stack([flex_index.reshape(n_node, 3)[conn[:, 0]],
                    flex_index.reshape(n_node, 3)[conn[:, 1]]], axis=1).reshape(n_el, 6)
    edofs = np.stack([node_dofs[conn[:, 0]], node_dofs[conn[:, 1]]], axis=1).reshape(n_el, 6)
    b.close_body(flat[keep], *_frame_invariants(efd, f0, nf, IS, I0S, I0IS, dt))
    elements = b.add_elements(index, efd, edofs, Me, Se, Ke, Be)
    return ref, node_dofs, Xb, th0, elements


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


def _rewrite_sections(b: Builder, rec, redo, arrays) -> None:
    """The frames ``redo`` of a beam whose nodes are the nominal's (``rec``) and whose section
    values are not: their entries were copied with the rest of the beam; their numbers
    (``arrays``, :func:`_element_arrays`) replace the copies (``incremental.rewrite``)."""
    for f, (scal, IS, I0S, I0IS, Me, Se, Ke, Be) in zip(redo, arrays):
        efd = rec.builder.elem["fdof"][inc.frame_start(rec, f, "elem", "fdof")]
        offsets, i = rec.builder.flex_off, inc.frame_start(rec, f, "flex_off")
        f0 = offsets[i - 1]  # the frame's first flexible coordinate (close_body appends)
        sums = _frame_invariants(efd, f0, offsets[i] - f0, IS, I0S, I0IS, b.dtype)
        inc.rewrite(b, rec, f, {("body_scal", None): list(scal), ("flex", "IS"): sums[0],
                                ("flex", "I0S"): sums[1], ("flex", "I0IS"): sums[2],
                                ("elem", "M"): Me, ("elem", "St"): Se, ("elem", "K"): Ke,
                                ("elem", "B"): Be})


def _element_arrays(body: Beam, specs: list, dt) -> list:
    """Invariants, matrices and stress maps of the elements of the frames ``specs`` of
    ``body``, each in its frame, in one stack (:func:`.beam.element_arrays`: the same bits as
    frame by frame, at a fraction of the cost for one frame per element); per frame
    ``(scal (4,), IS, I0S, I0IS, M, St, K, B)``."""
    if not specs:
        return []
    ends, rows = [], []
    for spec in specs:
        Xb = np.asarray(_frame_nodes(body, spec)[2], dtype=dt)
        ends.append((Xb[:-1], Xb[1:]))
        rows.append(np.arange(spec.first, spec.last))
    rows = np.concatenate(rows)

    def part(value):  # a section value: a scalar or one per element of the beam
        value = np.asarray(value)
        return (value[rows] if value.ndim == 1 else np.full(rows.shape, value)).astype(dt)

    arrays = element_arrays(np.concatenate([e[0] for e in ends]),
                            np.concatenate([e[1] for e in ends]),
                            part(body.rho * body.area), part(body.E * body.area),
                            part(body.E * body.second_moment), part(body.E), part(body.fibre),
                            dt)
    out, k = [], 0
    for spec in specs:
        n = spec.last - spec.first
        scal, *rest = (a[k:k + n] for a in arrays)
        out.append((scal.sum(axis=0), *rest))
        k += n
    return out
