"""The benchmark suite's machinery: the page generated from the record, merging, the compile
recorder's accounting, the scenarios against the README, and two quick cases end to end.
Timings themselves are not asserted (the suite measures them; a test machine is shared)."""

from __future__ import annotations

import copy
import json
import pathlib
import re

import numpy as np
import pytest
from numba import njit

from morphlab.bench import record, report, suite
from morphlab.bench.compile import CompileRecorder, kernel_table
from morphlab.bench.scenarios import (
    QUICKSTART,
    QUICKSTART_SENSITIVITY,
    SCENARIOS,
    every_item_model,
)

ROOT = pathlib.Path(__file__).resolve().parents[1]


def st(median: float) -> dict:
    """A time_stats dict with a distinctive median and a spread around it."""
    return {"median": median, "min": 0.9 * median, "max": 1.2 * median, "runs": 3}


def kernels(scale: float) -> dict:
    return {"morphlab.kernels.steps.run_steps": {"signatures": 1, "complex_signatures": 0,
                                                 "self_cpu_s": 2.5 * scale},
            "morphlab.kernels.direct.chunk": {"signatures": 2, "complex_signatures": 1,
                                              "self_cpu_s": 0.75 * scale},
            "numba.np.arrayobj.impl": {"signatures": 3, "complex_signatures": 0,
                                       "self_cpu_s": 0.125}}


def scenario(cpu: float, name: str) -> dict:
    return {"process_cpu_s": st(cpu), "process_wall_s": st(cpu + 1), "compilations": 9,
            "phases": {name: {"cpu_s": st(cpu - 1), "wall_s": st(cpu - 0.5)}},
            "kernels": {name: kernels(cpu / 10)}}


