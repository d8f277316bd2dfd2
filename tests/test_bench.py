"""The benchmark suite runs and reports what BENCHMARKS.md is made of (smoke test, one repeat;
the timings themselves are not asserted: performance is measured by the suite, not by tests)."""

import json

import pytest

from morphlab.bench import suite as bench


def test_bench_cases_run_and_tabulate(tmp_path, capsys):
    out = tmp_path / "b.json"
    assert bench.main(["--quick", "--repeats", "1", "--cases", "morphing,variables,profile,floor",
                       "--out", str(out)]) == 0
    data = json.loads(out.read_text())
    m = data["cases"]["morphing"]
    for key in ("primal", "direct", "direct_fd", "adjoint", "finite_difference",
                "primal_modified_newton"):
        assert m[key]["median"] > 0
    best = min(m["direct"]["median"], m["adjoint"]["median"])
    assert m["ratios"]["finite_difference_over_best"] == pytest.approx(
        m["finite_difference"]["median"] / best, rel=1e-12)
    # finite differences run n_x + 1 = 6 primal simulations, so they cost more than one
    assert m["ratios"]["finite_difference_over_primal"] > 1.0
    v = data["cases"]["variables"]
    assert [r["n_x"] for r in v["rows"]] == [1, 5, 20]
    for r in v["rows"]:  # ratios formed from the same run's medians
        assert r["over_primal"]["adjoint"] == pytest.approx(
            r["seconds"]["adjoint"] / r["seconds"]["primal"], rel=1e-12)
    shares = data["cases"]["profile"]["fractions"]
    assert abs(sum(shares.values()) - 1.0) < 1e-9
    # the floor is formed from the kernels it lists (exact bookkeeping, no timing asserted)
    f = data["cases"]["floor"]
    us = {k: v["median"] for k, v in f["kernels_us"].items()}
    per_iteration = us["residual"] + us["matrix"] + us["factorization"] + us["solve, 1 column"]
    assert f["primal_step_us"] == pytest.approx(f["newton_iterations_per_step"] * per_iteration,
                                                rel=1e-12)
    sens = (us["split matrices (state part)"] + us["partial derivatives, 5 variables"]
            + us["solve, 5 columns"])
    assert f["sensitivity_step_us"] == pytest.approx(sens, rel=1e-12)
    assert f["floor_direct_over_primal"] == pytest.approx(1.0 + sens / f["primal_step_us"],
                                                          rel=1e-12)
    least = us["matrix"] + us["solve, 5 columns"]
    assert f["one_matrix_and_solve_over_primal"] == pytest.approx(
        1.0 + least / f["primal_step_us"], rel=1e-12)
    text = capsys.readouterr().out
    assert "kernel floor" in text
    assert "Table 2" in text and "Cost against the number of design variables" in text


def test_unknown_case_is_refused(capsys):
    assert bench.main(["--cases", "nonsense"]) == 2
    assert "unknown cases" in capsys.readouterr().err
