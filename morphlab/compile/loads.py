"""Compile functions of the loads: point forces, torques, follower forces and pressures."""

from __future__ import annotations

import numpy as np

from ..model import Beam, Force, Torque
from ..model.frames import drive_node
from ..model.pressure import FollowerForce, Pressure
from .beam import GAUSS_W, GAUSS_XI, element_geometry, shape_matrix
from .bodies import loaded_elements
from .builder import Builder, compiles


@compiles(Force)
def compile_force(f: Force, b: Builder) -> None:
    """A force of fixed global direction at a material point."""
    dofs, u0, _ = b.point(f.body, f.at)
    b.table("loads").add(f.name, base=np.asarray(f.force), profile=f.profile, u0=u0, dofs=dofs)


@compiles(Torque)
def compile_torque(t: Torque, b: Builder) -> None:
    """A torque on a body's angle (and on the nodal rotation of the beam node at ``at``)."""
    info = b.bodies[t.body.name]
    dofs = np.array([info.ref[2], -1], dtype=np.int64)
    if isinstance(t.body, Beam):  # without ``at``: the drive node (docs/frames.md)
        k = t.body.nearest_node(t.at)[0] if t.at is not None else drive_node(t.body)
        dofs[:] = info.node_ref[k, 2], info.node_dofs[k, 2]
    b.table("torques").add(t.name, base=t.magnitude, profile=t.profile, dofs=dofs)


def _shape_derivative(xi, L, c, s):
    """``dS_e/dxi`` (2, 6) of the element at ``xi`` (derivative of
    :func:`~morphlab.compile.beam.shape_matrix`; complex-safe)."""
    dax = (-1.0, 1.0)
    dtr = (-6.0 * xi + 6.0 * xi * xi, 6.0 * xi - 6.0 * xi * xi)
    drot = ((1.0 - 4.0 * xi + 3.0 * xi * xi) * L, (3.0 * xi * xi - 2.0 * xi) * L)
    dS = np.zeros((2, 6), dtype=np.result_type(L, c, s))
    for node in range(2):
        na, hv, hr, j = dax[node], dtr[node], drot[node], 3 * node
        dS[0, j] = c * na * c + s * hv * s
        dS[0, j + 1] = c * na * s - s * hv * c
        dS[0, j + 2] = -s * hr
        dS[1, j] = s * na * c - c * hv * s
        dS[1, j + 1] = s * na * s + c * hv * c
        dS[1, j + 2] = c * hr
    return dS


def pressure_integrals(X1, X2) -> dict:
    """The integrals ``c, D, e, f, H, g, G`` (each with a leading node axis of 2) of a pressure
    on the element ``X1 -> X2`` (body frame), :mod:`morphlab.kernels.pressure`. The 4-point
    Gauss rule integrates them exactly (``N_a S^T S'``: degree 6). In ``xi``: ``ds = L dxi``,
    ``u0' = (X2 - X1) / L``, ``S' = (dS/dxi) / L``; complex-safe."""
    X1, X2 = np.asarray(X1), np.asarray(X2)
    L, c, s = element_geometry(X1, X2)
    dX = X2 - X1
    It = np.array([[0.0, -1.0], [1.0, 0.0]])
    dt = np.result_type(X1, X2, float)
    out = {"c": np.zeros((2, 2), dt), "D": np.zeros((2, 2, 6), dt), "e": np.zeros(2, dt),
           "f": np.zeros((2, 6), dt), "H": np.zeros((2, 6, 6), dt), "g": np.zeros((2, 6), dt),
           "G": np.zeros((2, 6, 6), dt)}
    S = np.zeros((2, 6), dtype=dt)
    for xi, w in zip(GAUSS_XI, GAUSS_W):
        shape_matrix(xi, L, c, s, S)
        dS = _shape_derivative(xi, L, c, s)
        u0 = X1 + xi * dX
        for a, Na in enumerate((1.0 - xi, xi)):
            wa = w * Na
            out["c"][a] += wa * dX
            out["D"][a] += wa * dS
            out["e"][a] += wa * (u0 @ dX)
            out["f"][a] += wa * (S.T @ dX + dS.T @ u0)
            out["H"][a] += wa * (S.T @ dS)
            out["g"][a] += wa * (S.T @ (It @ dX))
            out["G"][a] += wa * (S.T @ It @ dS)
    return out


@compiles(Pressure)
def compile_pressure(pr: Pressure, b: Builder) -> None:
    """A pressure: one entry of the ``pressures`` table per loaded element, with the
    element's integrals in the frame that holds it and ``P = p width`` at its two nodes."""
    for k, ref, X1, X2, dofs in loaded_elements(b, pr.beam, pr.elements):
        integrals = pressure_integrals(X1, X2)
        P = np.array([pr.p[k], pr.p[k + 1]]) * pr.width[k]
        b.table("pressures").add(pr.name, base=P, profile=pr.profile, ref=ref, dofs=dofs,
                                 **{n: v.astype(b.dtype) for n, v in integrals.items()})


@compiles(FollowerForce)
def compile_follower(f: FollowerForce, b: Builder) -> None:
    """A force that turns with the material point: its point, DOFs and initial rotation."""
    dofs, u0, angle0 = b.point(f.body, f.at)
    b.table("followers").add(f.name, base=np.asarray(f.force), profile=f.profile, u0=u0,
                             psi0=angle0, dofs=dofs)
