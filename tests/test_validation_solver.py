"""Solver settings are validated through ``ml.simulate``; run-time failures raise a
:class:`SolverError` that says where and why, and keeps the steps completed before it.

References: the four-bar linkage locks where coupler and rocker become collinear, at a crank
angle known in closed form (law of cosines); the steps completed before a failure are checked
against the closed-form position analysis of the same linkage.
"""

import functools

import numpy as np
import pytest
from models import flexible_mechanism

import morphlab as ml
from morphlab.solve.settings import Settings
from morphlab.solve.stepper import Stepper

PATHS = {"dense": dict(dense_max=1000), "sparse": dict(dense_max=0),
         "python": dict(dense_max=0, compiled_newton=False)}


@pytest.fixture(autouse=True, params=list(PATHS))
def newton_path(request, monkeypatch):
    """Every test three times: the Newton loop in one compiled call on the dense LU of small
    step matrices and on the sparse factorization of larger ones (``dense_max`` forces either
    on these models of 20-40 unknowns; SuperLU factors the first two sparse matrices of a run
    from Python), and every iteration from Python (``compiled_newton=False``). All must fail
    the same way. (``ml.simulate`` of these tests gets the path's settings.)"""
    monkeypatch.setattr(ml, "simulate", functools.partial(ml.simulate, **PATHS[request.param]))
    return request.param


# ------------------------------------------------------------------------------- settings
@pytest.mark.parametrize("kw,name", [
    (dict(rho_inf=1.5), "rho_inf"), (dict(rho_inf=-0.1), "rho_inf"),
    (dict(rho_inf=np.nan), "rho_inf"), (dict(rho_inf=None), "rho_inf"),
    (dict(dt=0.0), "dt"), (dict(dt=-1e-3), "dt"), (dict(dt=np.nan), "dt"), (dict(dt=None), "dt"),
    (dict(dt=0.02), "dt"),  # larger than t_end
    (dict(t_end=np.inf), "t_end"), (dict(t_end=-1.0), "t_end"), (dict(t_end="1"), "t_end"),
    (dict(tol=0.0), "tol"), (dict(tol=1.5), "tol"), (dict(tol="a"), "tol"), (dict(tol=1), "tol"),
    (dict(max_iter=0), "max_iter"), (dict(max_iter=1.5), "max_iter"),
    (dict(stabilization=-1.0), "stabilization"),
    (dict(constraint_form="index3"), "constraint_form"),
])
def test_bad_settings_are_refused_by_simulate(kw, name):
    args = dict(t_end=0.01, dt=1e-3)
    args.update(kw)
    with pytest.raises(ml.ModelError, match=name):
        ml.simulate(flexible_mechanism(), **args)


# Type checks of Settings.validate (morphlab/solve/settings.py): a bool is not an iteration
# count, a NumPy integer is one, and a string is not a number.
def test_max_iter_true_is_refused():
    with pytest.raises(ml.ModelError, match="max_iter"):
        ml.simulate(flexible_mechanism(), t_end=0.01, dt=1e-3, max_iter=True)


def test_numpy_integer_max_iter_is_accepted():
    res = ml.simulate(flexible_mechanism(), t_end=0.002, dt=1e-3, max_iter=np.int64(12))
    assert res.status == "ok"


def test_string_stabilization_is_refused():
    with pytest.raises(ml.ModelError, match="stabilization"):
        ml.simulate(flexible_mechanism(), t_end=0.01, dt=1e-3, stabilization="a")


@pytest.mark.parametrize("bad", [np.nan, -1.0])
def test_bad_stabilization_damping_is_refused(bad):
    with pytest.raises(ml.ModelError, match="stabilization_damping"):
        ml.simulate(flexible_mechanism(), t_end=0.01, dt=1e-3, stabilization_damping=bad)


# ------------------------------------------------------------------------ run-time failures
A, B, C, D = 1.0, 2.0, 2.0, 3.5  # crank, coupler, rocker, ground link [mm]
TH0 = np.pi / 2  # initial crank angle


def fourbar_points(theta):
    """Closed-form position analysis: pins (B, C) for crank angle ``theta`` (elbow up)."""
    Bp = A * np.array([np.cos(theta), np.sin(theta)])
    Dp = np.array([D, 0.0])
    e = Dp - Bp
    dist = np.hypot(*e)
    x = (dist**2 + B**2 - C**2) / (2 * dist)
    y = np.sqrt(B**2 - x**2)
    e = e / dist
    return Bp, Bp + x * e + y * np.array([-e[1], e[0]])


