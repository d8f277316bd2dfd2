"""Follower loads (``morphlab.kernels.pressure``, docs/theory.md §4.7): a pressure normal to
the deformed beam and a point force that turns with the body.

Each is checked against something independent: the Newton-matrix terms against complex-step
columns of the step residual; a ring's buckling under external pressure against the closed
forms of the follower (3EI/R³) and the dead (4EI/R³) load, at order 2 in the element size; a
ring's radial expansion under internal pressure against membrane theory; Beck's column (a
cantilever under a tangential follower force) fluttering at 20.05 EI/L², against its dead-load
twin that buckles at the Euler load, in an eigenvalue analysis and in a dynamic run; the work
of the pressure on a closed ring against the pressure times the change of the enclosed area;
the sensitivities by the direct and adjoint methods against the whole-run complex step.
"""

import numpy as np
import pytest
import scipy.linalg as sla
import scipy.sparse as sp
from models import (
    E_AL,
    RHO_AL,
    check_gradients_by_complex_step,
    check_step_matrix_by_complex_step,
    straight_nodes,
)

import morphlab as ml
from morphlab.compile.system import time_table
from morphlab.kernels.assemble import matrix
from morphlab.kernels.ffrf import scratch
from morphlab.kernels.types import Level, Weights

E, RHO, B = 70000.0, 2.7e-9, 10.0  # MPa, t/mm^3, mm (width)


# ------------------------------------------------------------------ Newton-matrix terms
def _loaded_models():
    """A two-frame pendulum beam with a pressure varying along it on some elements and a
    follower force at its tip; a rigid body with a follower force (no nodal rotation)."""
    m = ml.Model(gravity=(0.0, -9.81e3), name="pressure")
    nodes = straight_nodes(4, length=80.0, angle=0.3)
    beam = m.add_beam(nodes, E=E_AL, rho=RHO_AL, thickness=2.0, width=10.0, frames=2,
                      name="beam")
    m.add_revolute(m.ground, beam, at=(0.0, 0.0), name="pin")
    m.add_pressure("p", beam, lambda xy: 0.01 + 1e-4 * xy[:, 0], elements=[0, 2, 3])
    m.add_force(beam, at=tuple(nodes[4]), force=(0.3, -0.2), follower=True, name="f")
    m2 = ml.Model(name="rigid follower")
    body = m2.add_rigid_body(mass=1e-4, inertia=0.1, position=(30.0, 40.0), angle=0.2,
                             name="body")
    m2.add_revolute(m2.ground, body, at=(0.0, 0.0), name="pin")
    m2.add_force(body, at=(35.0, 45.0), force=(1.0, 0.5), follower=True, name="f")
    return [m, m2]


@pytest.mark.parametrize("model", _loaded_models(), ids=lambda m: m.name)
def test_newton_matrix_is_the_complex_step_of_the_residual(model):
    """Every column of the step matrix (and of its split D0, Dq, Dv) equals the complex-step
    derivative of the step residual, to 1e-9 of the column's largest entry (h = 1e-30: round-
    off only), at a random state: the load stiffness of the pressure (not symmetric) and of the
    follower force are exact."""
    check_step_matrix_by_complex_step(model, seed=11)


# ------------------------------------------------------------------ tangent analysis
def _blocks(system, q, lam):
    """Mass and tangent stiffness (the residual's derivatives along a and q at ``q, lam``,
    zero velocity) reduced to the null space of the constraint Jacobian."""
    n_dof = system.n_dof
    z = np.zeros(n_dof)
    data = np.zeros((3, system.nnz))
    w = Weights(1.0, 1.0, 1.0, 1.0, 1.0, 1.0, 1.0, 0.0)
    matrix(system.arrays, Level(q, z, z, lam), w, time_table(system, np.array([1.0])), 0, 0,
           np.eye(3), data, scratch(system.count("flex"), z))

    def dense(d):
        return sp.csc_matrix((d, system.indices, system.indptr),
                             shape=(system.n, system.n)).toarray()[:n_dof, :n_dof]

    J = system.constraint_matrix(q)
    Z = sla.null_space(J.toarray() if hasattr(J, "toarray") else J)
    return Z.T @ dense(data[0]) @ Z, Z.T @ dense(data[1]) @ Z


def _equilibrium(model, steps=2):
    system = ml.compile_model(model)
    res = ml.static(system, steps=steps, t=1.0)
    return system, res.q[-1], res.lam[-1]


