"""Design optimization (morphlab.studies.optimize) on problems whose optimum is known.

Analytic problems through ``Problem.from_function`` (variables scaled to [0, 1] by their
bounds, so the tolerances below are in those scaled units unless said otherwise):

* a convex quadratic ``(a-3)² + 2(b+1)² + (a-3)(b+1)/2`` on ``a in [0, 2]``, ``b in [-5, 5]``:
  the unconstrained minimum (3, -1) is cut off by ``a <= 2``; at ``a = 2`` the b-stationarity
  ``4(b+1) - 1/2 = 0`` gives ``b = -7/8``. Bound multiplier ``-df/da = 31/16`` per unit of a;
* Rosenbrock ``(1-x)² + 100(y-x²)²`` with ``g = x + 2(y - 1/4)² <= 1/2``: every feasible point
  has ``x <= 1/2``, so ``f >= (1-x)² >= 1/4``, with equality only at ``(1/2, 1/4)`` (on the
  valley ``y = x²`` and on the constraint): the unique minimiser, a KKT point with the
  multiplier ``mu = 2(1 - 1/2) = 1`` (strictly active);
* ``x + y`` on the circle ``x² + y² = 2`` (equality): ``(-1, -1)``, multiplier 1/2;
* ``(x-c)² + (y-c)²`` with ``1 <= x + y <= 2`` (one constraint, both sides): the projection
  of (c, c) on the band, ``(1, 1)`` for c = 2 (upper side active) and ``(1/2, 1/2)`` for
  c = -1 (lower side).

Tolerances come from the optimizers' stopping rules. SLSQP (``ftol = 1e-12``) stops when the
objective changes by less than ``ftol``; with the smallest reduced Hessian of these problems
``h = 16`` in scaled variables (the circle: ``2 x 1/2 x 4²``) that leaves at most
``sqrt(2 ftol / h) = 3.5e-7``: we assert 1e-6. trust-constr is an interior-point method that
stops on its Lagrangian-gradient test (``gtol = 1e-10``) with an active inequality at a slack
``s = mu_barrier / lambda`` (``lambda`` the multiplier in scaled variables): we assert
``2 mu_barrier / lambda + 1e-8`` with its final barrier parameter.

One small simulation problem (a cantilever, ``tests/models.py``) compares exact gradients,
finite differences and a derivative-free method on the same optimum.
"""

import io
import re
from contextlib import redirect_stdout

import numpy as np
import pytest
from matplotlib.figure import Figure
from models import tip_loaded_cantilever
from problems import rosenbrock, rosenbrock_problem

import morphlab as ml
from morphlab.studies import Constraint, OptimizationResult, Problem, optimize

SLSQP = {"ftol": 1e-12, "maxiter": 300}
TRUST = {"gtol": 1e-10, "xtol": 1e-12, "barrier_tol": 1e-12, "maxiter": 3000}
OPTIONS = {"SLSQP": SLSQP, "trust-constr": TRUST}
SLSQP_TOL = 1e-6  # sqrt(2 ftol / h), h = 16 (module docstring), with a factor 3
# the cantilever problem (tests/models.py)
SETTINGS = {"t_end": 0.012, "dt": 2.5e-4}  # two bending periods in 48 steps
TIP = (100.0, 0.0)
TARGET_DESIGN = {"t": 2.2, "F": 1.3}
STRESS_LIMIT = 25.0  # MPa, below the KS stress of the target design (27.2): active


class Counted:
    """A function problem that counts and logs its calls."""

    def __init__(self, fn):
        self.fn, self.calls, self.log = fn, 0, []

    def __call__(self, p):
        self.calls += 1
        out = self.fn(p)
        self.log.append((dict(p), out[0]))
        return out


def quadratic(p):
    a, b = p["a"], p["b"]
    f = (a - 3) ** 2 + 2 * (b + 1) ** 2 + 0.5 * (a - 3) * (b + 1)
    return {"f": f}, {"f": {"a": 2 * (a - 3) + 0.5 * (b + 1), "b": 4 * (b + 1) + 0.5 * (a - 3)}}