def driven_fourbar():
    """Rigid four-bar, crank driven with angle(t) = 2 t^2 (zero initial speed, as the bodies
    start at rest). It locks when coupler and rocker become collinear: |BD| = B + C."""
    m = ml.Model(name="fourbar")
    Bp, Cp = fourbar_points(TH0)
    Dp = np.array([D, 0.0])

    def link(P, Q, name):
        d = np.asarray(Q) - np.asarray(P)
        return m.add_rigid_body(mass=1e-3, inertia=1e-3 * (d @ d) / 12,
                                position=tuple((np.asarray(P) + Q) / 2),
                                angle=np.arctan2(d[1], d[0]), name=name)

    crank, coupler, rocker = link((0.0, 0.0), Bp, "crank"), link(Bp, Cp, "coupler"), \
        link(Dp, Cp, "rocker")
    m.add_revolute(m.ground, crank, at=(0.0, 0.0), name="A")
    m.add_revolute(crank, coupler, at=Bp, name="B")
    m.add_revolute(coupler, rocker, at=Cp, name="C")
    m.add_revolute(rocker, m.ground, at=Dp, name="D")
    m.add_drive(crank, angle=ml.Custom(lambda t: 2.0 * t * t, lambda t: 4.0 * t, lambda t: 4.0),
                name="motor")
    return m, Cp


def test_driven_into_a_locked_position():
    # law of cosines: |BD|^2 = A^2 + D^2 - 2 A D cos(theta) = (B + C)^2 at the lock
    th_lock = np.arccos((A**2 + D**2 - (B + C) ** 2) / (2 * A * D))
    t_lock = np.sqrt((th_lock - TH0) / 2.0)
    h = 0.01
    model, C0 = driven_fourbar()
    with pytest.raises(ml.SolverError) as err:
        ml.simulate(model, t_end=1.0, dt=h)
    e = err.value
    # no configuration exists after t_lock, so the first step past it must fail; the solver
    # may give up a few steps earlier, where the rocker speed grows like 1/sqrt(t_lock - t)
    assert t_lock - 5 * h <= e.time <= t_lock + h
    assert e.step == round(e.time / h)
    assert np.isfinite(e.residual) and e.residual > 0
    assert e.dominant and all(isinstance(s, str) for s in e.dominant)
    res = e.result
    assert res.status == "failed" and res.message == str(e)
    assert res.t[-1] == pytest.approx(e.time - h, abs=1e-12) and res.t[-1] < 1.0
    assert res.q.shape == (e.step, res.system.n_dof) == res.v.shape == res.a.shape
    assert res.lam.shape == (e.step, res.system.n_con)
    # the kept steps are the steps of a run that stops before the failure (same time grid)
    short = ml.simulate(driven_fourbar()[0], t_end=float(res.t[-1]), dt=h)
    assert short.n_t == res.n_t
    np.testing.assert_allclose(res.q, short.q, rtol=1e-12, atol=1e-12)  # h equal to round-off
    # ... and they are true solutions: pin C against the closed-form analysis, away from the
    # lock. Tolerance: the position drift of the stabilized acceleration-level constraints is
    # O(h^3) (about 3e-5 mm here at t <= 0.3 s; halving h divides it by ~7), so 1e-4 mm = 5e-5
    # of the coupler length; a wrong configuration would be off by the link sizes.
    keep = res.t <= 0.3
    C_sim = res.point_positions("rocker", C0)[keep]
    C_ref = np.array([fourbar_points(TH0 + 2 * t * t)[1] for t in res.t[keep]])
    assert np.max(np.abs(C_sim - C_ref)) < 1e-4


def test_too_few_newton_iterations():
    h = 1e-3
    with pytest.raises(ml.ConvergenceError) as err:
        # one iteration cannot reach a position correction of 1e-300 of the model size
        ml.simulate(flexible_mechanism(), t_end=0.01, dt=h, max_iter=1, tol=1e-300)
    e = err.value
    assert e.step == 1 and e.time == pytest.approx(h, rel=1e-12)
    assert np.isfinite(e.residual) and e.residual > 0
    names = set(e.result.system.dof_names) | {f"constraint {c}"
                                              for c in e.result.system.con_names}
    assert e.dominant and all(s.rsplit(" (", 1)[0] in names for s in e.dominant)
    res = e.result
    assert res.status == "failed" and res.n_t == 1 and res.t[-1] == 0.0
    # the one completed "step" is the initial state, which is the model's own q0
    assert np.array_equal(res.q[0], res.system.q0)


def nan_force_model(t_nan):
    m = flexible_mechanism()
    node = tuple(m.body("coupler").nodes[2])
    m.add_force("coupler", at=node, force=(1.0, 0.0), name="bad",
                profile=ml.Custom(lambda t: np.nan if t > t_nan else 1.0))
    return m


