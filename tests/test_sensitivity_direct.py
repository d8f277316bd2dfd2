"""Direct differentiation (``method="direct"``) against the whole-run complex step.

The reference differentiates the *entire* simulation in complex arithmetic (build, compile,
every Newton step) with ``p + i h e_k``, ``h = 1e-30``: it has no truncation error and no
subtractive cancellation (Martins, Sturdza & Alonso, ACM TOMS 29 (2003) 245), so the direct
method, which differentiates the same discrete equations step by step, must match it to
round-off. Two models, each with design variables of every kind the library supports:

* a flexible pendulum: beam hinged to the ground, a rigid tip mass pinned to its end, gravity
  and a ramped torque; variables: section thickness, E, rho, torque magnitude, the x coordinate
  of the ground pivot (it changes the beam's initial length and direction) and the tip mass;
* a closed-loop four-bar (crank, flexible coupler, rigid rocker): variables: coupler thickness,
  E, rho, crank torque, a point force, the x coordinate of the rocker's ground pivot (rocker
  position, length, mass and inertia computed from it, complex-safe through ``np.sqrt``) and the
  crank mass.

Responses of every kind: a displacement at the final time, the KS stress maximum, an RMS shape
error against a fixed target, a constraint reaction (a multiplier) at the final time and one
averaged over the run, and a rigid-body angle.

Also here: the sensitivity solve reuses the primal's factorizations (none of its own), and the
iterative refinement against the exact converged matrix reaches round-off.
"""

import numpy as np
import pytest
import scipy.sparse.linalg

import morphlab as ml
import morphlab.sensitivity.api
import morphlab.sensitivity.direct
import morphlab.solve.linalg
import morphlab.solve.stepper
import morphlab.solve.superlu
from morphlab.sensitivity import Direct

R = ml.responses
GRAVITY = (0.0, -9.81e3)  # mm/s^2
RUN = dict(t_end=0.03, dt=1e-3)  # 30 steps: long enough for large motion, short for the tests

# ---------------------------------------------------------------- flexible pendulum
PEND_TIP = np.array([60.0, -45.0])  # fixed tip point [mm]; the pivot moves with p["x_pivot"]


def pendulum(p, n_elem=4):
    """Beam from the ground pivot (x_pivot, 0) to a fixed tip point, pinned to the ground;
    a rigid tip mass pinned at the tip; gravity and a smoothly ramped torque on the beam."""
    m = ml.Model(gravity=GRAVITY, name="pendulum")
    pivot = np.array([p["x_pivot"], 0.0])
    s = np.linspace(0.0, 1.0, n_elem + 1)[:, None]
    nodes = pivot + s * (PEND_TIP - pivot)
    beam = m.add_beam(nodes, E=p["E"], rho=p["rho"], thickness=p["t"], width=10.0,
                      damping=1e-4, name="beam")
    m.add_revolute(m.ground, beam, at=pivot, name="pivot")
    tip = m.add_rigid_body(mass=p["m_tip"], inertia=0.05, position=PEND_TIP, name="tip")
    m.add_revolute(beam, tip, at=PEND_TIP, name="T")
    m.add_torque(beam, p["M"], profile=ml.SmoothStep(0.0, 0.01), name="Mt")
    return m


P_PEND = {"t": 1.5, "E": 70000.0, "rho": 2.7e-9, "M": 40.0, "x_pivot": 5.0, "m_tip": 2e-4}

# ---------------------------------------------------------------- closed-loop four-bar
B_PT = np.array([0.0, 20.0])  # crank-coupler pin [mm]
C_PT = B_PT + 60.0 * np.array([np.cos(0.1), np.sin(0.1)])  # coupler-rocker pin [mm]


