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


def check_step_matrix_by_complex_step(model, seed: int) -> None:
    """Assert that every column of the step matrix equals the complex-step derivative of the
    step residual (h = 1e-30: no truncation or cancellation error, so agreement to round-off;
    1e-9 of the column's largest entry) at a random state far from any solution: nonzero
    velocities, accelerations and multipliers, so every term of the matrix shows."""
    from morphlab.compile import kernel_arrays
    from morphlab.kernels.assemble import step_matrix, step_residual

    system = ml.compile_model(model)
    n, n_dof = system.n, system.n_dof
    rng = np.random.default_rng(seed)
    c, cd, cdd, F, T = system.time_arrays(0.0)
    qh = system.q0 + 0.05 * rng.standard_normal(n_dof)
    vh = 3.0 * rng.standard_normal(n_dof)
    z = rng.standard_normal(n)
    bh2, gh, scale, b0, b1 = 0.3, 0.7, 2.0, 5.0, 3.0
    w = np.array([1.1, 0.9, 0.8, 1.3, 0.6])
    data = np.zeros(system.nnz)
    step_matrix(kernel_arrays(system), z, qh, vh, bh2, gh, scale, w, b0, b1, F, data)
    A = np.zeros((n, n))
    for col in range(n):
        sl = slice(system.indptr[col], system.indptr[col + 1])
        A[system.indices[sl], col] = data[sl]
    Sc = kernel_arrays(system, np.complex128)
    cplx = [x.astype(complex) for x in (qh, vh, c, cd, cdd, F, T)]
    h = 1e-30
    for k in range(n):
        zk = z.astype(complex)
        zk[k] += 1j * h
        R = np.zeros(n, dtype=complex)
        step_residual(Sc, zk, cplx[0], cplx[1], bh2, gh, scale, w, b0, b1, *cplx[2:], n_dof,
                      np.zeros(n, dtype=complex), R)
        col = R.imag / h
        assert np.abs(A[:, k] - col).max() <= 1e-9 * max(np.abs(col).max(), 1.0), \
            system.unknown_names[k]
    _check_split_matrices(system, Sc, z, qh, vh, bh2, gh, scale, w, b0, b1, cplx, data)


def _check_split_matrices(system, Sc, z, qh, vh, bh2, gh, scale, w, b0, b1, cplx, data):
    """The split matrices of the sensitivity methods at the step's state: ``D0, Dq, Dv``
    (one pass, ``split_matrices``) combine to the step matrix ``data`` (round-off: 1e-13 of
    its largest entry), and each is the complex-step derivative of the level's residual share
    with respect to ``(a, lam/scale)``, ``q`` and ``q'`` with the other two held (1e-9 of the
    column's largest entry, as above); ``Dq`` and ``Dv`` have empty multiplier columns."""
    from morphlab.compile import kernel_arrays
    from morphlab.kernels.assemble import add_residual
    from morphlab.kernels.direct import split_matrices

    n, n_dof = system.n, system.n_dof
    q, v, a = qh + bh2 * z[:n_dof], vh + gh * z[:n_dof], z[:n_dof]
    lam = z[n_dof:] * scale
    D = np.zeros((3, system.nnz))
    split_matrices(kernel_arrays(system), q, v, a, lam, w, scale, b0, b1, cplx[5].real, D)
    assert np.abs(D[0] + bh2 * D[1] + gh * D[2] - data).max() <= 1e-13 * np.abs(data).max()
    h = 1e-30
    for k in range(n):
        sl = slice(system.indptr[k], system.indptr[k + 1])
        for which in range(3):  # 0: a or lam/scale, 1: q, 2: q'
            if k >= n_dof and which > 0:
                assert not D[which, sl].any(), system.unknown_names[k]
                continue
            x = [q.astype(complex), v.astype(complex), a.astype(complex), lam.astype(complex)]
            if k >= n_dof:
                x[3][k - n_dof] += 1j * h * scale
            else:
                x[(2, 0, 1)[which]][k] += 1j * h
            R = np.zeros(n, dtype=complex)
            add_residual(Sc, *x, *w, scale, b0, b1, *cplx[2:], n_dof, R)
            col = R.imag / h
            got = np.zeros(n)
            got[system.indices[sl]] = D[which, sl]
            assert np.abs(got - col).max() <= 1e-9 * max(np.abs(col).max(), 1.0), \
                (which, system.unknown_names[k])