def test_nan_from_a_profile_stops_the_run_there_and_names_the_load():
    """The profile's table is checked before the run; the run goes up to the last time
    before the NaN and raises a ProfileError (a SolverError) naming the load."""
    h, t_nan = 1e-3, 4.5e-3
    with pytest.raises(ml.ProfileError, match="force 'bad' gave a NaN") as err:
        ml.simulate(nan_force_model(t_nan), t_end=0.01, dt=h)
    e = err.value
    assert isinstance(e, ml.SolverError)
    assert e.step == 5 and e.time == pytest.approx(5 * h, rel=1e-12)  # first t > t_nan
    res = e.result
    assert res.status == "failed" and res.n_t == 5 and res.t[-1] < t_nan
    for arr in (res.q, res.v, res.a, res.lam):
        assert np.all(np.isfinite(arr))


def test_a_nan_in_a_drive_at_t0_names_the_drive():
    m = flexible_mechanism()
    # angle(0) = 0 passes the model check, but the second derivative is NaN
    m.add_drive("crank", name="motor", angle=ml.Custom(lambda t: 0.5 * t * t, lambda t: t,
                                                       lambda t: np.nan))
    with pytest.raises(ml.ProfileError, match="drive 'motor' gave a NaN.* at t=0") as err:
        ml.simulate(m, t_end=0.01, dt=1e-3)
    assert err.value.step == 0


def test_non_finite_residual_names_the_equations():
    """A NaN that no profile check sees (a state from outside, here the start velocities):
    the Newton iteration names the equations that received it."""
    system = ml.compile_model(flexible_mechanism())
    v0 = np.zeros(system.n_dof)
    v0[system.body("coupler").ref[2]] = 1e200  # its first frame's angle: its square overflows
    with pytest.raises(ml.NonFiniteError) as err:
        ml.simulate(system, t_end=0.01, dt=1e-3, v0=v0)
    e = err.value
    assert e.step <= 1 and e.dominant
    assert e.result.status == "failed"


def test_singular_step_matrix_names_the_time_and_the_step(newton_path):
    """A step matrix that is exactly singular (all masses, inertias and stiffnesses of a
    four-bar scaled to zero, so the equation rows of the free directions vanish) raises
    SingularMatrixError in the initial solve, at t = 0, with the residual and the dominant
    equations; the dense path names the unknown whose column has no pivot."""
    system = ml.compile_model(flexible_mechanism())
    settings = Settings(t_end=0.01, dt=1e-3, **PATHS[newton_path])
    system.design[:] = 0.0  # every design field (a view of it) zero
    stp = Stepper.dynamic(system, settings, ml.compile.time_table(system, np.zeros(1)),
                          scale=1.0)
    with pytest.raises(ml.SingularMatrixError) as err:
        stp.initial(0.0, system.q0, system.v0)
    e = err.value
    assert e.time == 0.0 and e.step == 0
    assert "singular saddle-point matrix at t=0" in str(e)
    assert np.isfinite(e.residual) and e.dominant
    if newton_path == "dense":
        names = system.dof_names + [f"constraint {c}" for c in system.con_names]
        assert any(f"column of {name}." in str(e) for name in names)


# ------------------------------------------------------------------- automatic step reduction
def _suddenly_loaded_four_bar():
    m = flexible_mechanism(n_elem=12)
    # a point load switched on at t = 0: the first step starts far from equilibrium
    m.forces[0].profile = ml.Constant(1.0)
    return m


def test_step_reduction_rescues_a_failing_step_and_reports_it():
    m = _suddenly_loaded_four_bar()
    with pytest.raises(ml.ConvergenceError):
        ml.simulate(m, t_end=0.01, dt=2e-3, max_iter=3)
    res = ml.simulate(m, t_end=0.01, dt=2e-3, max_iter=3, max_halvings=6)
    assert res.status == "ok" and len(res.t) == 6  # results stay on the regular grid
    assert res.step_reductions and res.step_reductions[0][0] == pytest.approx(2e-3)
    assert res.step_reductions[0][1] >= 2
    # the sub-stepped run agrees with a run at the smaller step on the same grid points
    # (max |dq| small against the 60 mm model: both are second-order accurate in time)
    fine = ml.simulate(m, t_end=0.01, dt=2e-3 / res.step_reductions[0][1], max_iter=12)
    stride = res.step_reductions[0][1]
    assert np.max(np.abs(fine.q[::stride][:2] - res.q[:2])) < 1e-6 * 60.0


def test_step_reduction_is_refused_with_an_observer():
    from morphlab.solve.stepper import Settings
    from morphlab.solve.timeloop import integrate

    system = ml.compile_model(flexible_mechanism())
    with pytest.raises(ml.ModelError, match="step reduction"):
        integrate(system, Settings(t_end=0.01, dt=1e-3), observer=lambda info: None,
                  max_halvings=2)