def mechanism(p, n_elem=6):
    """Crank pinned to the ground at the origin, flexible coupler B-C, rigid rocker C-D with D
    = (x_D, 0) on the ground; the rocker's centre, length, mass (5e-6 t/mm) and inertia
    (slender rod, m L²/12) follow from x_D."""
    m = ml.Model(gravity=GRAVITY, name="four-bar")
    crank = m.add_rigid_body(mass=p["m_crank"], inertia=0.2, position=(0.0, 10.0),
                             angle=np.pi / 2, name="crank")
    s = np.linspace(0.0, 1.0, n_elem + 1)[:, None]
    nodes = B_PT + s * (C_PT - B_PT)
    coupler = m.add_beam(nodes, E=p["E"], rho=p["rho"], thickness=p["t"], width=10.0,
                         damping=p.get("beta", 1e-4), name="coupler")
    D = np.array([p["x_D"], 0.0 * p["x_D"]])
    d = C_PT - D
    length = np.sqrt(d[0] * d[0] + d[1] * d[1])  # complex-safe (no np.hypot / abs)
    mass = 5e-6 * length
    rocker = m.add_rigid_body(mass=mass, inertia=mass * length * length / 12.0,
                              position=(C_PT + D) / 2.0, name="rocker")
    m.add_revolute(m.ground, crank, at=(0.0, 0.0), name="A")
    m.add_revolute(crank, coupler, at=B_PT, name="B")
    m.add_revolute(coupler, rocker, at=C_PT, name="C")
    m.add_revolute(rocker, m.ground, at=D, name="D")
    m.add_torque(crank, p["M"], profile=ml.SmoothStep(0.0, 0.02), name="Mt")
    m.add_force(coupler, at=nodes[3], force=(0.0, -p["F"]), name="F")
    return m


P_MECH = {"t": 2.0, "E": 70000.0, "rho": 2.7e-9, "M": 50.0, "F": 2.0, "x_D": 65.0,
          "m_crank": 2e-4}


def reaction(joint, component, time_index=-1):
    """Response: multiplier of the constraint row ``joint.component`` at one time."""
    def response(result):
        return result.lam[time_index, result.system.con_names.index(f"{joint}.{component}")]
    return response


def mean_reaction(joint, component):
    """Response: time average of a multiplier over the run (depends on the whole history)."""
    def response(result):
        return np.mean(result.lam[:, result.system.con_names.index(f"{joint}.{component}")])
    return response


def responses_for(name):
    if name == "pendulum":
        body, point, build, p0 = "beam", PEND_TIP, pendulum, P_PEND
        joint = "pivot"
    else:
        body, point, build, p0 = "coupler", C_PT, mechanism, P_MECH
        joint = "D"
    # a fixed target (does not move with p): the nominal undeformed nodes shifted by (3, -5) mm
    target = np.real(np.asarray(build(p0).body(body).nodes)) + np.array([3.0, -5.0])
    resp = {
        "displacement": R.point_displacement(body, tuple(point), 1),
        "ks_stress": R.ks_max_stress(body, 0.5),
        "rms_error": R.rms_error(body, target),
        "reaction": reaction(joint, "y"),
        "mean_reaction": mean_reaction(joint, "x"),
    }
    if name == "mechanism":
        resp["rocker_angle"] = lambda r: r.dof("rocker.theta")[-1]
    return build, p0, resp


CASES = ("pendulum", "mechanism")
#: The exact variant (matrices at each step's converged state, refined): equal to the
#: whole-run complex step to round-off. The default (``reuse=True``, the primal's last Newton
#: matrices) is exact to the Newton tolerance: test_reuse_variant_is_exact_to_the_newton_tol.
EXACT = Direct(reuse=False)


@pytest.fixture(scope="module", params=CASES)
def runs(request):
    build, p0, resp = responses_for(request.param)
    # store="all": the history tests below compare every sensitivity history
    direct = ml.sensitivities(build, p0, resp, method=EXACT, store="all", **RUN)
    reference = ml.sensitivities(build, p0, resp, method="complex-step", **RUN)
    return request.param, build, p0, direct, reference


# Agreement criterion. An entry is compared relative to itself, down to a floor of 1e-3 of the
# response's largest logarithmic sensitivity max_j |p_j dr/dp_j|: below that floor an entry
# (e.g. the averaged pivot reaction against E, 1e-6 of the dominant one) is a near-cancellation
# whose absolute error is set by round-off in the dominant terms. Measured worst errors against
# the reference, relative to the entry: 1e-11 on both models for the entries above the floor,
# 3e-9 on the weakest entry (9e-11 of the floor), so 1e-8 leaves a margin of ~100.
REL = 1e-8
FLOOR = 1e-3


