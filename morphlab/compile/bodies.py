"""Compile functions of the bodies: rigid bodies and flexible beams (FFRF).

Each adds the body's reference coordinates ``x, y, theta``, its invariants and, for a beam, its
flexible coordinates and elements to the :class:`~morphlab.compile.builder.Builder`, and tells
the builder how to find a material point of the body (``builder.locate``).
Formulation: ``docs/theory.md`` §2 (body) and §3 (element).
"""

from __future__ import annotations

import numpy as np

from ..kernels import beam as kbeam
from ..model.model import Beam, RigidBody
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


def _frame_angle(X, r):
    """Angle of the tangent frame at node ``r``: along the element that starts there (the one
    that ends there for the last node). For complex nodes (a complex step through ``build``)
    the analytic continuation, so the frame follows the perturbation exactly."""
    nb = r + 1 if r < X.shape[0] - 1 else r - 1
    dc = X[max(r, nb)] - X[min(r, nb)]
    d = np.real(dc)
    th0 = float(np.arctan2(d[1], d[0]))
    if np.iscomplexobj(dc):
        th0 = th0 + np.arctan((d[0] * dc[1] - d[1] * dc[0]) / (d[0] * dc[0] + d[1] * dc[1]))
    return th0


@compiles(Beam)
def compile_beam(body: Beam, b: Builder) -> None:
    """One FFRF body: frame at the reference node (its deformation DOFs removed), x axis along
    its element; the element invariants summed into the body's flexible coordinates."""
    dt = b.dtype
    X = body.nodes
    r = body.reference_node
    n_node = X.shape[0]
    th0 = _frame_angle(X, r)
    Xb = (X - X[r]) @ rotation(th0)  # A0^T (X - X_r) for each row
    index, ref = b.add_body(body.name, [X[r][0], X[r][1], th0], [0.0, 0.0, 0.0],
                            np.zeros(4, dtype=dt), body.damping)
    node_dofs = -np.ones((n_node, 3), dtype=np.int64)
    for k in range(n_node):
        if k != r:
            names = [f"{body.name}.node{k}.{lab}" for lab in ("u", "v", "phi")]
            node_dofs[k] = b.add_dofs(names, [0.0] * 3, [0.0] * 3)
    flat = node_dofs.ravel()
    keep = flat >= 0
    nf = int(keep.sum())
    f0 = b.flex_off[-1]
    flex_index = -np.ones(flat.shape, dtype=np.int64)
    flex_index[keep] = f0 + np.arange(nf)
    n_el = n_node - 1
    conn = np.stack([np.arange(n_el), np.arange(1, n_node)], axis=1).astype(np.int64)
    scal, IS, I0S, I0IS, Me, Se, Ke, Be = _element_arrays(body, Xb, conn, dt)
    b.body_scal[index] = list(scal)
    efd = np.stack([flex_index.reshape(n_node, 3)[conn[:, 0]],
                    flex_index.reshape(n_node, 3)[conn[:, 1]]], axis=1).reshape(n_el, 6)
    edofs = np.stack([node_dofs[conn[:, 0]], node_dofs[conn[:, 1]]], axis=1).reshape(n_el, 6)
    # sum element invariants into the body's flexible coordinates
    fIS = np.zeros((nf, 2), dtype=dt)
    fI0S = np.zeros(nf, dtype=dt)
    fI0IS = np.zeros(nf, dtype=dt)
    m_ok = efd >= 0
    loc = efd - f0
    np.add.at(fIS[:, 0], loc[m_ok], IS[:, 0, :][m_ok])
    np.add.at(fIS[:, 1], loc[m_ok], IS[:, 1, :][m_ok])
    np.add.at(fI0S, loc[m_ok], I0S[m_ok])
    np.add.at(fI0IS, loc[m_ok], I0IS[m_ok])
    b.close_body(flat[keep], fIS, fI0S, fI0IS)
    elements = b.add_elements(index, efd, edofs, Me, Se, Ke, Be)
    b.bodies[body.name] = BodyInfo(body.name, index, ref, th0, "beam", node_dofs, Xb, elements)

    def locate(at):
        dofs = -np.ones(6, dtype=np.int64)
        dofs[:3] = ref
        k, _ = body.nearest_node(at)
        dofs[3:] = node_dofs[k]
        return dofs, Xb[k], th0

    b.locate[body.name] = locate


def _element_arrays(body: Beam, Xb, conn, dt):
    """Invariants, matrices and stress maps of every element of ``body`` (nodes ``Xb`` in the
    body frame): ``(scal (4,), IS, I0S, I0IS, M, St, K, B)`` (kernels.beam)."""
    n_el = conn.shape[0]
    ones = np.ones(n_el, dtype=dt)
    scal = np.zeros(4, dtype=dt)
    IS = np.zeros((n_el, 2, 6), dtype=dt)
    I0S = np.zeros((n_el, 6), dtype=dt)
    I0IS = np.zeros((n_el, 6), dtype=dt)
    Me = np.zeros((n_el, 6, 6), dtype=dt)
    Se = np.zeros((n_el, 6, 6), dtype=dt)
    Ke = np.zeros((n_el, 6, 6), dtype=dt)
    Be = np.zeros((n_el, 2, 2, 6), dtype=dt)
    kbeam.beam_element_arrays(
        np.ascontiguousarray(Xb, dtype=dt), conn,
        ones * (body.rho * body.area), ones * (body.E * body.area),
        ones * (body.E * body.second_moment), ones * body.E, ones * body.fibre,
        scal, IS, I0S, I0IS, Me, Se, Ke, Be,
    )
    return scal, IS, I0S, I0IS, Me, Se, Ke, Be
