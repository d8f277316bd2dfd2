"""Markdown tables of a benchmark record (:mod:`morphlab.bench` measures, this module renders;
``BENCHMARKS.md`` quotes the output). Reads only the JSON-shaped dict the suite writes, so a
saved ``benchmarks.json`` can be rendered again with ``table(json.load(fh))``."""

from __future__ import annotations

import json


def _morphing(m: dict) -> list[str]:
    """The morphing leading edge: each run's time and its ratio to the primal run."""
    lines = ["### Morphing leading edge (Table 2 on this machine)", "",
             "| run | median [s] | min | max | / primal |", "|---|---|---|---|---|"]
    prim = m["primal"]["median"]
    for key, label in (
            ("primal", "one primal run: build, compile, simulate, 3 responses"),
            ("direct", "direct differentiation, 5 variables (values and gradients)"),
            ("direct_fd", "direct with FD partial derivatives (paper's variant)"),
            ("adjoint", "discrete adjoint, 5 variables (values and gradients)"),
            ("finite_difference", "finite differences (n_x + 1 runs)"),
            ("primal_solver_only", "simulate a compiled model only (no build, no "
                                   "responses)"),
            ("primal_modified_newton", "the same with modified Newton (primal only)")):
        if key not in m:
            continue
        s = m[key]
        lines.append(f"| {label} | {s['median']:.4f} | {s['min']:.4f} | {s['max']:.4f} | "
                     f"{s['median'] / prim:.2f} |")
    rt = m["ratios"]
    best = (f"; finite differences / best of direct and adjoint = "
            f"{rt['finite_difference_over_best']:.2f}" if "finite_difference_over_best" in rt
            else "")
    lines += ["", f"finite differences / direct = {rt['finite_difference_over_direct']:.2f}"
                  f"{best}"
                  f"; direct / simulate-only = "
                  f"{rt.get('direct_over_primal_solver_only', float('nan')):.2f}; "
                  f"{m['steps']} steps, {m['newton_iterations_per_step']:.2f} Newton "
                  "iterations per step.", ""]
    if "direct_parts_s" in m:
        d = m["direct_parts_s"]
        lines += ["Inside a direct run (its own timers, median): " + ", ".join(
            f"{k} {v:.4f} s" for k, v in d.items()), ""]
    return lines


def _startup(s: dict) -> list[str]:
    """Import and first-result times of a fresh process, cold and warm."""
    lines = ["### Start-up", "", "| measure | median [s] |", "|---|---|",
             f"| import morphlab | {s['import']['median']:.3f} |",
             f"| fresh process to first result, empty Numba cache | "
             f"{s['cold_first_result']['median']:.2f} |",
             f"| fresh process to first result, filled cache | "
             f"{s['warm_first_result']['median']:.2f} |", ""]
    return lines


def _elements(e: dict) -> list[str]:
    """Time per step, Newton iterations and memory against the number of elements."""
    lines = ["### Growth with elements", "",
             "| elements | DOFs | primal per step [ms] | direct per step [ms] | direct "
             "set-up + responses [s] | Newton it./step | peak memory [MiB] |",
             "|---|---|---|---|---|---|---|"]
    for r in e["rows"]:
        dps = r["direct_per_step"]
        dps = dps[0] if isinstance(dps, list) else dps
        extra = r.get("direct_setup_s", float("nan")) + r.get("direct_responses_s", 0.0)
        lines.append(f"| {r['n_elements']} | {r['n_dof']} | "
                     f"{1e3 * r['primal_per_step'][0]:.3f} | {1e3 * dps:.3f} | "
                     f"{extra:.3f} | {r['newton_iterations_per_step']:.2f} | "
                     f"{r['peak_memory_MiB']:.0f} |")
    f = e["fitted_exponent"]
    lines += ["", f"fitted exponent (>= 100 elements): primal {f['primal_per_step']:.2f}, "
                  f"direct {f['direct_per_step']:.2f}", ""]
    return lines


def _variables(v: dict) -> list[str]:
    """Cost of direct, adjoint and finite differences against the number of variables."""
    lines = [f"### Cost against the number of design variables ({v['n_elements']}-element "
             f"skin, {len(v['responses'])} responses)", "",
             "| n_x | primal [s] | direct / primal | adjoint / primal | FD / primal |",
             "|---|---|---|---|---|"]
    for r in v["rows"]:
        o = r["over_primal"]
        lines.append(f"| {r['n_x']} | {r['seconds']['primal']:.4f} | {o['direct']:.2f} | "
                     f"{o['adjoint']:.2f} | {o['finite_difference']:.2f} |")
    c = v.get("crossover")
    lines += ["", "adjoint faster than direct above n_x = "
              + (f"{c:.1f}" if c is not None else "(no crossing in the range measured)"), ""]
    return lines