def test_direct_gradients_match_whole_run_complex_step(runs):
    name, _, p0, direct, ref = runs
    assert direct.values == pytest.approx(ref.values, rel=1e-14, abs=0.0)  # same primal run
    for r, g_ref in ref.gradients.items():
        scaled = {v: abs(p0[v] * g_ref[v]) for v in p0}
        largest = max(scaled.values())
        assert largest > 0.0
        for v in p0:
            err = abs(p0[v] * (direct.gradients[r][v] - g_ref[v]))
            assert err <= REL * max(scaled[v], FLOOR * largest), (name, r, v, err / scaled[v])


@pytest.mark.parametrize("name", CASES)
def test_direct_matches_complex_step_with_the_papers_weighting(name):
    """scheme="paper" (eq. 25-26) gives the residual an old-level share, so the state part of
    the pseudo-load also differentiates that share (three more matrix fills at the old state,
    kernels.direct.state_loads). Same criterion as above; measured 4.4e-11 (pendulum) and
    1.6e-11 (four-bar) relative, the largest entry above the floor."""
    build, p0, resp = responses_for(name)
    direct = ml.sensitivities(build, p0, resp, method=EXACT, scheme="paper", **RUN)
    ref = ml.sensitivities(build, p0, resp, method="complex-step", scheme="paper", **RUN)
    for r, g_ref in ref.gradients.items():
        scaled = {v: abs(p0[v] * g_ref[v]) for v in p0}
        largest = max(scaled.values())
        for v in p0:
            err = abs(p0[v] * (direct.gradients[r][v] - g_ref[v]))
            assert err <= REL * max(scaled[v], FLOOR * largest), (name, r, v, err / scaled[v])


def test_every_design_variable_is_exercised(runs):
    """Guard against a vacuous comparison: each variable must move at least one response by
    at least 1e-3 of that response's dominant logarithmic sensitivity (checked at 1e-8 above)."""
    _, _, p0, _, ref = runs
    for v in p0:
        strength = max(abs(p0[v] * g[v]) / max(abs(p0[w] * g[w]) for w in p0)
                       for g in ref.gradients.values())
        assert strength >= FLOOR, v


@pytest.mark.parametrize("key", ["q", "v", "a", "lam"])
def test_sensitivity_histories_match_complex_step(runs, key):
    """The whole state sensitivity history, column by column, against the derivative of the
    complex-step run's history. Scaled by each column's largest entry; measured <= 1.5e-10 (the
    accelerations, two differentiations further than the positions, are the noisiest)."""
    name, _, _, direct, ref = runs
    dref = ref.derivative(lambda r: getattr(r, key))
    dd = direct.state[key]
    assert dd.shape == dref.shape == getattr(direct.result, key).shape + (len(direct.variables),)
    scale = np.max(np.abs(dref), axis=(0, 1))
    assert np.all(scale > 0.0)
    err = np.max(np.abs(dd - dref), axis=(0, 1)) / scale
    assert np.all(err < 1e-8), (name, key, err)


def test_stress_and_node_position_derivatives_match_complex_step(runs):
    """The accessors ``.stress`` and ``.node_positions`` of the two methods agree (scaled by the
    largest entry of each variable's column; measured <= 3e-11)."""
    name, _, _, direct, ref = runs
    body = "beam" if name == "pendulum" else "coupler"
    for acc in ("stress", "node_positions"):
        dd = getattr(direct, acc)(body)
        dref = getattr(ref, acc)(body)
        scale = np.max(np.abs(dref).reshape(-1, dref.shape[-1]), axis=0)
        err = np.max(np.abs(dd - dref).reshape(-1, dd.shape[-1]), axis=0) / scale
        assert np.all(err < 1e-8), (name, acc, err)