#: Results of every case, with distinctive figures the page must show (case -> figures).
RESULTS = {
    "compile": ({"main_command": "morphlab morphing --out DIR",
                 "errors": {"adjoint": "RuntimeError: scenario 'adjoint' failed (status 1): "
                                       + "x" * 600 + " ZeroDivisionError: division by zero"},
                 "scenarios": {"quickstart": {**scenario(17.3, "quickstart"),
                                              "notice_estimate_cpu_s": 33.3},
                               "direct": {**scenario(38.1, "direct"),
                                          "method_cpu_s": st(20.8)},
                               "every-item": {**scenario(26.4, "every-item"),
                                              "kinds": ["rigid body", "beam"]},
                               "main-command": scenario(61.7, "main-command")}},
                ["17.3", "20.8", "26.4", "61.7", "steps.run_steps", "notice's estimate", "33.3",
                 "≤ 8 ✗", "≤ 10 ✗", "≤ 15 ✗", "≤ 60 ✗", "Scenario adjoint failed: RuntimeError",
                 "… xxx", "ZeroDivisionError: division by zero"]),
    "startup": ({"import_cpu_s": st(0.647), "import_wall_s": st(0.851),
                 "first_result_cpu_s": st(1.17), "first_result_wall_s": st(1.91),
                 "first_result_at_s": st(1.31), "first_result_in_process_wall_s": st(0.6),
                 "floor_cpu_s": st(0.93), "floor_wall_s": st(1.41), "floor_at_s": st(1.07),
                 "cache_dir": "/c"},
                ["0.647", "0.851", "1.17", "1.91", "1.31", "0.93", "1.41", "1.07",
                 "≤ 1.5 ✓", "the dependencies' floor"]),
    "morphing": ({"n_x": 5, "responses": ["a", "b", "c"], "settings": {}, "steps": 300,
                  "newton_iterations_per_step": 1.77,
                  "table2_s": {"primal": st(0.1), "primal_solver_only": st(0.0611),
                               "direct": st(0.187), "direct_fd": st(0.222),
                               "adjoint": st(0.177), "finite_difference": st(0.718)},
                  "second_set_s": {"primal": st(0.2), "auto": st(0.354),
                                   "complex_step": st(2.46)},
                  "ratios": {"best_over_primal": 1.77, "finite_difference_over_best": 4.06},
                  "auto_chose": "adjoint", "paper_table2_s": {
                      "primal": 148.0, "direct": 212.0, "finite_difference": 888.0},
                  "gradient_difference_to_complex_step": {"direct": 7.3e-9}},
                 ["0.0611", "1.87", "2.22", "1.77", "7.18", "1.77 (", "12.30", "1.43",
                  "4.06: target ≥ 5 ✗", "paper 4.2", "7.3e-09"]),
    "variables": ({"n_elements": 240, "responses": ["a", "b", "c"], "settings": {},
                   "crossover": 1.9, "rows": [
                       {"n_x": n_x, "auto_chose": "adjoint", "faster": "adjoint",
                        "adjoint_vs_direct": 1e-12, "auto_vs_direct": 2e-12,
                        "seconds": {"primal": st(0.637), "direct": st(0.637 * d),
                                    "adjoint": st(0.637 * a), "auto": st(0.637 * a),
                                    "finite_difference": st(0.637 * (n_x + 1))},
                        "over_primal": {"best": min(a, d)}}
                       for n_x, d, a in ((1, 1.4, 1.35), (50, 5.65, 1.92),
                                         (200, 18.38, 2.21))]
                   + [{"n_x": 20, "auto_chose": "direct", "faster": "adjoint",
                       "adjoint_vs_direct": 1e-12, "auto_vs_direct": 1e-12,
                       "seconds": {"primal": st(0.8), "direct": st(0.896), "adjoint": st(0.864),
                                   "auto": st(0.9), "finite_difference": st(13.3)},
                       "over_primal": {"best": 1.08}}]  # a tie: the ranges overlap
                   + [{"n_x": 5, "error": "ZeroDivisionError: boom"}],
                   "by_responses": [
                       {"n_x": 1, "m": 12, "auto_chose": "adjoint", "faster": "direct",
                        "adjoint_vs_direct": 1e-12,
                        "seconds": {"primal": st(0.5), "direct": st(0.68),
                                    "adjoint": st(0.71), "auto": st(0.7)}},
                       {"n_x": 1, "m": 30, "auto_chose": "adjoint", "faster": "direct",
                        "adjoint_vs_direct": 1e-12,
                        "seconds": {"primal": st(0.5), "direct": st(0.6),
                                    "adjoint": st(0.9), "auto": st(0.9)}},
                       {"n_x": 5, "m": 15, "error": "ValueError: bad"}]},
                  ["5.65", "18.38", "1.92", "≤ 1.6 ✗", "≤ 2 ✗", "201.00", "1.9",
                   "| 5 | failed: ZeroDivisionError: boom", "| 1 | 12 | 1.36 (", "1.42 (",
                   "1.40 (1.26–1.68), adjoint | tie, direct by median |",
                   "1.80 (1.62–2.16), adjoint | direct |", "| 5 | 15 | failed: ValueError: bad",
                   "slower method at (n_x 1, m 30).", "faster method at every n_x where one "
                   "is faster (n_x = 20: a tie"]),
    "pendulum": ({"n_elements": 32, "n_x": 32, "steps": 1000, "responses": ["tip_y"],
                  "settings": {}, "auto_chose": "adjoint", "adjoint_vs_direct": 1e-14,
                  "seconds": {"primal": st(0.25), "direct": st(0.83), "adjoint": st(0.335),
                              "auto": st(0.34)},
                  "ratios": {"best_over_primal": 1.34}},
                 ["3.32", "1.34", "≤ 1.4 ✓", "1.36"]),
    "optimizers": ({"variables": list("abcdefghijklm"), "settings": {}, "target": 0.00748378,
                    "budget": {"maxiter": 60, "free_runs": 400, "fd_runs": None},
                    "optimizers": {"exact": {
                        "status": "converged", "message": "ok", "objective": 0.00747112,
                        "feasible": True, "runs": 55, "simulations": 55, "wall_s": 915.0,
                        "to_target": {"runs": 49, "simulations": 49, "time": 13.0}}}},
                   ["0.00747112", "0.00748378", "915", "| 49 |"]),
    "aero": ({"flow_s": {"target_cl": st(0.0813), "target_cl_no_pressure": st(0.0391),
                         "from_start_angle": st(0.0522), "fixed_alpha": st(0.0377)},
              "flow_one_blas_thread_s": {"target_cl": st(0.0153),
                                         "target_cl_no_pressure": st(0.00681)},
              "coupled_s": {"high_speed": st(0.917), "thermalling": st(0.612)},
              "gradient_s": {"design_problem_13": st(2.71), "primal": st(0.241)},
              "settings": {"t_end": 0.15, "dt": 5e-4}, "passes": {"high_speed": 5,
                                                               "thermalling": 3},
              "share_s": {"high_speed": {"static": 0.31, "flow": 0.55},
                          "thermalling": {"static": 0.12, "flow": 0.44}},
              "deflection_max_mm": {"high_speed": 0.279, "thermalling": 0.0853},
              "cd_counts": 194.15, "variables": 13},
             ["0.0813", "0.0391", "0.0153", "0.00681", "0.917", "0.612", "| 5 |", "0.0853",
              "2.71", "11.24"]),
    "elements": ({"steps": 50, "fitted_exponent": {"primal_per_step_s": 1.63,
                                                   "direct_per_step_s": None},
                  "rows": [{"n_elements": 300, "n_dof": 1812, "steps": 50,
                            "newton_iterations_per_step": 2.0, "direct_setup_s": 0.169,
                            "primal_per_step_s": st(0.00707),
                            "direct_per_step_s": st(0.0531), "peak_memory_MiB": 305.0}]},
                 ["1812", "7.07", "53.1", "305", "1.63"]),
    "memory": ({"n_elements": 3000, "n_dof": 18012, "steps": 10000, "budget_MiB": 512,
                "primal_s": 58.4, "adjoint_s": 190.0, "segment_steps": 84,
                "peak_memory_MiB": 1934.0}, ["18012", "58.4", "190.0", "| 84 |", "1934"]),
    "sweep": ({"n_designs": 64, "settings": {"dt": 5e-4}, "cpus": 2, "dask_workers": 2,
               "n_jobs": 300, "time_s": {"serial": st(8.21), "pool": st(4.4)},
               "designs_per_s": {"serial": 7.8, "pool": 14.5}, "speedup": {"pool": 1.86},
               "overhead_per_job_ms": {"serial": 0.059, "pool": 1.458}},
              ["8.21", "14.5", "1.86", "1.458"]),
    "exudyn": ({"skipped": "Exudyn is not installed: not run."}, ["Exudyn is not installed"]),
}


