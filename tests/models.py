"""Small models shared by the tests (each builds in milliseconds)."""

import numpy as np
import pytest

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


def inclined_slider_crank(p, length=50.0, th0=0.5, speed=30.0, rod_inertia=40.0,
                          name="inclined slider-crank"):
    """Rigid slider-crank under gravity whose guide through the crank's pivot is inclined by
    ``p["alpha"]`` [rad]; slider mass ``p["m"]`` [t], crank radius ``p["r"]`` [mm], rod
    ``length`` [mm], crank angle ``th0`` [rad] at the start; the crank driven from rest to
    ``speed`` [rad/s]. Complex-safe in every design value (the slider's frame follows the
    guide)."""
    r, alpha = p["r"], p["alpha"]
    e = np.array([np.cos(alpha), np.sin(alpha)])
    pin = np.array([r * np.cos(th0), r * np.sin(th0)])
    cross = pin[0] * e[1] - pin[1] * e[0]
    x0 = (pin @ e + np.sqrt(length * length - cross * cross)) * e
    m = ml.Model(gravity=(0.0, -9.81e3), name=name)
    crank = m.add_rigid_body(mass=1e-4, inertia=5.0, position=tuple(pin / 2), name="crank")
    rod = m.add_rigid_body(mass=2e-4, inertia=rod_inertia, position=tuple((pin + x0) / 2),
                           name="rod")
    slider = m.add_rigid_body(mass=p["m"], inertia=1.0, position=tuple(x0), angle=alpha,
                              name="slider")
    m.add_revolute(m.ground, crank, at=(0.0, 0.0), name="O")
    m.add_revolute(crank, rod, at=tuple(pin), name="A")
    m.add_revolute(rod, slider, at=tuple(x0), name="B")
    m.add_prismatic(m.ground, slider, at=tuple(x0), axis=tuple(e), name="guide")
    k = 2 * np.pi / 0.02
    m.add_drive(crank, angle=ml.Custom(lambda t: speed * (t - np.sin(k * t) / k),
                                       lambda t: speed * (1 - np.cos(k * t)),
                                       lambda t: speed * k * np.sin(k * t)), name="motor")
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


def _step_data(system, seed):
    """A random state far from any solution (nonzero velocities, accelerations and
    multipliers) and the step's weights; the time values at t = 0 (mid-ramp profiles are
    not needed: the time values enter linearly)."""
    from morphlab.compile.system import time_table
    from morphlab.kernels.types import Weights

    n_dof = system.n_dof
    rng = np.random.default_rng(seed)
    qh = system.q0 + 0.05 * rng.standard_normal(n_dof)
    vh = 3.0 * rng.standard_normal(n_dof)
    z = rng.standard_normal(system.n)
    w = Weights(1.1, 0.9, 0.8, 1.3, 0.6, 2.0, 5.0, 3.0)
    return qh, vh, z, w, time_table(system, np.array([0.0, 1e-3]), np.complex128)


def _level(z, qh, vh, bh2, gh, scale, n_dof):
    from morphlab.kernels.types import Level

    a = np.ascontiguousarray(z[:n_dof])
    return Level(qh + bh2 * a, vh + gh * a, a, np.ascontiguousarray(z[n_dof:] * scale))