# ---------------------------------------------------------------- factorizations and refinement
def _count_factorizations(monkeypatch):
    """Count every numeric factorization and sparse direct solve, wherever bound (scipy itself
    and the names imported into the morphlab modules): SuperLU (``splu``, and the entry point
    the solver calls directly, ``morphlab.solve.linalg._gstrf``), the compiled sparse
    refactorization ``morphlab.solve.linalg.refactor`` (a call that returns -1: one that
    reports a failed pivot leaves no factors), the dense LU of small step matrices
    ``morphlab.solve.linalg.lu_factor``, and SciPy's ``spsolve``, ``factorized``, ``spilu``.
    The compiled Newton loop (``morphlab.kernels.newton``) factors where no counter can see
    it, so the solver iterates from Python in the tests below (``compiled_newton=False``, the
    same iterates), which take the sparse path (``dense_max=0``). A new row order for a
    matrix (``StepFactorization._new_row_order``) counts once: it factors the matrix with
    SuperLU to choose the order and again with the compiled refactorization in that order,
    so that the later steps and a compiled chunk continue from identical factors."""
    calls = {"n": 0, "mute": 0}

    def wrap(fn, done=lambda out: True):
        def counted(*args, **kwargs):
            out = fn(*args, **kwargs)
            calls["n"] += bool(done(out)) and not calls["mute"]
            return out
        return counted

    renew = morphlab.solve.linalg.StepFactorization._new_row_order

    def renew_counted(self, data):
        calls["n"] += not calls["mute"]
        calls["mute"] += 1
        try:
            return renew(self, data)
        finally:
            calls["mute"] -= 1

    monkeypatch.setattr(morphlab.solve.linalg.StepFactorization, "_new_row_order",
                        renew_counted)

    for mod in (scipy.sparse.linalg, morphlab.solve.linalg, morphlab.solve.superlu,
                morphlab.solve.stepper, morphlab.sensitivity.api, morphlab.sensitivity.direct):
        for name in ("splu", "_gstrf", "refactor", "lu_factor", "spsolve", "factorized",
                     "spilu"):
            fn = getattr(mod, name, None)
            if fn is not None:
                done = (lambda bad: bad < 0) if name == "refactor" else (lambda out: True)
                monkeypatch.setattr(mod, name, wrap(fn, done))
    return calls


@pytest.mark.parametrize("name", CASES)
def test_direct_uses_only_the_primal_factorizations(monkeypatch, name):
    build, p0, resp = responses_for(name)
    run = dict(RUN, dense_max=0, compiled_newton=False)
    calls = _count_factorizations(monkeypatch)
    plain = ml.simulate(build(p0), **run)
    n_plain = calls["n"]
    assert n_plain == plain.n_factorizations > 0  # the counter sees the solver's factorizations

    calls["n"] = 0
    sens = ml.sensitivities(build, p0, resp, method="direct", **run)
    # exact equality: the n_x right-hand sides of every step are solved with the primal's LU
    assert calls["n"] == n_plain
    assert sens.stats["n_factorizations"] == sens.result.n_factorizations == n_plain
    np.testing.assert_array_equal(sens.result.newton_iterations, plain.newton_iterations)

    calls["n"] = 0
    cs = ml.sensitivities(build, p0, resp, method="complex-step", **run)
    # contrast (shows the count can differ): the reference factors matrices of its own (the
    # real parts of its complex runs, one more iteration per step)
    assert calls["n"] == cs.stats["n_factorizations"] > n_plain


@pytest.mark.parametrize("name", CASES)
def test_refinement_residuals_at_round_off(name):
    """Where the lagged LU is refined against the exact matrix at the converged point, the
    relative residual ||b - J x|| / ||b|| must be at round-off: a backward-stable sparse LU
    solve of these ~20-40 unknowns leaves O(n eps ||J|| ||x|| / ||b||); measured <= 4e-14 on
    both models. 1e-12 leaves a factor 25."""
    build, p0, resp = responses_for(name)
    sens = ml.sensitivities(build, p0, resp, method=EXACT, **RUN)
    res = np.asarray(sens.stats["refinement_residual"])
    # the exact variant refines every step (one refinement, refine=1)
    assert res.size == sens.stats["refined_steps"] == sens.result.t.size
    assert np.all(np.isfinite(res)) and res.max() < 1e-12