CTX = {"commit": "0123456789abcdef", "dirty": False, "versions": {"numba": "0.68.1"},
       "machine": {"cores": 2, "usable_cores": 2, "cpu_model": "Test CPU"}}


def full_record() -> dict:
    return record.merge(record.empty(), {
        case: record.entry(res, command=f"python -m morphlab.bench --cases {case}",
                           repeats=3, quick=case == "memory", seconds=12.0, context=CTX)
        for case, (res, _) in RESULTS.items()})


def sections(page: str) -> dict:
    """The page's text per case section."""
    parts = re.split(r"^## (\w[\w-]*):", page, flags=re.M)
    return dict(zip(parts[1::2], parts[2::2]))


def test_the_details_page_shows_every_figure_with_its_command():
    page = report.render_detail(full_record())
    secs = sections(page)
    assert list(secs) == list(report.DESCRIPTIONS)  # every case, in the suite's order
    for case, (_, figures) in RESULTS.items():
        text = secs[case]
        quick = " --quick" if case == "memory" else ""
        assert f"`python -m morphlab.bench --cases {case} --repeats 3{quick}`" in text
        assert "commit 0123456789" in text and "Test CPU" in text
        for fig in figures:
            assert fig in text, (case, fig)
    assert "**Quick run**" in secs["memory"] and "**Quick run**" not in secs["morphing"]


def summary_rows(page: str) -> dict:
    """The summary page's figure rows per case: [(figure, measured, target)]."""
    rows: dict = {}
    for line in page.splitlines():
        cells = [c.strip() for c in line.strip("|").split("|")]
        if line.startswith("| ") and len(cells) == 4 and cells[0] != "case":
            rows.setdefault(cells[0], []).append(tuple(cells[1:]))
    return rows