def circle(p):
    x, y = p["x"], p["y"]
    return {"f": x + y, "h": x * x + y * y}, {"f": {"x": 1.0, "y": 1.0},
                                              "h": {"x": 2 * x, "y": 2 * y}}


def quadratic_problem(fn=quadratic):
    return Problem.from_function(fn, {"a": 0.5, "b": 4.0}, "f",
                                 bounds={"a": (0.0, 2.0), "b": (-5.0, 5.0)})


def scaled_error(problem, design, exact):
    return float(np.max(np.abs(problem.to_x(design) - problem.to_x(exact))))


def trust_tol(result, multiplier):
    """Interior-point slack of the active inequality, ``mu / lambda``, times 2, + 1e-8."""
    return 2.0 * result.info["scipy"]["barrier_parameter"] / multiplier + 1e-8


@pytest.mark.parametrize("method", ["SLSQP", "trust-constr"])
def test_convex_quadratic_with_an_active_bound(method):
    pr = quadratic_problem()
    res = optimize(pr, method, options=OPTIONS[method])
    exact = {"a": 2.0, "b": -0.875}
    # multiplier of the bound a <= 2 in scaled variables: 31/16 per unit a x range 2
    tol = SLSQP_TOL if method == "SLSQP" else trust_tol(res, 31 / 8)
    assert res.status == "converged" and res.feasible
    assert scaled_error(pr, res.design, exact) < tol
    # f* = 1 + 2/64 - 1/16; off the bound by the scaled slack s, f - f* = 31/8 s + O(s²)
    assert abs(res.objective - 0.96875) <= 31 / 8 * tol + 1e-14


@pytest.mark.parametrize("method", ["SLSQP", "trust-constr"])
def test_rosenbrock_with_an_active_nonlinear_constraint(method):
    pr = rosenbrock_problem()
    res = optimize(pr, method, options=OPTIONS[method])
    # multiplier mu = 1 per unit g; dg/dx = 1 and x spans 4: 4 per scaled unit
    tol = SLSQP_TOL if method == "SLSQP" else trust_tol(res, 4.0)
    assert res.status == "converged" and res.feasible
    assert scaled_error(pr, res.design, {"x": 0.5, "y": 0.25}) < tol
    assert res.values["g"] == pytest.approx(0.5, abs=4 * tol)  # active: g = x + O(dy²)


@pytest.mark.filterwarnings("ignore:delta_grad == 0.0")  # BFGS on the linear objective
@pytest.mark.parametrize("method", ["SLSQP", "trust-constr"])
def test_equality_constraint(method):
    pr = Problem.from_function(circle, {"x": 0.5, "y": -1.5}, "f",
                               constraints=[Constraint("h", equals=2.0)],
                               bounds={"x": (-2.0, 2.0), "y": (-2.0, 2.0)})
    res = optimize(pr, method, options=OPTIONS[method])
    # no inequality: both stop on KKT residuals <= 1e-10, distance <= 1e-10 / h (h = 16)
    assert res.status == "converged" and res.feasible
    assert scaled_error(pr, res.design, {"x": -1.0, "y": -1.0}) < SLSQP_TOL
    assert abs(res.values["h"] - 2.0) < 1e-6  # feasibility_tol of the result