@pytest.mark.parametrize("scheme", ["arnold-bruls", "paper"])
@pytest.mark.parametrize("name", CASES)
def test_chunking_does_not_change_the_sensitivities(monkeypatch, name, scheme):
    """The time loop runs compiled chunks of steps (``Settings.chunk_seconds`` of work each) and the
    sensitivities of a chunk's steps right after it: the same kernels on the same data,
    called at other times, so one step per chunk and the whole run in one chunk give the same
    numbers bit for bit, in both variants. For the sparse path as well (``dense_max=0``) and
    for the paper's weighting, whose residual also reads the state at the start of each step
    (for a chunk's first step that state belongs to the previous chunk)."""
    build, p0, resp = responses_for(name)
    for dense_max in (1000, 0):
        for method in (Direct(), EXACT):
            runs = []
            for seconds in (1e9, 0.0):  # the whole run in one chunk / a step per chunk
                runs.append(ml.sensitivities(build, p0, resp, method=method, store="all",
                                             scheme=scheme, dense_max=dense_max,
                                             chunk_seconds=seconds, **RUN))
            assert runs[1].gradients == runs[0].gradients
            for key in ("q", "v", "a", "lam"):
                np.testing.assert_array_equal(runs[1].state[key], runs[0].state[key])


@pytest.mark.parametrize("name", CASES)
def test_sensitivities_beside_the_primal_are_the_same_bits(monkeypatch, name):
    """With ``overlap`` the design data and each chunk's sensitivities are formed in the
    worker thread while the primal's next chunk runs: the same calls on the same data, in the
    same order, so the gradients and histories equal those formed in the caller's thread bit
    for bit, in both variants, on dense and sparse factors. Short chunks (4 steps) and no
    room for records in flight make the run hand over several chunks and wait for the worker
    whenever it is behind (``OVERLAP_BYTES`` 0)."""
    monkeypatch.setattr(morphlab.sensitivity.direct, "OVERLAP_STEPS", 4)
    monkeypatch.setattr(morphlab.sensitivity.direct, "OVERLAP_BYTES", 0)
    build, p0, resp = responses_for(name)
    for dense_max in (1000, 0):
        for reuse in (True, False):
            runs = [ml.sensitivities(build, p0, resp, store="all", dense_max=dense_max,
                                     method=Direct(reuse=reuse, overlap=overlap), **RUN)
                    for overlap in (False, True)]
            assert [r.stats["overlap"] for r in runs] == [False, True]
            assert runs[1].gradients == runs[0].gradients, (dense_max, reuse)
            for key in ("q", "v", "a", "lam"):
                np.testing.assert_array_equal(runs[1].state[key], runs[0].state[key])
            assert runs[1].timing["sensitivity"] > 0.0


@pytest.mark.parametrize("name", CASES)
def test_responses_by_their_vjp_equal_their_complex_evaluation(name):
    """Responses with a ``vjp`` are differentiated by the chain rule over the sensitivity
    histories, one pass each (``Direct(vjp=True)``, the default), instead of being evaluated
    on every variable's complex result: both are the same linearization of the same
    histories, summed in another order, so they agree to round-off (measured 2.5e-14 of the
    largest entry on the morphing study; 1e-11 leaves a margin for cancellation in the longer
    sums), in both variants. A response without a ``vjp`` makes the run evaluate them all."""
    build, p0, responses = responses_for(name)
    with_vjp = {k: f for k, f in responses.items() if hasattr(f, "vjp")}
    assert len(with_vjp) >= 3 and len(with_vjp) < len(responses)
    for reuse in (True, False):
        a, b = (ml.sensitivities(build, p0, with_vjp, method=Direct(reuse=reuse, vjp=v), **RUN)
                for v in (True, False))
        assert a.stats["responses_by_vjp"] and not b.stats["responses_by_vjp"]
        for r in with_vjp:
            assert a.values[r] == pytest.approx(b.values[r], rel=1e-13, abs=1e-300), r
            ga, gb = (np.array([g.gradients[r][v] for v in p0]) for g in (a, b))
            assert np.max(np.abs(ga - gb)) <= 1e-11 * np.max(np.abs(gb)), (r, ga, gb)
    mixed = ml.sensitivities(build, p0, responses, method="direct", **RUN)
    assert not mixed.stats["responses_by_vjp"]


