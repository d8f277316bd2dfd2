"""The sections of the details page (docs/benchmarks-detail.md), one function per case
(:mod:`morphlab.bench.report`).

Each takes the case's result (as the case function returned it) and the target checker
``check(key, value)`` (the text of the issue's target for that figure, empty where there is
none) and returns Markdown lines.
"""

from __future__ import annotations

#: Compile table: kernels shown by name when one column reaches this many CPU seconds.
KERNEL_MIN_S = 0.5
#: ... and at most this many of them (the rest is summed in one row).
KERNEL_ROWS = 24


def clip(text: str, n: int = 300) -> str:
    """``text`` cut to about ``n`` characters, keeping its start and its end (where an error
    message names the exception)."""
    text = " ".join(str(text).split())
    return text if len(text) <= n else f"{text[: n // 3]} … {text[-(2 * n) // 3:]}"


def s3(st: dict, digits: int = 3) -> str:
    """``median (min–max)`` of a :func:`~morphlab.studies.timing.time_stats` dict."""
    return f"{st['median']:.{digits}g} ({st['min']:.{digits}g}–{st['max']:.{digits}g})"


def ratio(st: dict, primal: float) -> str:
    """A method's median over the primal's, with its min and max over the same primal."""
    return f"{st['median'] / primal:.2f} ({st['min'] / primal:.2f}–{st['max'] / primal:.2f})"


def cpu_ratio(st: dict, primal: dict) -> str:
    """A method's median process CPU time over the primal's (blank for a record without)."""
    if "cpu_median" not in st or "cpu_median" not in primal:
        return ""
    return f"{st['cpu_median'] / primal['cpu_median']:.2f}"


def _scenario_rows(r: dict, check) -> list[str]:
    sc = r["scenarios"]
    rows = ["| first use, empty cache | process CPU [s] | wall [s] | target [CPU-s] |",
            "|---|---|---|---|"]
    if "quickstart" in sc:
        q = sc["quickstart"]
        rows.append(f"| README quickstart, first result | {s3(q['process_cpu_s'])} | "
                    f"{s3(q['process_wall_s'])} | "
                    f"{check('compile.quickstart', q['process_cpu_s']['median'])} |")
    for m in ("direct", "adjoint", "complex-step", "direct-fd"):
        if m in sc and "method_cpu_s" in sc[m]:
            x = sc[m]
            rows.append(f"| its first `sensitivities(method=\"{m}\")`, on top of the primal | "
                        f"{s3(x['method_cpu_s'])} | {s3(x['phases'][m]['wall_s'])} | "
                        f"{check('compile.method', x['method_cpu_s']['median'])} |")
    if "every-item" in sc:
        x = sc["every-item"]
        rows.append(f"| first result of a model with every item kind | "
                    f"{s3(x['process_cpu_s'])} | {s3(x['process_wall_s'])} | "
                    f"{check('compile.every-item', x['process_cpu_s']['median'])} |")
    if "main-command" in sc:
        x = sc["main-command"]
        rows.append(f"| `{r['main_command']}` | {s3(x['process_cpu_s'])} | "
                    f"{s3(x['process_wall_s'])} | "
                    f"{check('compile.main-command', x['process_cpu_s']['median'])}; wall "
                    f"{check('compile.main-command.wall', x['process_wall_s']['median'])} |")
    return rows


