"""Progress reporting of the long study loops: FORM's rounds, the sweeps of importance
sampling, Sobol' indices and Monte Carlo propagation, and the optimizer comparison of the
design problem. Cheap analytic tasks; what is checked is what the reports count against
what the study did (its runs, its rounds, its budget)."""

import pytest
from problems import rosenbrock_problem
from scipy import stats

from morphlab.errors import ModelError
from morphlab.morphing import optimization as opt
from morphlab.studies import (
    FunctionTask,
    JointDistribution,
    SearchOptions,
    StudyError,
    form,
    importance_sampling,
    propagate,
    sobol_indices,
)

# a nonlinear limit state x^3 + y^3 >= 18 (several iHL-RF rounds), x ~ N(10, 5), y ~ N(9.9, 5)
CUBIC = {"x": stats.norm(10.0, 5.0), "y": stats.norm(9.9, 5.0)}
ALLOW = {"g": (18.0, None)}


def cubic(p):
    x, y = p["x"], p["y"]
    return {"g": x**3 + y**3}, {"g": {"x": 3 * x * x, "y": 3 * y * y}}


def values(p):
    return {"s": p["x"] + 2.0 * p["y"]}


@pytest.fixture(scope="module")
def cubic_form():
    return form(FunctionTask(cubic), JointDistribution(CUBIC), ALLOW, executor="serial")


def test_form_reports_every_round_of_both_phases():
    seen = []
    res = form(FunctionTask(cubic), JointDistribution(CUBIC), ALLOW, executor="serial",
               options=SearchOptions(mirror=True), progress=seen.append)
    phases = [r["phase"] for r in seen]
    n_search = phases.count("search")
    assert n_search >= 3 and phases == ["search"] * n_search + ["mirror"] * (len(seen) - n_search)
    for phase in ("search", "mirror"):
        recs = [r for r in seen if r["phase"] == phase]
        assert [r["round"] for r in recs] == list(range(1, len(recs) + 1))
        assert recs[-1]["running"] == 0 and all(r["searches"] == 1 for r in recs)
        assert all(r["running"] == 1 for r in recs[:-1])
    runs = [r["runs"] for r in seen]
    assert runs == sorted(runs) and runs[-1] == res.runs
    # one limit state: each round evaluates exactly one point
    assert runs == list(range(1, len(seen) + 1))


def test_form_progress_line(capsys):
    seen = []
    form(FunctionTask(cubic), JointDistribution(CUBIC), ALLOW, executor="serial",
         progress=seen.append)
    form(FunctionTask(cubic), JointDistribution(CUBIC), ALLOW, executor="serial",
         progress=True)
    out = capsys.readouterr().out
    assert out.count("\r") == len(seen) and out.endswith("\n")
    assert out.startswith("\rFORM search: round 1, 1 of 1 searches running")
    assert f"round {len(seen)}, 0 of 1 searches running" in out
    assert f"{len(seen)} gradient runs" in out


@pytest.mark.parametrize("call", [
    lambda: form(FunctionTask(cubic), JointDistribution(CUBIC), ALLOW, progress="yes"),
    lambda: propagate(FunctionTask(cubic), JointDistribution(CUBIC), "form", allowables=ALLOW,
                      progress=lambda d, t: None),
])
def test_bad_progress_is_refused(call):
    with pytest.raises(StudyError, match="progress must be"):
        call()


def test_importance_sampling_reports_its_draws(cubic_form):
    seen = []
    importance_sampling(FunctionTask(cubic), JointDistribution(CUBIC), cubic_form, 40,
                        executor="serial", progress=lambda d, t: seen.append((d, t)))
    assert seen[-1] == (40, 40) and seen[0] == (0, 40)


def test_sobol_indices_report_every_run():
    seen = []
    sobol_indices(values, {"x": stats.uniform(0, 1), "y": stats.uniform(0, 1)}, 8,
                  executor="serial", n_resamples=9, progress=lambda d, t: seen.append((d, t)))
    assert seen[-1] == (8 * (2 + 2), 8 * (2 + 2))  # n (d + 2) runs


def test_monte_carlo_propagation_prints_a_bar(capsys):
    res = propagate(values, {"x": stats.norm(0, 1), "y": stats.norm(0, 1)}, "monte-carlo",
                    n=16, executor="serial", progress=True)
    assert res.n == 16
    assert capsys.readouterr().out.endswith("] 16/16 designs\n")


def test_compare_optimizers_reports_each_optimizer_within_its_budget(capsys):
    """Each optimizer's iterations in order, with its runs; the finite-difference run
    stops at its budget of runs."""
    seen = []
    runs = opt.compare_optimizers(rosenbrock_problem(), maxiter=40, free_runs=30, fd_runs=4,
                                  progress=lambda name, rec: seen.append((name, rec)))
    assert [n for n in dict.fromkeys(n for n, _ in seen)] == list(opt.COMPARED)
    for name in opt.COMPARED:
        recs = [r for n, r in seen if n == name]
        assert [r["iteration"] for r in recs] == list(range(len(recs)))
        assert recs[-1]["runs"] <= runs[name]["result"].n_runs
    fd = runs["finite_difference"]["result"]
    assert fd.status == "budget" and fd.n_runs == 4
    assert fd.n_simulations == 4 * (2 + 1)  # a design and one step per variable
    assert runs["derivative_free"]["result"].n_runs <= 30

    opt.compare_optimizers(rosenbrock_problem(), maxiter=5, free_runs=8, fd_runs=2,
                           progress=True)
    lines = capsys.readouterr().out.split("\n")
    assert len(lines) == 4 and lines[3] == ""  # one line per optimizer, rewritten in place
    ends = [ln.rsplit("\r", 1)[-1] for ln in lines[:3]]  # what stays visible
    assert [e.split(":")[0] for e in ends] == list(opt.COMPARED.values())
    assert "iteration 1 of at most 5, " in lines[0]
    assert ends[1].startswith("SLSQP, finite differences: budget (run budget max_runs=2 "
                              "reached) after 2 of 2 runs of 3 simulations each, objective ")
    assert "of 8 runs, objective" in ends[2]


def test_compare_optimizers_refuses_a_bad_progress():
    with pytest.raises(ModelError, match="progress must be"):
        opt.compare_optimizers(rosenbrock_problem(), progress="verbose")


def test_tolerances_monte_carlo_passes_progress_to_its_sweep(monkeypatch):
    """The design problem's Monte Carlo hands its progress to the sweep of its runs (the
    sweep itself is not run here: it is the leading edge)."""
    import morphlab.studies as studies

    got = {}

    def fake_sweep(task, designs, executor=None, progress=False):
        got["progress"], got["n"] = progress, len(designs["t0"])
        raise RuntimeError("stop here")

    def report(done, total):
        return None

    monkeypatch.setattr(studies, "sweep", fake_sweep)
    with pytest.raises(RuntimeError, match="stop here"):
        opt.tolerances_monte_carlo(opt.start(), 6, progress=report)
    assert got == {"progress": report, "n": 6}