def test_an_error_of_the_work_beside_is_raised_and_the_worker_freed():
    """The design data formed in the worker thread fail (a variable that changes the model's
    structure): the caller gets that error, not a hang, and the worker thread serves the next
    gradient."""
    build, p0, resp = responses_for("pendulum")

    def changes_structure(p):
        m = build(p)
        if np.iscomplexobj(p["extra"]) or p["extra"] != 1.0:
            m.add_rigid_body(mass=1.0, inertia=1.0, position=(0.0, 0.0), name="more")
        return m

    p = dict(p0, extra=1.0)
    with pytest.raises(ml.SensitivityError, match="'extra'"):
        ml.sensitivities(changes_structure, p, resp, method=Direct(overlap=True), **RUN)
    ok = ml.sensitivities(build, p0, resp, method=Direct(overlap=True), **RUN)
    ref = ml.sensitivities(build, p0, resp, method=Direct(overlap=False), **RUN)
    assert ok.gradients == ref.gradients


@pytest.mark.parametrize("name", CASES)
def test_steps_solved_from_python_give_the_sensitivities_of_compiled_steps(name):
    """With every step solved from Python (``compiled_newton=False``) the sensitivity steps
    run as the initial solve's do in a compiled run: the direct method keeps each step until
    the end of the run and forms its right-hand sides by the compiled chunk on a record of
    that step, the adjoint sweeps each step on such a record, and neither run has a compiled
    record to take the types from. The primal is the same bit for bit
    (``tests/test_kernels_newton.py``), the kernels are the same and the Python factor solves
    with the compiled loop's factors by the same kernels: the gradients are the same bit for
    bit, in both variants, on dense and sparse factors.

    A compiled step forms ``Dq``, ``Dv`` from the iteration at which the step before converged
    on, and once more at its last matrix's iterate when it converges sooner; the Python loop
    forms them at every iteration. Both cases have steps that converge sooner than the step
    before (checked below), so the second fill is compared too (the pendulum's also has
    steps that converge later)."""
    from morphlab.sensitivity import Adjoint

    build, p0, responses = responses_for(name)
    iters = np.diff(ml.simulate(build(dict(p0)), **RUN).newton_log_offsets)[1:]
    assert np.any(np.diff(iters) < 0), iters
    for dense_max in (1000, 0):
        for method in (Direct(), EXACT, Adjoint(), Adjoint(reuse=False)):
            resp = responses if isinstance(method, Direct) else {  # the adjoint's: with a vjp
                k: f for k, f in responses.items() if hasattr(f, "vjp")}
            fast, slow = (ml.sensitivities(build, p0, resp, method=method,
                                           dense_max=dense_max, compiled_newton=compiled,
                                           **RUN) for compiled in (True, False))
            assert slow.gradients == fast.gradients, (name, dense_max, method)


@pytest.mark.parametrize("name", CASES)
def test_reuse_variant_is_exact_to_the_newton_tolerance(name):
    """The default variant solves each step's sensitivities with the primal's last Newton
    matrix and blocks, formed at the iterate before the last correction: its error is of the
    order of that correction, bounded by the Newton tolerance (positions, relative to the
    model size). Against the exact variant, scaled as above: at tol = 1e-10 within 1e-5
    (measured <= 8e-7: the error of one step, ~tol, grows over the run with the
    sensitivities' own dynamics), and it falls with the tolerance (tol = 1e-12: ten times
    smaller at least; measured ~100: quadratic convergence makes the last correction far
    below the tolerance)."""
    build, p0, resp = responses_for(name)
    errors = []
    for tol in (1e-10, 1e-12):
        exact = ml.sensitivities(build, p0, resp, method=EXACT, tol=tol, **RUN)
        reuse = ml.sensitivities(build, p0, resp, method=Direct(), tol=tol, **RUN)
        worst = 0.0
        for r, g in exact.gradients.items():
            scaled = {v: abs(p0[v] * g[v]) for v in p0}
            largest = max(scaled.values())
            for v in p0:
                err = abs(p0[v] * (reuse.gradients[r][v] - g[v]))
                worst = max(worst, err / max(scaled[v], FLOOR * largest))
        errors.append(worst)
    assert errors[0] <= 1e-5, errors
    assert errors[1] <= 0.1 * errors[0], errors


