"""Small models shared by the tests (each builds in milliseconds)."""

import numpy as np

import morphlab as ml

# aluminium-like strip in mm, t, s, N, MPa
E_AL = 70000.0
RHO_AL = 2.7e-9


def straight_nodes(n_elem, length=100.0, angle=0.0, origin=(0.0, 0.0)):
    s = np.linspace(0.0, length, n_elem + 1)
    return np.stack([origin[0] + s * np.cos(angle), origin[1] + s * np.sin(angle)], axis=1)


def flexible_mechanism(gravity=(0.0, -9.81e3), n_elem=6, **frames):
    """A closed loop: rigid crank on ground, flexible coupler beam, rigid rocker; plus a weld,
    a point force and a torque, so every kernel contributes. ``frames``: the coupler's frame
    arguments (``frames``, ``reference``, ``reference_node``; default one chord frame per
    element)."""
    m = ml.Model(gravity=gravity, name="four-bar")
    crank = m.add_rigid_body(mass=2e-4, inertia=0.2, position=(0.0, 10.0), angle=np.pi / 2,
                             name="crank")
    nodes = straight_nodes(n_elem, length=60.0, origin=(0.0, 20.0), angle=0.1)
    coupler = m.add_beam(nodes, E=E_AL, rho=RHO_AL, thickness=2.0, width=10.0,
                         damping=1e-4, name="coupler", **frames)
    end = nodes[-1]
    rocker = m.add_rigid_body(mass=3e-4, inertia=0.3, position=(end[0], end[1] / 2),
                              angle=np.pi / 2, name="rocker")
    m.add_revolute(m.ground, crank, at=(0.0, 0.0), name="A")
    m.add_revolute(crank, coupler, at=(0.0, 20.0), name="B")
    m.add_revolute(coupler, rocker, at=tuple(end), name="C")
    m.add_revolute(rocker, m.ground, at=(end[0], 0.0), name="D")
    m.add_torque(crank, 50.0, profile=ml.SmoothStep(0.0, 0.05), name="Mt")
    # ramped, not suddenly applied: a point load switched on at t = 0 gives the consistent-mass
    # beam an initial acceleration ~F/m_node (~1e7 mm/s^2) that no step size resolves
    m.add_force(coupler, at=tuple(nodes[n_elem // 2]), force=(0.0, -2.0),
                profile=ml.SmoothStep(0.0, 0.05), name="F")
    return m


def tip_loaded_cantilever(p, n_elem=4, length=100.0, frames="element"):
    """Aluminium strip (width 10 mm, thickness ``p["t"]`` [mm]) clamped at x = 0, a tip force
    ``-p["F"]`` [N] in y switched on smoothly over 4 ms, no gravity: the design model of the
    optimization and uncertainty tests (first bending period about 6 ms at t = 2 mm).
    ``frames``: the beam's floating frames (1: one linear frame held at the clamp)."""
    m = ml.Model(gravity=(0.0, 0.0), name="cantilever")
    beam = m.add_beam(straight_nodes(n_elem, length), E=E_AL, rho=RHO_AL, thickness=p["t"],
                      width=10.0, damping=1e-4, frames=frames,
                      reference="first" if frames == 1 else "chord", name="beam")
    m.add_fix(beam, at=(0.0, 0.0), dofs="xyr", name="clamp")
    m.add_force(beam, at=(length, 0.0), force=(0.0, -p["F"]), profile=ml.SmoothStep(0.0, 4e-3),
                name="F")
    return m