def compile(r: dict, check) -> list[str]:  # noqa: A001 - the case's name
    """First use: process CPU per scenario, then compile CPU per kernel."""
    lines = _scenario_rows(r, check) + [""]
    sc = r["scenarios"]
    for s, err in r.get("errors", {}).items():
        lines += [f"Scenario {s} failed: {clip(err)}", ""]
    if "every-item" in sc:
        lines += [f"Every-item model: {', '.join(sc['every-item'].get('kinds', []))}. A "
                  "method's CPU is its process's minus the quickstart process's of the same "
                  "round; wall is the method's own call. The main command's process CPU "
                  "includes its compile helper's (morphlab.morphing.warmup: the adjoint and "
                  "the flight loads' statics, compiled in a second process on first use); "
                  "its kernel column holds what the command's own process compiled.", ""]
    cols = list(sc)  # each scenario's own phase has its name (morphlab.bench.scenarios.run)
    tables = {s: sc[s]["kernels"][s] for s in cols}
    names = sorted({k for t in tables.values() for k in t})
    lib = [k for k in names if not k.startswith("morphlab.")]
    ours = [k for k in names if k.startswith("morphlab.")]
    peak = {k: max(t.get(k, {}).get("self_cpu_s", 0.0) for t in tables.values()) for k in ours}
    shown = sorted([k for k in ours if peak[k] >= KERNEL_MIN_S], key=lambda k: -peak[k])
    shown = shown[:KERNEL_ROWS]
    rest = [k for k in ours if k not in shown]
    lines += ["Compile CPU [s] per kernel (self time: nested compilations are charged to "
              "their own kernel) and its number of signatures (c: with complex arguments), "
              "median of the rounds; a method's column holds what its own call compiled.",
              "", "| kernel | " + " | ".join(cols) + " |",
              "|---" * (len(cols) + 1) + "|"]

    def cell(t: dict, keys) -> str:
        rows = [t[k] for k in keys if k in t]
        if not rows:
            return "-"
        n = sum(x["signatures"] for x in rows)
        c = sum(x["complex_signatures"] for x in rows)
        return f"{sum(x['self_cpu_s'] for x in rows):.2f} ({n:g}{f', {c:g}c' if c else ''})"

    for k in shown:
        name = k.removeprefix("morphlab.kernels.").removeprefix("morphlab.")
        lines.append(f"| {name} | " + " | ".join(cell(tables[s], [k]) for s in cols) + " |")
    for label, keys in ((f"{len(rest)} other morphlab kernels", rest),
                        (f"{len(lib)} numba library functions", lib),
                        ("**all compilations**", names)):
        lines.append(f"| {label} | " + " | ".join(cell(tables[s], keys) for s in cols) + " |")
    if any("llvm_cpu_s" in x for t in tables.values() for x in t.values()):
        def llvm(t: dict, keys) -> str:  # of the self CPU above, the part in LLVM
            return f"{sum(t[k].get('llvm_cpu_s', 0.0) for k in keys if k in t):.2f}"

        lines.append("| of which in LLVM: its optimization and machine code (the rest: "
                     "Numba's typing and lowering, in Python) | "
                     + " | ".join(llvm(tables[s], names) for s in cols) + " |")
    if any("notice_estimate_cpu_s" in sc[s] for s in cols):
        def notice(s: str) -> str:
            e = sc[s].get("notice_estimate_cpu_s")
            return "-" if e is None else f"{e:.1f}"

        lines.append("| the compile notice's estimate of all compilations "
                     "(morphlab.jit.progress.ESTIMATES) | "
                     + " | ".join(notice(s) for s in cols) + " |")
    return lines + [""]


def startup(r: dict, check) -> list[str]:
    """Import, first result and (records with them) the time to the result and the
    dependencies' floor; the target is judged on the time to the result where recorded (the
    process's exit comes after it), else on the process's wall time."""
    head = ["| fresh process, filled cache | CPU [s] | wall [s] | launch to result [s] "
            "| target [s to result] |", "|---|---|---|---|---|",
            f"| `import morphlab` | {s3(r['import_cpu_s'])} | {s3(r['import_wall_s'])} | | |"]
    if "first_result_at_s" not in r:
        return head + [
            f"| README quickstart, first result | {s3(r['first_result_cpu_s'])} | "
            f"{s3(r['first_result_wall_s'])} | | "
            f"{check('startup.first_result', r['first_result_wall_s']['median'])} |", ""]
    at = r["first_result_at_s"]
    return head + [
        f"| README quickstart, first result | {s3(r['first_result_cpu_s'])} | "
        f"{s3(r['first_result_wall_s'])} | {s3(at)} | "
        f"{check('startup.first_result', at['median'])} |",
        f"| the dependencies' floor: NumPy, SciPy's sparse solvers, Numba and one cached "
        f"kernel | {s3(r['floor_cpu_s'])} | {s3(r['floor_wall_s'])} | {s3(r['floor_at_s'])} "
        "| |", "",
        "Launch to result: from starting the process to the moment its result exists; the "
        "wall time adds the interpreter's exit. The floor is what any first result of a "
        "program on these libraries costs; morphlab's share is the difference.", ""]