def test_store_auto_keeps_the_histories_the_responses_read():
    """``store="auto"`` probes the responses: positions and a reaction need q and lam only; the
    gradients are the same as with every history kept (the others still advance, over two
    levels), and differentiating an unkept history afterwards names what to do."""
    build, p0, resp = responses_for("pendulum")
    auto = ml.sensitivities(build, p0, resp, method="direct", **RUN)
    assert sorted(auto.state) == ["lam", "q"]
    full = ml.sensitivities(build, p0, resp, method="direct", store="all", **RUN)
    for r in resp:
        for v in p0:
            assert auto.gradients[r][v] == full.gradients[r][v]
    np.testing.assert_array_equal(auto.state["q"], full.state["q"])
    with pytest.raises(ml.SensitivityError, match="store='all'"):
        auto.derivative(lambda res: res.v[-1])
    with pytest.raises(ml.SensitivityError, match="store"):
        ml.sensitivities(build, p0, resp, method="direct", store=("q", "x"), **RUN)


@pytest.mark.parametrize("scheme", ["arnold-bruls", "paper"])
def test_linear_variables_take_real_products(monkeypatch, scheme):
    """A variable whose changed data the residual is linear in (``Field.linear``: E, the
    coupler's thickness and density change its invariants and element matrices, the crank's
    mass its invariants, the torque and force magnitudes their loads; the data themselves
    may depend on the variable in any way) takes the linear path of the pseudo-loads: the
    kernels evaluated in real arithmetic with the derivative data in place of the data. The
    others (x_D moves the geometry and the initial state; the damping coefficient ``beta``
    multiplies the stiffness, bilinear) take the perturbed path, a residual of complex
    data. Forcing every variable through the perturbed
    path must give the same gradients: the two compute the same products in another order,
    so they agree to round-off of the recursion (1e-12 of the response's largest logarithmic
    sensitivity), for the direct method, its forward-difference variant (the perturbed path
    then carries the rounding of R(p + h) - R(p), ~5e-11 relative: 1e-9) and the adjoint,
    both weightings."""
    from morphlab.sensitivity import designs

    build, p0, every = responses_for("mechanism")
    p0 = {**p0, "beta": 1e-4}
    resp = {k: every[k] for k in ("displacement", "ks_stress", "rms_error")}  # with a vjp
    linear_vars = []
    real_items, real_fields = designs._items, designs._linear_fields

    def spy(sys0, ch):
        items, linear, flex = real_items(sys0, ch)
        linear_vars.append(all(linear.get(k, True) for k in items))
        return items, linear, flex

    monkeypatch.setattr(designs, "_items", spy)
    for method, tol in ((Direct(reuse=False), 1e-12),
                        (Direct(reuse=False, partials="forward-difference"), 1e-9),
                        (ml.Adjoint(reuse=False), 1e-12)):
        runs = {}
        for linear in (True, False):
            monkeypatch.setattr(designs, "_linear_fields",
                                real_fields if linear else (lambda: set()))
            linear_vars.clear()
            runs[linear] = ml.sensitivities(build, p0, resp, method=method, scheme=scheme,
                                            **RUN)
            taken = {v for v, lin in zip(p0, linear_vars) if lin}
            expected = {"E", "t", "rho", "m_crank", "M", "F"} if linear else set()
            assert taken == expected, (method, taken)
        for r in runs[True].gradients:
            a, b = runs[True].gradients[r], runs[False].gradients[r]
            scale = max(abs(p0[v] * b[v]) for v in p0)  # logarithmic sensitivities
            for v in p0:
                assert abs(p0[v] * (a[v] - b[v])) <= tol * scale, (method, r, v, a[v], b[v])