@pytest.mark.parametrize("c, exact", [(2.0, 1.0), (-1.0, 0.5)])
@pytest.mark.parametrize("method", ["SLSQP", "COBYQA"])
def test_two_sided_constraint(method, c, exact):
    def fn(p):
        x, y = p["x"], p["y"]
        return ({"f": (x - c) ** 2 + (y - c) ** 2, "s": x + y},
                {"f": {"x": 2 * (x - c), "y": 2 * (y - c)}, "s": {"x": 1.0, "y": 1.0}})

    pr = Problem.from_function(fn, {"x": 0.7, "y": 0.6}, "f",
                               constraints=[Constraint("s", lower=1.0, upper=2.0)],
                               bounds={"x": (-3.0, 3.0), "y": (-3.0, 3.0)})
    options = SLSQP if method == "SLSQP" else {"final_tr_radius": 1e-9}
    res = optimize(pr, method, options=options)
    # COBYQA: its quadratic model of this quadratic objective is exact, so the last
    # trust-region radius (1e-9) bounds the error; 1e-6 leaves room for the linear constraint
    assert res.status == "converged" and res.feasible
    assert scaled_error(pr, res.design, {"x": exact, "y": exact}) < SLSQP_TOL


@pytest.mark.parametrize("method", ["SLSQP", "trust-constr"])
def test_one_run_per_design_serves_objective_gradient_and_constraints(method):
    fn = Counted(rosenbrock)
    res = optimize(rosenbrock_problem(fn), method, options=OPTIONS[method])
    hist = res.history
    requests = hist.column("evaluations", "design")
    new = hist.column("evaluations", "new")
    distinct = {row.tobytes() for row in requests}
    # one call of fn per distinct design, whatever scipy asked there
    assert fn.calls == res.n_runs == new.sum() == len(distinct)
    # scipy asked for objective, gradient, constraints and their Jacobian: >= 2 requests per
    # design on average (a line-search point without gradient costs fun + constraints)
    assert len(requests) >= 2 * fn.calls
    assert res.n_simulations == res.n_runs


def test_finite_difference_gradients_cost_n_plus_one_calls():
    fn = Counted(lambda p: (rosenbrock(p)[0], None))
    res = optimize(rosenbrock_problem(fn), "SLSQP", gradient="finite-difference",
                   options=SLSQP)
    assert fn.calls == 3 * res.n_runs == res.n_simulations  # n + 1 = 3 per design
    # forward differences (relative step 1e-6): gradient error ~1e-6 * f'' ~ 1e-4 absolute
    # near x = 1/2 (f'' ~ 200), shifting the optimum by ~1e-4 / h_reduced (3264): 1e-6
    assert scaled_error(rosenbrock_problem(), res.design, {"x": 0.5, "y": 0.25}) < 1e-5


def test_budget_stops_with_the_best_feasible_design():
    fn = Counted(rosenbrock)
    res = optimize(rosenbrock_problem(fn), "SLSQP", max_runs=5, options=SLSQP)
    assert res.status == "budget" and "max_runs=5" in res.message
    assert fn.calls == res.n_runs == 5
    feasible = [(v["f"], p) for p, v in fn.log if v["g"] <= 0.5 + 1e-6]
    f_best, p_best = min(feasible, key=lambda t: t[0])
    assert res.feasible and res.objective == f_best
    assert res.design == p_best


def test_time_budget():
    fn = Counted(rosenbrock)
    res = optimize(rosenbrock_problem(fn), "COBYLA", max_time=1e-9)
    # the start design is always run; the budget stops the next run
    assert res.status == "budget" and fn.calls == 1
    assert res.design == {"x": -1.2, "y": 1.0}


def test_a_failing_run_stops_with_the_best_design_so_far():
    def fn(p):
        if p["a"] > 1.5:
            raise ml.ConvergenceError("Newton did not converge")
        return quadratic(p)

    res = optimize(quadratic_problem(Counted(fn)), "SLSQP", options=SLSQP)
    assert res.status == "error" and "Newton did not converge" in res.message
    failed = re.search(r"the run at \{'a': ([-+.e\d]+), 'b': ", res.message)
    assert failed and float(failed.group(1)) > 1.5  # the message names the failing design
    best = min((r for r in res.history.evaluations if r["new"]), key=lambda r: r["objective"])
    assert res.objective == best["objective"] and res.design["a"] <= 1.5