def _memory(mem: dict) -> list[str]:
    """Peak memory of the adjoint on a long run."""
    lines = ["### Peak memory of the adjoint on a long run", "",
             "| elements | DOFs | steps | budget [MiB] | primal [s] | adjoint [s] | "
             "segment steps | peak memory [MiB] |", "|---|---|---|---|---|---|---|---|",
             f"| {mem['n_elements']} | {mem['n_dof']} | {mem['steps']} | "
             f"{mem['budget_MiB']} | {mem['primal_s']:.1f} | {mem['adjoint_s']:.1f} | "
             f"{mem['segment_steps'] or 'all kept'} | {mem['peak_memory_MiB']:.0f} |", ""]
    return lines


def _profile(p: dict) -> list[str]:
    """Where the time of a direct run goes (cProfile)."""
    lines = ["### Where the time goes (direct run, cProfile)", "",
             "| part | seconds | share |", "|---|---|---|"]
    for k, sec in sorted(p["seconds"].items(), key=lambda kv: -kv[1]):
        lines.append(f"| {k} | {sec:.4f} | {100 * p['fractions'][k]:.1f} % |")
    lines.append("")
    return lines


def _floor(f: dict) -> list[str]:
    """Kernel times per call and the floor of direct / primal they imply."""
    lines = ["### The kernel floor of direct / primal (morphing model, one step)", "",
             "| kernel | µs per call (median) | min | max |", "|---|---|---|---|"]
    for k, v in f["kernels_us"].items():
        lines.append(f"| {k} | {v['median']:.1f} | {v['min']:.1f} | {v['max']:.1f} |")
    lines += ["", f"primal step: {f['newton_iterations_per_step']:.2f} iterations x "
                  f"(residual + matrix + factorization + 1-column solve) = "
                  f"{f['primal_step_us']:.1f} µs; sensitivity step at least split "
                  f"matrices + partial derivatives + 5-column solve = "
                  f"{f['sensitivity_step_us']:.1f} µs; floor of direct / primal = "
                  f"{f['floor_direct_over_primal']:.2f}; with one matrix and the solve "
                  "alone (free partial derivatives, the state part from a single fill): "
                  f"{f['one_matrix_and_solve_over_primal']:.2f}", ""]
    return lines


def _exudyn(x: dict) -> list[str]:
    """Side by side with Exudyn, or why the case was skipped."""
    if "rows" not in x:
        return ["### Exudyn", "", x.get("skipped", json.dumps(x)), ""]
    lines = ["### Side by side with Exudyn (flexible pendulum, same elements and steps)", "",
             "| elements | morphlab full Newton [µs/step] | Exudyn full Newton | morphlab "
             "modified Newton | Exudyn default (modified) | morphlab direct [s] | "
             "Exudyn FD [s] | Exudyn FD / morphlab direct |",
             "|---|---|---|---|---|---|---|---|"]
    for r in x["rows"]:
        p, s = r["primal"], r["sensitivities"]["timing_s"]
        mod = p.get("morphlab_modified_newton")
        mod_s = f"{1e6 * mod['per_step_s']['median']:.0f}" if mod else "-"
        lines.append(
            f"| {r['n_elements']} | {1e6 * p['morphlab']['per_step_s']['median']:.0f} | "
            f"{1e6 * p['exudyn_full_newton']['per_step_s']['median']:.0f} | {mod_s} | "
            f"{1e6 * p['exudyn_modified_newton']['per_step_s']['median']:.0f} | "
            f"{s['morphlab_direct']['median']:.3f} | "
            f"{s['exudyn_forward_difference']['median']:.3f} | "
            f"{r['sensitivities']['ratios']['exudyn_fd_over_morphlab_direct']:.2f} |")
    lines += ["", x.get("notes", ""), ""]
    return lines


def _sweep(record: dict) -> list[str]:
    """Parameter studies: serial, process pool and Dask."""
    from .sweeps import rows

    return rows(record)


#: The tables in the order they are written: (case name in the record, renderer).
_TABLES = (("morphing", _morphing), ("startup", _startup), ("elements", _elements),
           ("variables", _variables), ("memory", _memory), ("profile", _profile),
           ("floor", _floor), ("exudyn", _exudyn), ("sweep", _sweep))


def table(results: dict) -> str:
    """The results as Markdown tables, one per case the record holds."""
    lines = []
    for case, render in _TABLES:
        if results["cases"].get(case):
            lines += render(results["cases"][case])
    return "\n".join(lines)
