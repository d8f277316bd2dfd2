"""The benchmark suite runs and reports what BENCHMARKS.md is made of (smoke test, one repeat;
the timings themselves are not asserted: performance is measured by the suite, not by tests)."""

import json

from morphlab import bench


def test_bench_cases_run_and_tabulate(tmp_path, capsys):
    out = tmp_path / "b.json"
    assert bench.main(["--quick", "--repeats", "1", "--cases", "morphing,variables,profile,floor",
                       "--out", str(out)]) == 0
    data = json.loads(out.read_text())
    m = data["cases"]["morphing"]
    for key in ("primal", "direct", "direct_fd", "finite_difference", "primal_modified_newton"):
        assert m[key]["median"] > 0
    # finite differences run n_x + 1 = 6 primal simulations, so they cost more than one
    assert m["ratios"]["finite_difference_over_primal"] > 1.0
    assert [r["n_x"] for r in data["cases"]["variables"]["rows"]] == [1, 5, 20]
    shares = data["cases"]["profile"]["fractions"]
    assert abs(sum(shares.values()) - 1.0) < 1e-9
    # the floor's sensitivity step holds the split matrices (two fills) and the partial
    # derivatives, so it exceeds the bound of one matrix and the solve alone
    f = data["cases"]["floor"]
    assert f["floor_direct_over_primal"] > f["one_matrix_and_solve_over_primal"] > 1.0
    text = capsys.readouterr().out
    assert "kernel floor" in text
    assert "Table 2" in text and "Growth with design variables" in text


def test_unknown_case_is_refused(capsys):
    assert bench.main(["--cases", "nonsense"]) == 2
    assert "unknown cases" in capsys.readouterr().err