def test_save_load_round_trip(tmp_path):
    res = optimize(rosenbrock_problem(), "SLSQP", max_runs=8, options=SLSQP)
    res.save(tmp_path / "opt.npz")
    back = OptimizationResult.load(tmp_path / "opt.npz")
    for name in ("design", "values", "objective", "feasible", "max_violation", "status",
                 "message", "n_runs", "n_simulations", "wall_time", "optimizer", "gradient",
                 "info"):
        assert getattr(back, name) == getattr(res, name), name
    assert back.history.evaluations == res.history.evaluations
    assert back.history.iterations == res.history.iterations


def test_resume_continues_history_and_reaches_the_optimum(tmp_path):
    first = optimize(rosenbrock_problem(), "SLSQP", max_runs=6, options=SLSQP)
    assert first.status == "budget"
    first.save(tmp_path / "first.npz")
    fn = Counted(rosenbrock)
    res = optimize(rosenbrock_problem(fn), "SLSQP", resume=tmp_path / "first.npz",
                   options=SLSQP)
    assert res.status == "converged"
    assert scaled_error(rosenbrock_problem(), res.design, {"x": 0.5, "y": 0.25}) < SLSQP_TOL
    assert res.n_runs == first.n_runs + fn.calls  # counted across both
    assert fn.log[0][0] != first.design  # the restart design came from the saved history
    n = len(first.history.evaluations)
    assert res.history.evaluations[:n] == first.history.evaluations
    its = res.history.column("iterations", "iteration")
    assert np.array_equal(its, np.arange(len(its)))  # numbered on from the first part


def test_progress_line_per_iteration():
    out = io.StringIO()
    with redirect_stdout(out):
        res = optimize(quadratic_problem(), "SLSQP", progress=True, options=SLSQP)
    lines = out.getvalue().splitlines()
    assert len(lines) == len(res.history.iterations)
    assert re.match(r"iter +0 +objective ", lines[0])
    seen = []
    optimize(quadratic_problem(), "SLSQP", progress=seen.append, options=SLSQP)
    assert [r["iteration"] for r in seen] == list(range(len(seen)))


@pytest.mark.parametrize("make, match", [
    (lambda: Constraint("g"), "no limit"),
    (lambda: Constraint("g", upper=1.0, equals=0.0), "excludes"),
    (lambda: Constraint("g", lower=2.0, upper=1.0), "lower 2.0 > upper"),
    (lambda: optimize(Problem.from_function(rosenbrock, {"x": 0.0, "y": 0.0}, "q", bounds={
        "x": (-1, 1), "y": (-1, 1)})), r"fn returned no value of \['q'\]"),
    (lambda: Problem(tip_loaded_cantilever, {"t": 2.0, "F": 1.0}, {"f": lambda r: 0.0}, "q",
                     bounds={"t": (1, 3), "F": (0, 2)}, settings=SETTINGS), "objective 'q'"),
    (lambda: Problem.from_function(rosenbrock, {"x": 0.0, "y": 0.0}, "f",
                                   bounds={"x": (-1, 1)}), "'y' needs finite bounds"),
    (lambda: Problem.from_function(rosenbrock, {"x": 2.0, "y": 0.0}, "f",
                                   bounds={"x": (-1, 1), "y": (-1, 1)}), "within bounds"),
    (lambda: Problem(tip_loaded_cantilever, {"t": 2.0, "F": 1.0}, {"f": lambda r: 0.0}, "f",
                     bounds={"t": (1, 3), "F": (0, 2)},
                     settings=dict(SETTINGS, newton="modified")), "newton must be 'full'"),
    (lambda: Problem(tip_loaded_cantilever, {"t": 2.0, "F": 1.0}, {"f": lambda r: 0.0}, "f",
                     bounds={"t": (1, 3), "F": (0, 2)}, settings=dict(SETTINGS, tol=2.0)),
     "tol must be"),
    (lambda: Problem(tip_loaded_cantilever, {"t": 2.0, "F": 1.0}, {"f": lambda r: 0.0}, "f",
                     bounds={"t": (1, 3), "F": (0, 2)}, settings={"dt": 1e-3}), "'t_end'"),
    (lambda: optimize(rosenbrock_problem(), "Nelder-Mead"), "no constraints"),
    (lambda: optimize(rosenbrock_problem(), "BFGS"), "unknown optimizer"),
    (lambda: optimize(rosenbrock_problem(lambda p: (rosenbrock(p)[0], None)), "SLSQP"),
     "no gradients"),
])
def test_bad_input_is_a_typed_error(make, match):
    with pytest.raises(ml.MorphlabError, match=match):
        make()