def _bisect(unstable, lo, hi, tol=1e-4):
    """The smallest load factor in [lo, hi] where ``unstable`` turns True (one change)."""
    assert not unstable(lo) and unstable(hi), (lo, hi)
    while hi - lo > tol:
        mid = 0.5 * (lo + hi)
        lo, hi = (lo, mid) if unstable(mid) else (mid, hi)
    return 0.5 * (lo + hi)


# ------------------------------------------------------------------ ring
R_RING, T_RING = 100.0, 1.0
EI_RING = E * B * T_RING**3 / 12.0


def ring(n, p, follower=True):
    """A ring of radius 100 mm (two half rings welded at the top and bottom), numbered
    counter-clockwise, under a uniform pressure ``p`` (positive: inwards) as a follower
    pressure or as dead loads of the same size (each element's force ``p b L`` along its
    initial inward normal). Held by symmetry: at (R, 0) and (-R, 0) in y and rotation, at
    (0, ±R) in x and rotation, which the doubly symmetric ovalization mode (n = 2) satisfies
    and which rule out rigid motions (a dead-loaded free ring is unstable in rotation)."""
    m = ml.Model(name="ring")
    half = n // 2
    arcs = (np.linspace(-np.pi / 2, np.pi / 2, half + 1),
            np.linspace(np.pi / 2, 3 * np.pi / 2, half + 1))
    beams = [m.add_beam(np.stack([R_RING * np.cos(a), R_RING * np.sin(a)], axis=1), E=E,
                        rho=RHO, thickness=T_RING, width=B, name=name)
             for a, name in zip(arcs, "ab")]
    a, b = beams
    m.add_weld(a, b, at=(0.0, R_RING), name="top")
    m.add_weld(b, a, at=(0.0, -R_RING), name="bottom")
    m.add_fix(a, at=(R_RING, 0.0), dofs="yr", name="right")
    m.add_fix(b, at=(-R_RING, 0.0), dofs="yr", name="left")
    m.add_fix(a, at=(0.0, R_RING), dofs="xr", name="up")
    m.add_fix(a, at=(0.0, -R_RING), dofs="xr", name="down")
    for beam, arc in zip(beams, arcs):
        if follower:
            m.add_pressure(f"p{beam.name}", beam, p)
            continue
        for k in range(half):
            mid = 0.5 * (arc[k] + arc[k + 1])
            m.add_line_load(f"q{beam.name}{k}", beam, q=-p * B * np.array([np.cos(mid),
                                                                          np.sin(mid)]),
                            elements=[k])
    return m


def ring_buckling_factor(n, follower):
    """The critical pressure of the ring over its closed form (3 or 4 EI/R³ / b): where the
    reduced tangent stiffness at the equilibrium first has an eigenvalue of negative real
    part."""
    ref = (3.0 if follower else 4.0) * EI_RING / R_RING**3 / B

    def unstable(f):
        system, q, lam = _equilibrium(ring(n, f * ref, follower))
        return np.linalg.eigvals(_blocks(system, q, lam)[1]).real.min() < 0.0

    return _bisect(unstable, 0.9, 1.1)


@pytest.mark.parametrize("follower", [True, False], ids=["follower", "dead"])
def test_ring_buckles_at_the_closed_form_of_its_load(follower):
    """External pressure on a ring: the follower pressure buckles it at 3EI/R³ (per unit
    length), dead loads of the same size at 4EI/R³ (Simitses & Hodges, Fundamentals of
    Structural Stability, §7: (n² - 1) EI/R³ and n² EI/R³ for the ovalization n = 2). With 48
    straight elements within 1.5 % (measured follower +0.8 %, dead +1.0 %); the error falls at
    order 2 with the element size (ratio 24 -> 48 elements >= 3: measured ~3.8). The two
    closed forms are 33 % apart, so each test tells the loads apart."""
    coarse, fine = (ring_buckling_factor(n, follower) for n in (24, 48))
    assert abs(fine - 1.0) <= 0.015
    assert abs(coarse - 1.0) / abs(fine - 1.0) >= 3.0