def morphing(r: dict, check) -> list[str]:
    t, s, rt = r["table2_s"], r["second_set_s"], r["ratios"]
    prim, prim2 = t["primal"]["median"], s["primal"]["median"]
    paper = r.get("paper_table2_s") or {}
    pp = paper.get("primal")

    def pap(k):
        return f"{paper[k] / pp:.2f}" if pp and k in paper else ""

    P, P2 = t["primal"], s["primal"]
    lines = ["| run (5 variables, 3 responses) | median [s] | / primal | CPU / primal | paper |",
             "|---|---|---|---|---|",
             f"| primal: build, compile, simulate, responses | {s3(t['primal'])} | 1 | 1 | 1 |",
             f"| simulate a compiled model only | {s3(t['primal_solver_only'])} | "
             f"{ratio(t['primal_solver_only'], prim)} | "
             f"{cpu_ratio(t['primal_solver_only'], P)} | |",
             f"| direct | {s3(t['direct'])} | {ratio(t['direct'], prim)} | "
             f"{cpu_ratio(t['direct'], P)} | |",
             f"| direct-fd (the paper's semi-analytical) | {s3(t['direct_fd'])} | "
             f"{ratio(t['direct_fd'], prim)} | {cpu_ratio(t['direct_fd'], P)} | "
             f"{pap('direct')} |",
             f"| adjoint | {s3(t['adjoint'])} | {ratio(t['adjoint'], prim)} | "
             f"{cpu_ratio(t['adjoint'], P)} | |",
             f"| finite differences (n_x + 1 runs) | {s3(t['finite_difference'])} | "
             f"{ratio(t['finite_difference'], prim)} | {cpu_ratio(t['finite_difference'], P)} "
             f"| {pap('finite_difference')} |",
             f"| second set: primal | {s3(s['primal'])} | 1 | 1 | |",
             f"| second set: auto (ran {r['auto_chose']}) | {s3(s['auto'])} | "
             f"{ratio(s['auto'], prim2)} | {cpu_ratio(s['auto'], P2)} | |",
             f"| second set: complex step (whole runs) | {s3(s['complex_step'])} | "
             f"{ratio(s['complex_step'], prim2)} | {cpu_ratio(s['complex_step'], P2)} | |", ""]
    g = r["gradient_difference_to_complex_step"]
    cpu_note = (f" (wall time; in process CPU time the adjoint costs "
                f"{rt['adjoint_cpu_over_primal']:.2f}, direct {rt['direct_cpu_over_primal']:.2f})"
                if "adjoint_cpu_over_primal" in rt else "")
    lines += [f"Best / primal {rt['best_over_primal']:.2f}{cpu_note}: target "
              f"{check('morphing.best_over_primal', rt['best_over_primal'])}. Finite "
              f"differences / best {rt['finite_difference_over_best']:.2f}: target "
              f"{check('morphing.finite_difference_over_best', rt['finite_difference_over_best'])}"
              + (f", paper {paper['finite_difference'] / paper['direct']:.1f}" if paper else "")
              + f". {r['steps']} steps, {r['newton_iterations_per_step']:.2f} Newton iterations "
              "per step. Largest gradient difference to the complex step (relative to the "
              "response's largest entry): " + ", ".join(f"{k} {v:.1e}" for k, v in g.items())
              + ".", ""]
    return lines


def tie(row: dict) -> bool:
    """Whether a row's direct and adjoint times overlap (min-max of their rounds): neither is
    the faster, whichever ``auto`` ran."""
    d, a = row["seconds"]["direct"], row["seconds"]["adjoint"]
    return d["min"] <= a["max"] and a["min"] <= d["max"]


def auto_verdict(rows: list[dict]) -> tuple[list[str], list[str]]:
    """The ``n_x`` (as text) of the rows where ``auto`` ran the slower method, and of those
    where the two methods tie and it ran the one slower by median."""
    wrong = [str(r["n_x"]) for r in rows if r["auto_chose"] != r["faster"] and not tie(r)]
    ties = [str(r["n_x"]) for r in rows if r["auto_chose"] != r["faster"] and tie(r)]
    return wrong, ties