#: The pseudo-load data's fields that serve the perturbed path alone.
PERTURBED_FIELDS = ("MN", "DN", "VN", "D0", "TN", "tn", "pert", "WN")


@pytest.mark.parametrize("scheme", ["arnold-bruls", "paper"])
def test_a_design_of_linear_variables_alone_has_no_perturbed_path(monkeypatch, scheme):
    """When every variable takes the linear path, the pseudo-load data carry no perturbed
    path (``MN`` and its data None), so the kernels compile none of that path's code and
    unbox none of its arrays. Its gradients equal those with every variable forced through
    the perturbed path (then a complex system) to the round-off of the recursion (1e-12 of
    the largest logarithmic sensitivity, as in the test above), for the direct method and
    the adjoint, both weightings."""
    from morphlab.sensitivity import designs, strategies

    build, p0, every = responses_for("mechanism")
    chosen = ["E", "t", "m_crank", "M"]
    resp = {k: every[k] for k in ("displacement", "ks_stress", "rms_error")}
    made = []
    real_pseudo, real_fields = strategies.pseudo_data, designs._linear_fields

    def spy(*args):
        made.append(real_pseudo(*args))
        return made[-1]

    monkeypatch.setattr(strategies, "pseudo_data", spy)
    for method in (Direct(reuse=False), ml.Adjoint(reuse=False)):
        runs = {}
        for linear in (True, False):
            monkeypatch.setattr(designs, "_linear_fields",
                                real_fields if linear else (lambda: set()))
            made.clear()
            runs[linear] = ml.sensitivities(build, p0, resp, method=method, scheme=scheme,
                                            variables=chosen, **RUN)
            (ps,) = made
            if linear:
                assert ps.MN is None
                assert all(getattr(ps, f) is None for f in PERTURBED_FIELDS), ps
            else:
                assert ps.MN is not None and ps.DN.dtype == np.complex128
        for r in runs[True].gradients:
            a, b = runs[True].gradients[r], runs[False].gradients[r]
            scale = max(abs(p0[v] * b[v]) for v in chosen)
            assert scale > 0
            for v in chosen:
                assert abs(p0[v] * (a[v] - b[v])) <= 1e-12 * scale, (method, r, v, a[v], b[v])


def test_a_variable_of_a_load_profile_alone_gets_its_time_derivative():
    """The torque's rate ``r`` enters only its time profile (no compiled array changes): its
    derivative comes from the time tables, which a perturbed design evaluates only where its
    time constants or profiles differ from the nominal's. The mass changes neither (its
    tables are not evaluated), the torque's magnitude the time constants. Each against the
    whole-run complex step (the exact variant: round-off; 1e-9 of the largest entry)."""
    from morphlab.compile.compile import compile_model
    from morphlab.sensitivity.designs import compile_perturbed, same_time_inputs

    def build(p):
        m = ml.Model(gravity=(0.0, -9.81e3))
        b = m.add_rigid_body(mass=p["m"], inertia=0.2, position=(0.0, 10.0), name="b")
        m.add_revolute(m.ground, b, at=(0.0, 0.0), name="A")
        m.add_torque(b, p["M"], profile=ml.Polynomial((0.0, p["r"])), name="T")
        return m

    p0 = {"m": 2e-4, "M": 30.0, "r": 50.0}
    sys0 = compile_model(build(p0))
    same = {v: same_time_inputs(sys0, compile_perturbed(build, p0, v, 1e-20j, sys0))
            for v in p0}
    assert same == {"m": True, "M": False, "r": False}
    resp = {"angle": lambda r: r.dof("b.theta")[-1]}
    kw = dict(t_end=0.05, dt=1e-3)
    got = ml.sensitivities(build, p0, resp, method=EXACT, **kw).gradients["angle"]
    ref = ml.sensitivities(build, p0, resp, method="complex-step", **kw).gradients["angle"]
    scale = max(abs(g) for g in ref.values())
    assert all(abs(ref[v]) > 1e-6 * scale for v in p0)  # every variable moves the angle
    for v in p0:
        assert abs(got[v] - ref[v]) <= 1e-9 * scale, (v, got[v], ref[v])