def test_the_summary_is_one_page_with_every_case_its_targets_and_command():
    rec = full_record()
    page = report.render(rec)
    assert page.count("\n") <= 60  # one page: a screen or a printed sheet
    rows = summary_rows(page)
    assert list(rows) == list(report.DESCRIPTIONS)  # every case, in the suite's order
    text = {case: " ".join(" ".join(r) for r in rs) for case, rs in rows.items()}
    # every target the record can judge, judged as on the details page
    assert "17.3 CPU-s" in text["compile"] and "≤ 8 ✗ (#36)" in text["compile"]
    assert "direct 20.8 CPU-s" in text["compile"] and "≤ 10 ✗ (#36)" in text["compile"]
    assert "failed" in text["compile"]  # the adjoint scenario's error is not hidden
    # judged on the time from launch to the result, the process's wall time beside it
    assert "1.31 s (1.91 s); 1.07 s" in text["startup"] and "≤ 1.5 ✓ (#36)" in text["startup"]
    assert "1.77" in text["morphing"] and "≤ 1.2 ✗ (#37)" in text["morphing"]
    assert "4.06" in text["morphing"] and "≥ 5 ✗ (#37)" in text["morphing"]
    assert "1.34" in text["pendulum"] and "≤ 1.4 ✓ (#37)" in text["pendulum"]
    assert "n_x = 5" in text["variables"]  # its failed row is named
    assert "at every n_x where one is faster; a tie at n_x = 20" in text["variables"]
    assert "exact 49 runs" in text["optimizers"]
    assert "Exudyn is not installed" in text["exudyn"]
    for case in report.DESCRIPTIONS:
        quick = " --quick" if case == "memory" else ""
        line = next(x for x in page.splitlines() if x.startswith(f"| {case} | `"))
        assert f"`python -m morphlab.bench --cases {case} --repeats 3{quick}`" in line
        assert "| 12 s | 0123456 |" in line
    assert "**quick run**" in next(x for x in page.splitlines() if x.startswith("| memory | `"))


def test_a_record_the_summary_cannot_read_is_named_not_hidden():
    rec = copy.deepcopy(full_record())  # the record shares RESULTS' dicts
    del rec["cases"]["pendulum"]["result"]["ratios"]
    rows = summary_rows(report.render(rec))
    assert rows["pendulum"][0][1].startswith("not summarized (KeyError")


def test_a_startup_record_without_the_time_to_result_is_judged_on_its_wall_time():
    """Records from before the time to result was kept judge the process's wall time; a new
    one judges the time to the result and shows the wall time and the floor beside it."""
    old = {k: v for k, v in RESULTS["startup"][0].items()
           if k in ("import_cpu_s", "import_wall_s", "first_result_cpu_s",
                    "first_result_wall_s", "cache_dir")}
    rec = record.merge(record.empty(), {"startup": record.entry(
        old, command="python -m morphlab.bench --cases startup", repeats=3, quick=False,
        seconds=12.0, context=CTX)})
    row = summary_rows(report.render(rec))["startup"][0]
    assert row[1] == "0.851 s; 1.91 s" and row[2] == "≤ 1.5 ✗ (#36)"
    detail = report.render_detail(rec)
    assert "1.91 (1.72–2.29)" in detail and "the dependencies' floor" not in detail
    new = report.render_detail(full_record())
    assert "1.31 (1.18–1.57) | ≤ 1.5 ✓ (#36) |" in new and "1.07 (0.963–1.28) |" in new


def test_each_run_records_and_shows_its_machines_speed():
    """The machine's speed (a Python loop's time per iteration: median and 10th-90th
    percentiles over two seconds) is measured into every entry and shown with its runs on
    both pages; a record taken before it was renders without it, one without the spread
    with the median alone."""
    m = record.machine()
    ns, (lo, hi) = m["python_loop_ns"], m["python_loop_ns_p10_p90"]
    assert 1.0 < lo <= ns <= hi < 5000.0  # nanoseconds an iteration: tens on a current machine
    median, p10, p90 = record.python_loop_ns(seconds=0.05)
    assert p10 <= median <= p90
    fast = {**CTX, "machine": {**CTX["machine"], "python_loop_ns": 57.2,
                               "python_loop_ns_p10_p90": [36.1, 66.4]}}
    rec = record.merge(record.empty(), {"pendulum": record.entry(
        RESULTS["pendulum"][0], command="python -m morphlab.bench --cases pendulum",
        repeats=3, quick=False, seconds=12.0, context=fast)})
    assert "Python loop 57 ns (36–66)" in report.render_detail(rec)
    assert "2 cores, Python loop 57 ns (36–66), load" in report.render(rec)
    older = {**CTX, "machine": {**CTX["machine"], "python_loop_ns": 57.2}}
    rec = record.merge(record.empty(), {"pendulum": record.entry(
        RESULTS["pendulum"][0], command="python -m morphlab.bench --cases pendulum",
        repeats=3, quick=False, seconds=12.0, context=older)})
    assert "2 cores, Python loop 57 ns, load" in report.render(rec)
    assert "Python loop" not in report.render_detail(full_record())  # CTX: no speed