def test_plots_draw_the_history():
    import morphlab.plots as mp

    res = optimize(rosenbrock_problem(), "SLSQP", options=SLSQP)
    fig = mp.optimization_history(res)
    assert isinstance(fig, Figure)
    ax_obj = fig.axes[0]
    k = res.history.column("iterations", "iteration")
    assert np.array_equal(ax_obj.get_lines()[0].get_ydata(),
                          res.history.column("iterations", "objective"))
    assert np.array_equal(ax_obj.get_lines()[0].get_xdata(), k)
    fig = mp.design_path(res)
    x_line = fig.axes[0].get_lines()[0]
    assert np.allclose(x_line.get_ydata(), (res.history.column("iterations", "design")[:, 0]
                                            + 2.0) / 4.0, rtol=0, atol=1e-15)
    with pytest.raises(ml.ModelError, match="not design variables"):
        mp.design_path(res, variables=["z"])


# ---------------------------------------------------------------- a simulation problem


@pytest.fixture(scope="module")
def cantilever_problem():
    target = ml.simulate(tip_loaded_cantilever(TARGET_DESIGN), **SETTINGS) \
        .point_positions("beam", TIP)[:, 1].copy()

    def tip_error(res):  # mean square tip-deflection error against the target history [mm²]
        d = res.point_positions("beam", TIP)[:, 1] - target
        return np.mean(d * d)

    responses = {"error": tip_error, "stress": ml.responses.ks_max_stress("beam", 2.0)}
    return Problem(tip_loaded_cantilever, {"t": 1.8, "F": 0.8}, responses, "error",
                   constraints=[Constraint("stress", upper=STRESS_LIMIT)],
                   bounds={"t": (1.5, 3.0), "F": (0.5, 2.0)}, settings=SETTINGS,
                   normalize=True)


def simulations_to_reach(res, f_target):
    """Simulations spent until the first feasible run with objective <= f_target."""
    spent = 0
    for rec in res.history.evaluations:
        spent += rec["simulations"]
        if rec["new"] and rec["objective"] <= f_target and rec["max_violation"] <= 1e-6:
            return spent
    return None