def test_internal_pressure_expands_a_ring_by_the_membrane_solution():
    """A uniform internal pressure (negative: outwards on the counter-clockwise ring) expands
    it uniformly: thin-ring membrane theory gives the strain e = p b R / EA. The 48 straight
    elements form a polygon inscribed in the ring; at each node the two chords' loads (p b
    times the deformed chord) and the chord forces N balance, N = p b R (1 + e) cos(pi/48),
    so e = a / (1 - a) with a = p b R cos(pi/48) / EA exactly for the polygon: asserted to
    1e-6 (the Newton tolerance and round-off), and within 0.25 % of the ring's closed form
    (the polygon's cos(pi/48) = 1 - 2.1e-3)."""
    p = -0.05
    n = 48
    system = ml.compile_model(ring(n, p))
    res = ml.static(system, steps=2, t=1.0)
    radii = np.concatenate([np.hypot(*res.node_positions(name)[-1].T) for name in "ab"])
    strain = radii / R_RING - 1.0
    EA = E * B * T_RING
    a = -p * B * R_RING * np.cos(np.pi / n) / EA
    np.testing.assert_allclose(strain, a / (1.0 - a), rtol=1e-6)
    np.testing.assert_allclose(strain, -p * B * R_RING / EA, rtol=2.5e-3)


# ------------------------------------------------------------------ Beck's column
L_BECK, T_BECK = 200.0, 2.0
EI_BECK = E * B * T_BECK**3 / 12.0
BECK = 20.05  # Beck (1952): flutter load P L² / EI of the clamped-free follower column
EULER = np.pi**2 / 4.0  # dead-load buckling of the cantilever


def column(n, P, follower):
    """A cantilever along x, clamped at the origin, compressed at its tip by ``P`` [N] (a
    force along -x that turns with the tip, or keeps its direction)."""
    m = ml.Model(name="beck")
    b = m.add_beam(straight_nodes(n, L_BECK), E=E, rho=RHO, thickness=T_BECK, width=B,
                   name="col")
    m.add_fix(b, at=(0.0, 0.0), dofs="xyr", name="clamp")
    m.add_force(b, at=(L_BECK, 0.0), force=(-P, 0.0), follower=follower, name="P")
    return m


def _frequencies_squared(n, factor, follower):
    """The eigenvalues of M^-1 K at the column's equilibrium under ``factor EI/L²``."""
    system, q, lam = _equilibrium(column(n, factor * EI_BECK / L_BECK**2, follower), steps=4)
    M, K = _blocks(system, q, lam)
    return np.linalg.eigvals(np.linalg.solve(M, K))


def test_beck_column_flutters_and_its_dead_twin_buckles():
    """Under a follower tip force the cantilever has no static instability: its two lowest
    frequencies meet and turn complex (flutter) at P = 20.05 EI/L² (Beck); 16 elements
    within 1 % (measured +0.4 %). Under the dead force it buckles at the Euler load
    (pi²/4) EI/L² (an eigenvalue through zero; 16 elements within 0.1 %), where the
    follower column is still stable: the tests tell the two loads apart."""
    flutter = _bisect(lambda f: np.abs(_frequencies_squared(16, f, True).imag).max() > 0.0,
                      0.9 * BECK, 1.1 * BECK, tol=1e-3)
    assert flutter / BECK == pytest.approx(1.0, abs=0.01)
    euler = _bisect(lambda f: _frequencies_squared(16, f, False).real.min() < 0.0,
                    0.9 * EULER, 1.1 * EULER, tol=1e-4)
    assert euler / EULER == pytest.approx(1.0, abs=1e-3)
    w2 = _frequencies_squared(16, 2.0 * EULER, True)
    assert np.all(w2.real > 0.0) and not np.any(w2.imag)  # the follower column: stable


@pytest.mark.parametrize("factor, grows", [(0.9, False), (1.05, True)])
def test_beck_column_in_a_dynamic_run(factor, grows):
    """The flutter seen in time: the column, kicked by a short transverse tip force (0.01 N
    over 4 ms), under 0.9 and 1.05 times Beck's load, without numerical damping (rho_inf =
    1), over 40 ms (about one period of the coalescing modes). Below, the tip deflection's
    largest amplitude over the last quarter of the run stays within 1.5 times that of the
    first quarter (measured 1.0); above, it grows by more than 10 (measured 63: the
    eigenvalue analysis gives a growth rate of ~100/s at 1.05)."""
    model = column(16, factor * BECK * EI_BECK / L_BECK**2, True)
    kick = ml.SmoothStep(0.0, 2e-3) - ml.SmoothStep(2e-3, 4e-3)
    model.add_force("col", at=(L_BECK, 0.0), force=(0.0, 0.01), profile=kick, name="kick")
    res = ml.simulate(model, t_end=0.04, dt=2e-4, rho_inf=1.0)
    y = res.node_positions("col")[:, -1, 1]
    quarter = len(y) // 4
    ratio = np.abs(y[-quarter:]).max() / np.abs(y[:quarter]).max()
    assert (ratio > 10.0) if grows else (ratio < 1.5), ratio