def check_step_matrix_by_complex_step(model, seed: int) -> None:
    """Assert that every column of the step matrix equals the complex-step derivative of the
    step residual (h = 1e-30: no truncation or cancellation error, so agreement to round-off;
    1e-9 of the column's largest entry) at a random state far from any solution: nonzero
    velocities, accelerations and multipliers, so every term of the matrix shows. The split
    matrices ``D0, Dq, Dv`` of the sensitivity methods (a pass with ``C`` the identity)
    combine to the step matrix of a pass of its own (round-off) and each is the complex-step
    derivative of the residual along ``(a, lam/scale)``, ``q`` and ``q'`` with the other two
    held."""
    from morphlab.kernels.assemble import matrix, residual
    from morphlab.kernels.ffrf import scratch
    from morphlab.kernels.system import all_parts

    system = ml.compile_model(model)
    n, n_dof = system.n, system.n_dof
    qh, vh, z, w, Tc = _step_data(system, seed)
    T = type(Tc)(*(None if x is None else type(x)(*(a.real.copy() for a in x)) for x in Tc))
    bh2, gh = 0.3, 0.7
    M = system.arrays
    Mc = system.arrays_as(np.complex128)
    n_flex = M.flex[0].shape[0]
    data = np.zeros((4, system.nnz))  # the step matrix, then D0, Dq, Dv in a second pass
    for C, out in ((np.array([[1.0, bh2, gh]]), data[0:1]), (np.eye(3), data[1:4])):
        matrix(M, _level(z, qh, vh, bh2, gh, w.scale, n_dof), w, T, np.int64(0), np.int64(0),
               C, out, scratch(n_flex, qh))
    A = np.zeros((n, n))
    for col in range(n):
        sl = slice(system.indptr[col], system.indptr[col + 1])
        A[system.indices[sl], col] = data[0, sl]
    P = all_parts(M)
    Wc = scratch(n_flex, np.zeros(1, complex))
    h = 1e-30
    zc, qc, vc = z.astype(complex), qh.astype(complex), vh.astype(complex)
    for k in range(n):
        zk = zc.copy()
        zk[k] += 1j * h
        R = np.zeros(n, dtype=complex)
        residual(Mc, _level(zk, qc, vc, bh2, gh, w.scale, n_dof), w, Tc, np.int64(0),
                 np.int64(0), P, np.int64(n_dof), R, Wc)
        col = R.imag / h
        assert np.abs(A[:, k] - col).max() <= 1e-9 * max(np.abs(col).max(), 1.0), \
            system.unknown_names[k]
    # the split matrices
    assert np.abs(data[1] + bh2 * data[2] + gh * data[3] - data[0]).max() <= \
        1e-13 * np.abs(data[0]).max()
    x0 = _level(zc, qc, vc, bh2, gh, w.scale, n_dof)
    for k in range(n):
        sl = slice(system.indptr[k], system.indptr[k + 1])
        for which in range(3):  # 0: a or lam/scale, 1: q, 2: q'
            if k >= n_dof and which > 0:
                assert not data[1 + which, sl].any(), system.unknown_names[k]
                continue
            x = [a.copy() for a in x0]
            if k >= n_dof:
                x[3][k - n_dof] += 1j * h * w.scale
            else:
                x[(2, 0, 1)[which]][k] += 1j * h
            R = np.zeros(n, dtype=complex)
            residual(Mc, type(x0)(*x), w, Tc, np.int64(0), np.int64(0), P, np.int64(n_dof), R,
                     Wc)
            col = R.imag / h
            got = np.zeros(n)
            got[system.indices[sl]] = data[1 + which, sl]
            assert np.abs(got - col).max() <= 1e-9 * max(np.abs(col).max(), 1.0), \
                (which, system.unknown_names[k])


def check_gradients_by_complex_step(build, p0: dict, responses: dict, run: dict,
                                    cross: float | None = None) -> None:
    """Assert that the direct and the adjoint design gradients of ``responses`` equal the
    whole-run complex step to 1e-8 of each response's largest scaled gradient
    (``p_i dpsi/dp_i``), and that each variable moves each response by more than 1e-4 of the
    largest (no comparison is vacuous); ``cross``: the direct and the adjoint gradients also
    equal each other to that fraction of the largest. ``run``: the keywords of the runs."""
    d = ml.sensitivities(build, p0, responses, method="direct", **run)
    a = ml.sensitivities(build, p0, responses, method="adjoint", **run)
    cs = ml.sensitivities(build, p0, responses, method="complex-step", **run)
    for r in responses:
        scaled = {v: abs(p0[v] * cs.gradients[r][v]) for v in p0}
        largest = max(scaled.values())
        for v in p0:
            assert scaled[v] > 1e-4 * largest, (r, v)  # every variable acts
            ref = cs.gradients[r][v]
            assert abs(p0[v] * (d.gradients[r][v] - ref)) <= 1e-8 * largest, (r, v)
            assert abs(p0[v] * (a.gradients[r][v] - ref)) <= 1e-8 * largest, (r, v)
            if cross is not None:
                diff = abs(p0[v] * (a.gradients[r][v] - d.gradients[r][v]))
                assert diff <= cross * largest, (r, v)


def check_method_by_complex_step(build, p0: dict, responses: dict, method: str, run: dict):
    """Assert that ``method``'s response values equal the whole-run complex step's (1e-12
    relative) and its gradients those of the complex step to 1e-8 of each response's largest
    gradient (both exact: the difference is the Newton tolerance's residue); return its
    :class:`~morphlab.sensitivity.api.SensitivityResult`. ``run``: the keywords of the runs."""
    got = ml.sensitivities(build, p0, responses, method=method, **run)
    ref = ml.sensitivities(build, p0, responses, method="complex-step", **run)
    for r in responses:
        assert got.values[r] == pytest.approx(ref.values[r], rel=1e-12)
        scale = max(abs(g) for g in ref.gradients[r].values())
        assert scale > 0
        for v in p0:
            assert abs(got.gradients[r][v] - ref.gradients[r][v]) <= 1e-8 * scale, (r, v)
    return got