def test_simulation_problem_exact_gradients_beat_derivative_free(cantilever_problem):
    pr = cantilever_problem
    exact = optimize(pr, "SLSQP", options={"ftol": 1e-10})
    fd = optimize(pr, "SLSQP", gradient="finite-difference", options={"ftol": 1e-10})
    free = optimize(pr, "COBYLA", options={"rhobeg": 0.1, "tol": 1e-7})
    for res in (exact, fd, free):
        assert res.status == "converged" and res.feasible, res
    assert exact.n_simulations == exact.n_runs and fd.n_simulations == 3 * fd.n_runs
    # the stress limit is active at the optimum (so the optimum is not the target design)
    assert exact.values["stress"] == pytest.approx(STRESS_LIMIT, abs=1e-5)
    # the same optimum from exact and forward-difference gradients: the difference gradient
    # error (relative step 1e-6) moves it by ~1e-6 relative; SLSQP's ftol = 1e-10 on the
    # normalised objective leaves ~sqrt(2e-10) = 1.4e-5 in scaled variables
    assert scaled_error(pr, fd.design, exact.design) < 5e-5
    # COBYLA's last trust-region radius is 1e-7 (scaled); its linear models leave the design
    # within a small multiple of it: 100 x
    assert scaled_error(pr, free.design, exact.design) < 1e-5
    # KKT at the optimum, from an independent sensitivity run: the objective gradient is
    # antiparallel to the active constraint's; SLSQP's Lagrangian-gradient test (ftol) leaves
    # an angle ~ ftol / |grad f| (normalised) far below the 1.4e-3 rad that 1e-6 allows
    s = ml.sensitivities(tip_loaded_cantilever, exact.design, pr.responses, **SETTINGS)
    ge = np.array([s.gradients["error"][v] for v in ("t", "F")]) * pr.factor
    gs = np.array([s.gradients["stress"][v] for v in ("t", "F")]) * pr.factor
    cos = ge @ gs / np.linalg.norm(ge) / np.linalg.norm(gs)
    assert cos == pytest.approx(-1.0, abs=1e-6)
    # cost to come within 0.1 % of the optimal objective
    f_target = exact.objective * (1 + 1e-3)
    n_exact = simulations_to_reach(exact, f_target)
    n_free = simulations_to_reach(free, f_target)
    assert n_exact is not None and n_free is not None
    assert n_exact < n_free


# ---------------------------------------------------------------- resume, result, stop
def _repeats(first, fn_log, variables):
    """Designs of a resumed run's new calls that the first part had already evaluated."""
    old = first.history.column("evaluations", "design")[
        first.history.column("evaluations", "new").astype(bool)]
    count = 0
    for p, _ in fn_log:
        v = np.array([p[k] for k in variables])
        count += bool(np.any(np.all(np.abs(old - v) <= 1e-12 * np.maximum(1, np.abs(v)),
                                    axis=1)))
    return count


@pytest.mark.parametrize("method", ["COBYLA", "COBYQA"])
def test_resume_runs_no_design_twice(method, tmp_path):
    """Issue 38: a resumed method that retraces its first designs (COBYLA's and COBYQA's
    initial simplex around the restart design) found them missing from the cache by a 1e-17
    rounding of the optimizer's vector and ran them again (6 and 2 of 162 here)."""
    repeats, calls = 0, 0
    for budget in range(1, 7):
        for kw in ({}, {"scale": {"x": 0.3, "y": 0.7}}, {"normalize": True}):
            first = optimize(rosenbrock_problem(**kw), method, max_runs=budget)
            first.save(tmp_path / "first.npz")
            fn = Counted(rosenbrock)
            optimize(rosenbrock_problem(fn, **kw), method, max_runs=budget + 6,
                     resume=tmp_path / "first.npz")
            repeats += _repeats(first, fn.log, ["x", "y"])
            calls += fn.calls
    assert calls > 50 and repeats == 0


def test_resume_from_a_file_without_optimizer_vectors(tmp_path):
    """Files written before the optimizer's vector was recorded: the cache is keyed by the
    design's vector, and a vector within 4 ulp of a cached one is a hit."""
    first = optimize(rosenbrock_problem(scale={"x": 0.3, "y": 0.7}), "COBYLA", max_runs=4)
    for rec in first.history.evaluations:
        del rec["x"]
    first.save(tmp_path / "old.npz")
    fn = Counted(rosenbrock)
    optimize(rosenbrock_problem(fn, scale={"x": 0.3, "y": 0.7}), "COBYLA", max_runs=10,
             resume=tmp_path / "old.npz")
    assert fn.calls == 6 and _repeats(first, fn.log, ["x", "y"]) == 0


