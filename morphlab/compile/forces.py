"""Compile functions of the force elements: spring-dampers (``kernels.forces``) and line loads
(``kernels.loads``). Formulation: ``docs/theory.md`` §4.6."""

from __future__ import annotations

import numpy as np

from ..errors import ModelError
from ..kernels.forces import SPRING_ANGLE, SPRING_LENGTH
from ..model import Ground, RigidBody
from ..model.forces import LineLoad, RotationalSpring, Spring
from .bodies import loaded_elements
from .builder import Builder, compiles


def _end(b: Builder, body, at):
    """``(dofs, u0, angle0)`` of a spring end; a ground end's point is its global position."""
    if isinstance(body, Ground):
        return -np.ones(6, dtype=np.int64), np.asarray(at, dtype=b.dtype), 0.0
    return b.point(body, at)


@compiles(Spring)
def compile_spring(sp: Spring, b: Builder) -> None:
    """A translational spring-damper: its ends and ``(k, c, l0, f0)``, ``l0`` the initial
    distance unless given (complex-safe: it follows a perturbed geometry)."""
    pa, pb = _end(b, sp.a, sp.at_a), _end(b, sp.b, sp.at_b)
    d = np.asarray(sp.at_a) - np.asarray(sp.at_b)
    length = np.sqrt(d[0] * d[0] + d[1] * d[1])
    if not np.real(length) > 0:
        raise ModelError(f"spring {sp.name!r}: its two points coincide in the initial "
                         "configuration, where the direction of its force is undefined")
    rest = length if sp.rest_length is None else sp.rest_length
    u0 = np.stack([np.asarray(pa[1], dtype=b.dtype), np.asarray(pb[1], dtype=b.dtype)])
    b.table("springs").add(sp.name, u0=u0, par=[sp.stiffness, sp.damping, rest, sp.preload],
                           kind=SPRING_LENGTH, dofs=np.stack([pa[0], pb[0]]))


@compiles(RotationalSpring)
def compile_rotational_spring(sp: RotationalSpring, b: Builder) -> None:
    """A torsion spring-damper on ``(theta_a + phi_a) - (theta_b + phi_b)``: relaxed at its
    initial value (the frames' initial angles) plus ``rest_angle``."""
    ends = []
    for body, at in ((sp.a, sp.at_a), (sp.b, sp.at_b)):
        if isinstance(body, RigidBody) and at is None:
            at = body.position
        ends.append(_end(b, body, at if at is not None else (0.0, 0.0)))
    pa, pb = ends
    rest = pa[2] - pb[2] + sp.rest_angle
    b.table("springs").add(sp.name, u0=np.zeros((2, 2), dtype=b.dtype),
                           par=[sp.stiffness, sp.damping, rest, sp.preload], kind=SPRING_ANGLE,
                           dofs=np.stack([pa[0], pb[0]]))


def line_integrals(X1, X2):
    """``(int ds, int u0 ds)`` (3,) and ``int S_e ds`` (2, 6) of the element ``X1 -> X2``
    (body frame): with ``int (1 - xi) = int xi = int H1 = int H3 = 1/2``,
    ``int H2 = 1/12``, ``int H4 = -1/12`` (``docs/theory.md`` §3.1), complex-safe."""
    dx, dy = X2[0] - X1[0], X2[1] - X1[1]
    L = np.sqrt(dx * dx + dy * dy)
    c, s = dx / L, dy / L
    u0 = np.array([L, L * (X1[0] + X2[0]) / 2, L * (X1[1] + X2[1]) / 2])
    h = L / 12
    N = L * np.array([[0.5, 0.0, -s * h, 0.5, 0.0, s * h],
                      [0.0, 0.5, c * h, 0.0, 0.5, -c * h]])
    return u0, N


@compiles(LineLoad)
def compile_line_load(ld: LineLoad, b: Builder) -> None:
    """A line load: one entry of the ``lines`` table per loaded element, with the element's
    integrals in the frame that holds it."""
    for _, ref, X1, X2, dofs in loaded_elements(b, ld.beam, ld.elements):
        u0, N = line_integrals(X1, X2)
        b.table("lines").add(ld.name, base=np.asarray(ld.q), profile=ld.profile,
                             u0=u0.astype(b.dtype), N=N.astype(b.dtype), ref=ref, dofs=dofs)
