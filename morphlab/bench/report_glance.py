"""The one-page BENCHMARKS.md: each case's key figures, one function per case.

Each takes the case's result (as the case function returned it) and the target checker
``check(key, value)`` (:func:`morphlab.bench.report.check`) and returns rows ``(figure,
measured, target)`` of plain Markdown text. The full tables of every case are on the details
page (:mod:`morphlab.bench.report_cases`); these rows repeat the figures a reader looks for
first, and every figure an issue's target judges.
"""

from __future__ import annotations

from .report_cases import auto_verdict

Row = tuple[str, str, str]


def _m(st: dict, digits: int = 3) -> str:
    """The median of a :func:`~morphlab.studies.timing.time_stats` dict."""
    return f"{st['median']:.{digits}g}"


def compile(r: dict, check) -> list[Row]:  # noqa: A001 - the case's name
    sc, rows = r["scenarios"], []
    if "quickstart" in sc:
        cpu = sc["quickstart"]["process_cpu_s"]["median"]
        rows.append(("first use (empty cache): README quickstart, first result",
                     f"{cpu:.3g} CPU-s, {_m(sc['quickstart']['process_wall_s'])} s",
                     check("compile.quickstart", cpu)))
    methods = {m: sc[m]["method_cpu_s"]["median"] for m in ("direct", "adjoint",
                                                            "complex-step", "direct-fd")
               if m in sc and "method_cpu_s" in sc[m]}
    if methods:
        rows.append(("... then its first `sensitivities`, per method",
                     ", ".join(f"{m} {v:.3g}" for m, v in methods.items()) + " CPU-s",
                     check("compile.method", max(methods.values()))))
    if "every-item" in sc:
        cpu = sc["every-item"]["process_cpu_s"]["median"]
        rows.append(("first use: a model with every item kind", f"{cpu:.3g} CPU-s",
                     check("compile.every-item", cpu)))
    if "main-command" in sc:
        x = sc["main-command"]
        cpu, wall = x["process_cpu_s"]["median"], x["process_wall_s"]["median"]
        rows.append((f"first use: `{r['main_command']}`", f"{cpu:.3g} CPU-s, {wall:.3g} s",
                     f"{check('compile.main-command', cpu)}; wall "
                     f"{check('compile.main-command.wall', wall)}"))
    for s in r.get("errors", {}):
        rows.append((f"first use: scenario {s}", "failed (details page)", ""))
    return rows


def startup(r: dict, check) -> list[Row]:
    if "first_result_at_s" not in r:  # a record from before the time to result was kept
        wall = r["first_result_wall_s"]["median"]
        return [("warm start (filled cache): `import morphlab`; the quickstart's first result",
                 f"{_m(r['import_wall_s'])} s; {wall:.3g} s",
                 check("startup.first_result", wall))]
    at = r["first_result_at_s"]["median"]
    return [("warm start (filled cache): `import morphlab`; the quickstart's first result, "
             "launch to result (process exit); the dependencies' floor",
             f"{_m(r['import_wall_s'])} s; {at:.3g} s ({_m(r['first_result_wall_s'])} s); "
             f"{_m(r['floor_at_s'])} s", check("startup.first_result", at))]


def morphing(r: dict, check) -> list[Row]:
    t, rt = r["table2_s"], r["ratios"]
    prim = t["primal"]["median"]
    methods = ", ".join(f"{label} {t[k]['median'] / prim:.2f}" for k, label in (
        ("adjoint", "adjoint"), ("direct", "direct"), ("direct_fd", "direct-fd"))
        if k in t)
    g = r.get("gradient_difference_to_complex_step") or {}
    worst = max((v for k, v in g.items() if k != "direct-fd"), default=None)
    return [("morphing study, primal run (build, compile, simulate, responses)",
             f"{prim:.3g} s", ""),
            (f"... its gradient, {r['n_x']} variables, {len(r['responses'])} responses: "
             "best, in primal runs", f"{rt['best_over_primal']:.2f} ({methods})",
             check("morphing.best_over_primal", rt["best_over_primal"])),
            ("... finite differences / best", f"{rt['finite_difference_over_best']:.2f}",
             check("morphing.finite_difference_over_best",
                   rt["finite_difference_over_best"]))] + (
        [] if worst is None else [("... largest gradient difference to the complex step",
                                   f"{worst:.1e}", "")])