@pytest.mark.parametrize("method", ["SLSQP", "trust-constr"])
@pytest.mark.parametrize("normalize", [False, True])
def test_result_fields_as_scipy_users_expect(method, normalize):
    pr = rosenbrock_problem(normalize=normalize)
    res = optimize(pr, method, options=OPTIONS[method])
    assert res.success and res.fun == res.objective
    np.testing.assert_array_equal(res.x, [res.design["x"], res.design["y"]])
    x, y = res.x
    np.testing.assert_allclose(res.jac, list(rosenbrock({"x": x, "y": y})[1]["f"].values()),
                               rtol=1e-12)
    # d f*/d(upper of g) = -mu = -1 (module docstring), in the problem's units whatever the
    # scaling; the optimizers' own tolerances (1e-6 on the design) bound its error
    assert res.multipliers["g <= 0.5"] == pytest.approx(-1.0, abs=1e-4)
    assert res.active == ["g <= 0.5"]
    assert res.nit >= 1 and res.nfev >= 1


def test_bound_and_equality_multipliers():
    res = optimize(quadratic_problem(), "trust-constr", options=TRUST)
    # f*(hi) with a = hi: d f*/d hi = 2 (a - 3) + (b + 1)/2 = -31/16 at a = 2, b = -7/8
    assert res.multipliers["a <= 2"] == pytest.approx(-31 / 16, abs=1e-5)
    assert res.multipliers["a >= 0"] == 0.0
    assert "a <= 2" in res.active and "b >= -5" not in res.active
    pr = Problem.from_function(circle, {"x": 0.5, "y": -1.5}, "f",
                               constraints=[Constraint("h", equals=2.0)],
                               bounds={"x": (-2.0, 2.0), "y": (-2.0, 2.0)}, normalize=True)
    res = optimize(pr, "SLSQP", options=SLSQP)
    # f* = -sqrt(2 c) on x² + y² = c: d f*/dc = -1/sqrt(2c) = -1/2
    assert res.multipliers["h == 2"] == pytest.approx(-0.5, abs=1e-5)
    assert res.active == ["h == 2"]


def test_result_fields_survive_save_and_load(tmp_path):
    res = optimize(rosenbrock_problem(), "SLSQP", options=SLSQP)
    res.save(tmp_path / "r.npz")
    back = OptimizationResult.load(tmp_path / "r.npz")
    np.testing.assert_array_equal(back.jac, res.jac)
    for name in ("multipliers", "active", "nit", "nfev", "njev"):
        assert getattr(back, name) == getattr(res, name), name


@pytest.mark.parametrize("at", [0, 2])
def test_a_progress_that_raises_stopiteration_reads_stopped(at):
    def stop(rec):
        if rec["iteration"] == at:
            raise StopIteration("enough")

    res = optimize(rosenbrock_problem(), "SLSQP", progress=stop, options=SLSQP)
    assert res.status == "stopped" and not res.success
    assert res.message == f"stopped by progress at iteration {at}: enough"
    assert len(res.history.iterations) == at + 1 and res.feasible is not None


# ---------------------------------------------------------------- multi-start
def two_wells(p):
    x = p["x"]
    return {"f": (x * x - 1.0) ** 2 + 0.3 * x}, {"f": {"x": 4 * x * (x * x - 1.0) + 0.3}}


def test_multistart_finds_the_global_minimum_on_any_executor():
    from morphlab.studies import multistart

    pr = Problem.from_function(two_wells, {"x": 1.5}, "f", bounds={"x": (-2.0, 2.0)})
    local = optimize(pr, "SLSQP", options=SLSQP)
    serial = multistart(pr, 4, "SLSQP", executor="serial", seed=1, options=SLSQP)
    pool = multistart(pr, 4, "SLSQP", seed=1, options=SLSQP)  # a local process pool
    # the global minimiser of (x² - 1)² + 0.3 x: the root of 4x³ - 4x + 0.3 near -1.04
    roots = np.roots([4.0, 0.0, -4.0, 0.3])
    x_global = float(np.min(roots.real))
    assert local.design["x"] > 0  # from x0 = 1.5 SLSQP stays in the right well
    assert serial.best.design["x"] == pytest.approx(x_global, abs=SLSQP_TOL * 4)
    assert [r.design for r in serial.results] == [r.design for r in pool.results]
    for r, q in zip(serial.results, pool.results):  # the same evaluations, bit for bit
        for key in ("design", "values", "x"):
            assert [e[key] for e in r.history.evaluations] == \
                [e[key] for e in q.history.evaluations]
    assert serial.errors == [""] * 4 and "start" in repr(serial)