def test_targets_are_judged_on_the_right_side():
    assert report.check("compile.quickstart", 7.9).startswith("≤ 8 ✓")
    assert report.check("compile.quickstart", 8.1).startswith("≤ 8 ✗")
    assert report.check("morphing.finite_difference_over_best", 5.2).startswith("≥ 5 ✓")
    assert report.check("morphing.finite_difference_over_best", 4.2).startswith("≥ 5 ✗")
    assert report.check("variables.20", 3.0) == ""  # no target for 20 variables


def test_a_run_of_some_cases_replaces_them_and_keeps_the_others(tmp_path):
    path = tmp_path / "b.json"
    rec = full_record()
    record.save(rec, path)
    new = record.entry({"import_cpu_s": st(9.99)}, command="c2", repeats=1, quick=True,
                       seconds=1.0, context=CTX)
    merged = record.merge(record.load(path), {"startup": new})
    assert merged["cases"]["startup"]["result"]["import_cpu_s"]["median"] == 9.99
    assert merged["cases"]["startup"]["command"] == "c2"
    for case in RESULTS:
        if case != "startup":
            assert merged["cases"][case] == rec["cases"][case]


def test_a_failed_case_keeps_its_earlier_figures_and_says_so(tmp_path):
    rec = full_record()
    failed = record.entry(None, command="c3", repeats=1, quick=False, seconds=1.0,
                          error="ZeroDivisionError: division by zero", context=CTX)
    merged = record.merge(rec, {"pendulum": failed, "newcase": failed})
    kept = merged["cases"]["pendulum"]
    assert kept["result"] == rec["cases"]["pendulum"]["result"]
    assert kept["failed_run"]["error"].startswith("ZeroDivisionError")
    assert merged["cases"]["newcase"]["error"]  # nothing earlier to keep: the failure itself
    secs = sections(report.render_detail(merged))
    assert "latest run of this case" in secs["pendulum"] and "1.34" in secs["pendulum"]
    summary = report.render(merged)
    assert re.search(r"^\| pendulum \| `[^`]+`; its latest run \(\d{4}-\d\d-\d\d\) failed",
                     summary, flags=re.M)
    assert re.search(r"^\| newcase", summary, flags=re.M) is None
    assert "does not render: newcase" in summary


def test_records_are_strict_json_and_other_layouts_are_refused(tmp_path):
    path = tmp_path / "b.json"
    rec = record.merge(record.empty(), {"x": record.entry(
        {"nan": float("nan"), "n": np.int64(3), "f": np.float64(0.5)}, command="c",
         repeats=1, quick=False, seconds=1.0, context=CTX)})
    record.save(rec, path)
    back = json.loads(path.read_text())  # strict: NaN became null, NumPy numbers plain
    assert back["cases"]["x"]["result"] == {"nan": None, "n": 3, "f": 0.5}
    old = tmp_path / "old.json"
    old.write_text(json.dumps({"command": "x", "cases": {}}))
    with pytest.raises(record.BenchError, match="format 2"):
        record.load(old)
    assert suite.main(["--report", "--out", str(old), "--markdown",
                       str(tmp_path / "B.md")]) == 2


def test_report_alone_runs_nothing(tmp_path, monkeypatch):
    path, md = tmp_path / "b.json", tmp_path / "B.md"
    rec = full_record()  # one record: its entries carry the time they were made
    record.save(rec, path)
    monkeypatch.setattr(suite, "_case", lambda name: pytest.fail(f"ran {name}"))
    assert suite.main(["--report", "--out", str(path), "--markdown", str(md)]) == 0
    assert md.read_text() == report.render(rec)
    assert (tmp_path / report.DETAIL_PATH).read_text() == report.render_detail(rec)


def test_bad_arguments_are_refused(capsys):
    assert suite.main(["--cases", "nonsense"]) == 2
    assert "unknown cases ['nonsense']" in capsys.readouterr().err
    assert suite.main(["--cases", "startup", "--repeats", "0"]) == 2
    assert "--repeats must be at least 1" in capsys.readouterr().err


def test_help_lists_every_case(capsys):
    with pytest.raises(SystemExit):
        suite.main(["--help"])
    out = capsys.readouterr().out
    for case in report.DESCRIPTIONS:
        assert re.search(rf"^  {case} +\S", out, flags=re.M), case