def variables(r: dict, check) -> list[Row]:
    good = [row for row in r["rows"] if "error" not in row]
    rows = [(f"{r['n_elements']}-element skin: gradient in primal runs (best) at n_x = "
             + ", ".join(str(row["n_x"]) for row in good),
             ", ".join(f"{row['over_primal']['best']:.2f}" for row in good),
             "; ".join(f"n_x {row['n_x']} {c}" for row in good
                       if (c := check(f"variables.{row['n_x']}",
                                      row["over_primal"]["best"]))))]
    wrong, ties = auto_verdict(good)
    rows.append(("... `auto` ran the faster method", (
        "at every n_x where one is faster" if not wrong else f"not at n_x = {', '.join(wrong)}")
        + (f"; a tie at n_x = {', '.join(ties)}" if ties else ""), ""))
    failed = [str(row["n_x"]) for row in r["rows"] if "error" in row]
    if failed:
        rows.append(("... failed rows", f"n_x = {', '.join(failed)} (details page)", ""))
    return rows


def pendulum(r: dict, check) -> list[Row]:
    b = r["ratios"]["best_over_primal"]
    return [(f"flexible pendulum, {r['n_x']} thickness variables, one response: gradient "
             f"in primal runs ({r['auto_chose']})", f"{b:.2f}",
             check("pendulum.best_over_primal", b))]


def optimizers(r: dict, check) -> list[Row]:
    parts = []
    for name, o in r["optimizers"].items():
        n = o["to_target"]["runs"]
        parts.append(f"{name} " + ("never" if n is None else f"{n:.0f} runs"))
    return [(f"design optimization, {len(r['variables'])} variables: runs to the target "
             "objective", ", ".join(parts), "")]


def aero(r: dict, check) -> list[Row]:
    f, c, g = r["flow_s"], r["coupled_s"], r["gradient_s"]
    prim = g["primal"]["median"]
    return [("flight loads: one flow evaluation (NeuralFoil + panel pressure)",
             f"{_m(f['target_cl'])} s", ""),
            ("... one coupled aeroelastic solve", ", ".join(f"{k} {_m(st)} s"
                                                            for k, st in c.items()), ""),
            (f"... drag and the design responses by {r['variables']} variables, in primal "
             "runs", f"{g['design_problem_13']['median'] / prim:.2f}", "")]


def elements(r: dict, check) -> list[Row]:
    big = max(r["rows"], key=lambda row: row["n_elements"])
    fit = r["fitted_exponent"].get("primal_per_step_s")
    return [(f"primal time per step at {big['n_elements']} skin elements "
             f"({big['n_dof']} DOFs)", f"{1e3 * big['primal_per_step_s']['median']:.3g} ms"
             + ("" if fit is None else f"; grows as n^{fit:.2f}"), "")]


def memory(r: dict, check) -> list[Row]:
    return [(f"adjoint on {r['steps']} steps, {r['n_dof']} DOFs: peak memory "
             f"(budget {r['budget_MiB']} MiB for the kept states)",
             f"{r['peak_memory_MiB']:.0f} MiB", "")]


def sweep(r: dict, check) -> list[Row]:
    sp = r["speedup"]
    return [(f"parameter study, {r['n_designs']} designs on {r['cpus']} CPUs: speed-up "
             "over serial", ", ".join(f"{k} {v:.2f}" for k, v in sp.items()) or "-", "")]


def exudyn(r: dict, check) -> list[Row]:
    if "rows" not in r:
        return [("beside Exudyn", r.get("skipped", "skipped"), "")]
    x = max(r["rows"], key=lambda row: row["n_elements"])
    p = x["primal"]
    us = {k: 1e6 * p[k]["per_step_s"]["median"] for k in ("morphlab", "exudyn_full_newton")}
    fd = x["sensitivities"]["ratios"]["exudyn_fd_over_morphlab_direct"]
    return [(f"flexible pendulum beside Exudyn, {x['n_elements']} elements: µs per step; "
             "Exudyn's finite differences / morphlab's direct gradient",
             f"{us['morphlab']:.0f} against {us['exudyn_full_newton']:.0f}; {fd:.2f}", "")]