# ---------------------------------------------------------------- robust design
def drift(p):
    """r = (x - 2)² + e x: at e = 0 the std under e ~ (0, σ) is σ |x|."""
    x, e = p["x"], p["e"]
    return {"r": (x - 2.0) ** 2 + e * x}, {"r": {"x": 2 * (x - 2.0) + e, "e": x}}


def test_robust_objective_closed_form():
    sigma, k = 0.4, 3.0
    pr = Problem.from_function(drift, {"x": 0.5, "e": 0.0}, "r", variables=["x"],
                               bounds={"x": (0.1, 3.0)},
                               robust={"std": {"e": sigma}, "k": k})
    res = optimize(pr, "SLSQP", options=SLSQP)
    # J = (x - 2)² + k σ x for x > 0: minimum at x = 2 - k σ / 2 = 1.4
    assert res.status == "converged" and pr.objective == "r.robust"
    assert res.design["x"] == pytest.approx(2.0 - k * sigma / 2, abs=3e-6 * 2.9)
    assert res.values["r.std"] == pytest.approx(sigma * res.design["x"], rel=1e-12)
    plain = optimize(Problem.from_function(drift, {"x": 0.5, "e": 0.0}, "r", variables=["x"],
                                           bounds={"x": (0.1, 3.0)}), "SLSQP", options=SLSQP)
    assert plain.design["x"] == pytest.approx(2.0, abs=3e-6 * 2.9)
    assert res.n_simulations == 2 * res.n_runs  # 1 + n gradient calls per design


def test_robust_gradient_of_a_simulation_against_central_differences():
    std = {"t": 0.02, "F": 0.05}
    pr = Problem(tip_loaded_cantilever, {"t": 2.0, "F": 1.0},
                 {"stress": ml.responses.ks_max_stress("beam", 2.0)}, "stress",
                 bounds={"t": (1.5, 3.0), "F": (0.5, 2.0)}, settings=SETTINGS,
                 robust={"std": std, "k": 2.0})
    values, grads, n_sim = pr.evaluate(dict(pr.p0), "exact")
    assert n_sim == 3
    s = ml.sensitivities(tip_loaded_cantilever, pr.p0, pr.responses, **SETTINGS)
    sd = np.sqrt(sum((s.gradients["stress"][v] * std[v]) ** 2 for v in std))
    assert values["stress.std"] == pytest.approx(sd, rel=1e-12)  # FOSM of the same run
    for v in ("t", "F"):
        h = 1e-4 * pr.p0[v]
        up = pr.evaluate({**pr.p0, v: pr.p0[v] + h}, None)[0]["stress.robust"]
        down = pr.evaluate({**pr.p0, v: pr.p0[v] - h}, None)[0]["stress.robust"]
        # central differences of the robust objective (error ~h² J''' ~ 1e-7 relative)
        # against forward differences of exact gradients (step 1e-6: ~1e-6 relative of
        # the std's share)
        assert grads["stress.robust"][v] == pytest.approx((up - down) / (2 * h), rel=2e-5)


def test_robust_bad_input():
    with pytest.raises(ml.ModelError, match="not variables of p0"):
        Problem.from_function(drift, {"x": 0.5}, "r", bounds={"x": (0.1, 3.0)},
                              robust={"std": {"e": 0.1}})
    pr = Problem.from_function(drift, {"x": 0.5, "e": 0.0}, "r", variables=["x"],
                               bounds={"x": (0.1, 3.0)}, robust={"std": {"e": 0.1}})
    with pytest.raises(ml.ModelError, match="gradient='exact'"):
        optimize(pr, "SLSQP", gradient="finite-difference")