def test_nested_compilations_are_charged_to_their_own_kernel():
    """A kernel calling a kernel compiles its callee inside its own compilation: the self
    times add up to the outer compilation's time, and each is charged to its function."""
    @njit
    def inner(x):
        return np.sin(x) * 2.0

    @njit
    def outer(x):
        return inner(x) + 1.0

    with CompileRecorder() as rec:
        rec.phase = "p"
        assert outer(1.0) == pytest.approx(np.sin(1.0) * 2.0 + 1.0)
    by = {r["kernel"].rsplit(".", 1)[-1]: r for r in rec.records}
    assert {"inner", "outer"} <= set(by) and all(r["phase"] == "p" for r in rec.records)
    assert by["outer"]["cpu_s"] > by["outer"]["self_cpu_s"] > 0
    assert sum(r["self_cpu_s"] for r in rec.records) == pytest.approx(by["outer"]["cpu_s"],
                                                                       rel=1e-9)
    table = kernel_table(rec.records, "p")
    assert table[by["inner"]["kernel"]]["signatures"] == 1
    assert kernel_table(rec.records, "other") == {}
    # the part in LLVM: some of every compilation's own time, none of its nested ones'; one
    # thread's CPU is at most its wall time, which Numba's own timer of the LLVM lock measures
    # over the whole compilation (nested ones included)
    assert all(0 < r["llvm_cpu_s"] < r["self_cpu_s"] for r in rec.records)
    wall = outer.get_metadata(outer.signatures[0])["timers"]["llvm_lock"]
    assert sum(r["llvm_cpu_s"] for r in rec.records) <= wall + 1e-3
    assert table[by["inner"]["kernel"]]["llvm_cpu_s"] == by["inner"]["llvm_cpu_s"]


def test_the_quickstart_scenario_is_the_readmes():
    readme = (ROOT / "README.md").read_text(encoding="utf-8")
    assert QUICKSTART in readme
    assert QUICKSTART_SENSITIVITY.replace("{method}", "direct") in readme


def test_the_every_item_model_has_every_kind():
    model, kinds = every_item_model()
    for kind in ("rigid body", "beam", "revolute", "weld", "prismatic", "fix", "drive",
                 "force", "torque", "spring", "rotational spring", "line load"):
        assert kind in kinds
    assert (len(model.forces), len(model.torques), len(model.springs),
            len(model.line_loads)) == (1, 1, 2, 1)
    assert set(SCENARIOS) >= {"quickstart", "every-item", "main-command"}


def test_peak_memory_is_the_childs_own():
    """A child process's peak is its own, not its parent's: with 256 MiB held here, a fresh
    interpreter (with NumPy, ~30-60 MiB) reports far less, and this process at least 256."""
    import subprocess
    import sys

    from morphlab.bench.elements import peak_memory_mib

    held = np.ones(2**25)  # 256 MiB, touched
    code = "from morphlab.bench.elements import peak_memory_mib; print(peak_memory_mib())"
    child = float(subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                                 check=True).stdout)
    assert peak_memory_mib() >= 256.0 and held.sum() == 2**25
    assert child < 200.0  # 256 MiB or more if the parent's peak were inherited


@pytest.mark.slow
def test_quick_cases_run_end_to_end(tmp_path):
    """The startup case (fresh processes, filled cache) and the pendulum (gradients in one
    process), reduced, into a record and a page: seconds once the kernels are cached."""
    path, md = tmp_path / "b.json", tmp_path / "B.md"
    assert suite.main(["--cases", "startup,pendulum", "--quick", "--repeats", "1", "--out",
                       str(path), "--report", "--markdown", str(md)]) == 0
    rec = record.load(path)
    s = rec["cases"]["startup"]["result"]
    assert 0 < s["import_wall_s"]["median"] < s["first_result_wall_s"]["median"]
    p = rec["cases"]["pendulum"]["result"]
    # 8 variables > 0.15 per response: the adjoint on one core, the direct method beside the
    # primal on two (8 <= Auto.beside_variables)
    from morphlab.sensitivity.beside import usable_cores

    assert p["n_x"] == 8
    assert p["auto_chose"] == ("direct" if usable_cores() >= 2 else "adjoint")
    assert p["ratios"]["direct_over_primal"] == pytest.approx(
        p["seconds"]["direct"]["median"] / p["seconds"]["primal"]["median"], rel=1e-12)
    # the adjoint is the direct method's recursion transposed: equal to round-off
    assert p["adjoint_vs_direct"] < 1e-10
    page = md.read_text()
    assert "--cases pendulum --repeats 1 --quick" in page and "| startup | warm start" in page
    assert "## startup:" in (md.parent / report.DETAIL_PATH).read_text()