def variables(r: dict, check) -> list[str]:
    lines = [f"{r['n_elements']}-element skin, {len(r['responses'])} responses; gradient cost "
             "in primal runs (wall time; the adjoint's in process CPU time beside it).", "",
             "| n_x | primal [s] | direct | adjoint | adjoint, CPU | auto (ran) | "
             "finite differences | best | target |", "|---|---|---|---|---|---|---|---|---|"]
    good = [row for row in r["rows"] if "error" not in row]
    for row in r["rows"]:
        if "error" in row:
            lines.append(f"| {row['n_x']} | failed: {clip(row['error'], 200)} | | | | | | | |")
            continue
        t, p = row["seconds"], row["seconds"]["primal"]["median"]
        target = check(f"variables.{row['n_x']}", row["over_primal"]["best"])
        lines.append(f"| {row['n_x']} | {s3(t['primal'])} | {ratio(t['direct'], p)} | "
                     f"{ratio(t['adjoint'], p)} | {cpu_ratio(t['adjoint'], t['primal'])} | "
                     f"{ratio(t['auto'], p)}, "
                     f"{row['auto_chose']} | {ratio(t['finite_difference'], p)} | "
                     f"{row['over_primal']['best']:.2f} | {target} |")
    c = r.get("crossover")
    wrong, ties = auto_verdict(good)
    worst = max(max(row["adjoint_vs_direct"], row["auto_vs_direct"]) for row in good)
    lines += ["", "Adjoint faster than direct above n_x = " + (
        f"{c:.1f}" if c is not None else "(no crossing in the range)") + "; auto ran the "
        + (f"slower method at n_x = {', '.join(wrong)}" if wrong else "faster method at every "
           "n_x where one is faster")
        + (f" (n_x = {', '.join(ties)}: a tie, the two methods' ranges overlap; auto ran the "
           "one slower by median)" if ties else "")
        + f"; adjoint and auto gradients within {worst:.1e} of direct.", ""]
    if r.get("by_responses"):
        lines += ["Other numbers of responses m (the first of the three, or the three and "
                  "displacements of skin nodes): gradient cost in primal runs; a tie where "
                  "the two methods' ranges overlap.", "",
                  "| n_x | m | direct | adjoint | auto (ran) | faster |",
                  "|---|---|---|---|---|---|"]
        wrong = []
        for row in r["by_responses"]:
            if "error" in row:
                lines.append(f"| {row['n_x']} | {row['m']} | failed: {clip(row['error'], 200)}"
                             " | | | |")
                continue
            t, p = row["seconds"], row["seconds"]["primal"]["median"]
            d, a = t["direct"], t["adjoint"]
            if not tie(row) and row["auto_chose"] != row["faster"]:
                wrong.append(f"(n_x {row['n_x']}, m {row['m']})")
            faster = f"tie, {row['faster']} by median" if tie(row) else row["faster"]
            lines.append(f"| {row['n_x']} | {row['m']} | {ratio(d, p)} | {ratio(a, p)} | "
                         f"{ratio(t['auto'], p)}, {row['auto_chose']} | {faster} |")
        lines += ["", "Auto ran " + (f"the slower method at {', '.join(wrong)}" if wrong else
                                     "the faster method wherever one is faster") + ".", ""]
    return lines


def pendulum(r: dict, check) -> list[str]:
    t, p = r["seconds"], r["seconds"]["primal"]["median"]
    lines = [f"{r['n_elements']} elements, {r['n_x']} thickness variables, response "
             f"{', '.join(r['responses'])}, {r['steps']} steps.", "",
             "| run | median [s] | / primal | CPU / primal |", "|---|---|---|---|",
             f"| primal: build, compile, simulate, response | {s3(t['primal'])} | 1 | 1 |"]
    for m in ("direct", "adjoint", "auto"):
        label = f"auto (ran {r['auto_chose']})" if m == "auto" else m
        lines.append(f"| {label} | {s3(t[m])} | {ratio(t[m], p)} | "
                     f"{cpu_ratio(t[m], t['primal'])} |")
    b = r["ratios"]["best_over_primal"]
    cpu = r["ratios"].get("adjoint_cpu_over_primal")
    cpu_note = "" if cpu is None else f" (wall time; the adjoint's CPU time {cpu:.2f} primal's)"
    return lines + ["", f"Best / primal {b:.2f}{cpu_note}: target "
                        f"{check('pendulum.best_over_primal', b)}; adjoint gradient within "
                        f"{r['adjoint_vs_direct']:.1e} of direct.", ""]


def optimizers(r: dict, check) -> list[str]:
    b = r["budget"]
    lines = [f"{len(r['variables'])} variables; budget: SLSQP {b['maxiter']} iterations, "
             f"COBYLA {b['free_runs']} runs, finite-difference SLSQP "
             f"{b['fd_runs'] or 'within its own limits'}; target objective (0.1 % of the "
             f"exact optimum's improvement) {r['target']:.6g}. Run once.", "",
             "| optimizer | status | objective | feasible | runs | simulations | wall [s] | "
             "to target: runs | simulations | s |", "|---|---|---|---|---|---|---|---|---|---|"]
    for name, o in r["optimizers"].items():
        to = o["to_target"]
        cells = [("-" if to[k] is None else f"{to[k]:.0f}") for k in ("runs", "simulations",
                                                                      "time")]
        status = f"{o['status']}: {o.get('message', '')[:48]}".rstrip(": ")
        lines.append(f"| {name} | {status} | {o['objective']:.6g} | {o['feasible']} | "
                     f"{o['runs']} | {o['simulations']} | {o['wall_s']:.0f} | "
                     + " | ".join(cells) + " |")
    return lines + [""]


