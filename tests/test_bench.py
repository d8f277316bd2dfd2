"""The benchmark suite runs and reports what BENCHMARKS.md is made of (smoke test, one repeat;
the timings themselves are not asserted: performance is measured by the suite, not by tests)."""

import json

import pytest

from morphlab.bench import suite as bench


def test_bench_cases_run_and_tabulate(tmp_path, capsys):
    out = tmp_path / "b.json"
    assert bench.main(["--quick", "--repeats", "1", "--cases", "morphing,variables,profile",
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
    text = capsys.readouterr().out
    assert "Table 2" in text and "Cost against the number of design variables" in text


def test_unknown_case_is_refused(capsys):
    assert bench.main(["--cases", "nonsense"]) == 2
    assert "unknown cases" in capsys.readouterr().err