# ------------------------------------------------------------------ energy
def test_the_pressure_work_on_a_closed_ring_is_p_times_the_area_change():
    """A ring under an internal pressure switched on at once (p b = 0.5 N/mm), no damping:
    it breathes. On a closed contour the follower pressure is conservative, with work
    p b (A - A0) for the enclosed area A (here the polygon of the nodes: the uniform breathing
    keeps the elements straight). The library's load work (the time integral of its power)
    equals that to 1e-3 of its largest value (trapezoidal rule on 400 steps per run), and the
    energy balance total - work closes to 1e-3 of the work."""
    p = -0.05
    system = ml.compile_model(ring(24, p))
    res = ml.simulate(system, t_end=2e-4, dt=5e-7, rho_inf=1.0)
    xy = np.concatenate([res.node_positions(name)[:, :-1] for name in "ab"], axis=1)
    area = 0.5 * np.sum(xy[:, :, 0] * np.roll(xy[:, :, 1], -1, axis=1)
                        - np.roll(xy[:, :, 0], -1, axis=1) * xy[:, :, 1], axis=1)
    expected = -p * B * (area - area[0])
    work = res.energy["load_work"]
    assert np.abs(work).max() > 0.0
    np.testing.assert_allclose(work, expected, atol=1e-3 * np.abs(expected).max())
    balance = res.energy["total"] - res.energy["total"][0] - work
    assert np.abs(balance).max() <= 1e-3 * np.abs(work).max()


# ------------------------------------------------------------------ sensitivities
P_PR = {"p": 2e-3, "t": 2.0, "f": 0.05, "x_tip": 80.0}
RUN = dict(t_end=0.02, dt=1e-3)


def _design(p):
    """A pendulum beam under a pressure and a follower force at its tip: the pressure's
    magnitude, the section, the follower force and the beam's length are the variables."""
    m = ml.Model(gravity=(0.0, -9.81e3), name="pressure design")
    nodes = straight_nodes(4, length=p["x_tip"], angle=-0.3)
    beam = m.add_beam(nodes, E=E_AL, rho=RHO_AL, thickness=p["t"], width=10.0, frames=2,
                      name="beam")
    m.add_revolute(m.ground, beam, at=(0.0, 0.0), name="pivot")
    m.add_pressure("p", beam, p["p"] * np.array([0.5, 1.0, 1.0, 0.8, 0.2]))
    m.add_force(beam, at=tuple(nodes[-1]), force=(0.0, p["f"]), follower=True, name="f")
    return m


def test_sensitivities_through_pressure_and_follower_force():
    """Direct and adjoint equal the whole-run complex step to 1e-8 of each response's
    largest scaled gradient (p_i dpsi/dp_i), and each variable moves each response by more
    than 1e-4 of the largest (no vacuous comparison)."""
    resp = {"tip_y": ml.responses.point_displacement("beam", (P_PR["x_tip"] * np.cos(-0.3),
                                                              P_PR["x_tip"] * np.sin(-0.3)),
                                                     1)}
    check_gradients_by_complex_step(_design, P_PR, resp, RUN)


# ------------------------------------------------------------------ input
@pytest.mark.parametrize("kwargs, match", [
    (dict(p=np.ones(3)), "one finite value per node"),
    (dict(p=np.nan), "finite"),
    (dict(p=0.1, elements=[7]), "elements must be"),
    (dict(p=lambda xy: 1 / 0), "ZeroDivisionError"),
    (dict(p=0.1, width=-1.0), "width must be > 0"),
])
def test_bad_pressure_input_names_the_pressure(kwargs, match):
    m = ml.Model()
    beam = m.add_beam(straight_nodes(4, 80.0), E=E_AL, rho=RHO_AL, thickness=2.0, width=10.0,
                      name="beam")
    with pytest.raises(ml.ModelError, match=match) as err:
        m.add_pressure("skin", beam, **kwargs)
    assert "pressure 'skin'" in str(err.value)


def test_a_pressure_needs_a_width():
    m = ml.Model()
    beam = m.add_beam(straight_nodes(4, 80.0), E=E_AL, rho=RHO_AL, area=20.0,
                      second_moment=6.0, name="beam")
    with pytest.raises(ml.ModelError, match="has no width"):
        m.add_pressure("skin", beam, 0.1)
    assert m.add_pressure("skin", beam, 0.1, width=10.0).width[0] == 10.0