def elements(r: dict, check) -> list[str]:
    lines = [f"{r['steps']} steps per run.", "",
             "| elements | DOFs | primal per step [ms] | direct per step [ms] | direct set-up "
             "[s] | Newton it./step | peak memory [MiB] |", "|---|---|---|---|---|---|---|"]
    for row in r["rows"]:
        pr, di = ({k: 1e3 * row[key][k] for k in ("median", "min", "max")}  # [ms]
                  for key in ("primal_per_step_s", "direct_per_step_s"))
        lines.append(f"| {row['n_elements']} | {row['n_dof']} | {s3(pr)} | {s3(di)} | "
                     f"{row['direct_setup_s']:.3f} | {row['newton_iterations_per_step']:.2f} | "
                     f"{row['peak_memory_MiB']:.0f} |")
    f = r["fitted_exponent"]
    fit = ", ".join(f"{k.split('_')[0]} {v:.2f}" for k, v in f.items() if v is not None)
    return lines + ["", f"Fitted exponent of the time per step (≥ 100 elements): {fit}.", ""]


def memory(r: dict, check) -> list[str]:
    return ["| elements | DOFs | steps | budget [MiB] | primal [s] | adjoint [s] | segment "
            "steps | peak memory [MiB] |", "|---|---|---|---|---|---|---|---|",
            f"| {r['n_elements']} | {r['n_dof']} | {r['steps']} | {r['budget_MiB']} | "
            f"{r['primal_s']:.1f} | {r['adjoint_s']:.1f} | {r['segment_steps'] or 'all kept'} | "
            f"{r['peak_memory_MiB']:.0f} |", "", "One run in a fresh process.", ""]


def sweep(r: dict, check) -> list[str]:
    dask = (f"Dask LocalCluster of {r['dask_workers']} single-thread workers"
            if r.get("dask_workers") else "Dask not installed")
    lines = [f"{r['n_designs']} morphing designs, dt = {r['settings']['dt']:g} s, "
             f"{r['cpus']} CPUs, {dask}; overhead: a task that does nothing, {r['n_jobs']} "
             "jobs of one design (the pool's start included).", "",
             "| executor | designs/s | speed-up | time [s] | overhead per job [ms] |",
             "|---|---|---|---|---|"]
    for k, t in r["time_s"].items():
        lines.append(f"| {k} | {r['designs_per_s'][k]:.1f} | {r['speedup'].get(k, 1.0):.2f} | "
                     f"{s3(t)} | {r['overhead_per_job_ms'][k]:.3f} |")
    return lines + [""]


def exudyn(r: dict, check) -> list[str]:
    if "rows" not in r:
        return [r.get("skipped", "skipped"), ""]
    lines = [f"Exudyn {r['exudyn']['version']}. {r['notes']}", "",
             "| elements | morphlab [µs/step] | Exudyn full Newton | morphlab modified | "
             "Exudyn modified | morphlab direct [s] | Exudyn FD [s] | Exudyn FD / direct |",
             "|---|---|---|---|---|---|---|---|"]
    for x in r["rows"]:
        p, s = x["primal"], x["sensitivities"]["timing_s"]
        us = [1e6 * p[k]["per_step_s"]["median"] for k in (
            "morphlab", "exudyn_full_newton", "morphlab_modified_newton",
            "exudyn_modified_newton")]
        lines.append(f"| {x['n_elements']} | " + " | ".join(f"{u:.0f}" for u in us)
                     + f" | {s3(s['morphlab_direct'])} | {s3(s['exudyn_forward_difference'])} | "
                     f"{x['sensitivities']['ratios']['exudyn_fd_over_morphlab_direct']:.2f} |")
    return lines + [""]


def aero(r: dict, check) -> list[str]:
    """Flow evaluation, coupled solve, drag gradient (:func:`morphlab.bench.aero.render`)."""
    from .aero import render

    return render(r, check)
