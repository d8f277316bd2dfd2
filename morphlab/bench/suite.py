"""Benchmark suite: ``python -m morphlab.bench [--quick] [--out FILE] [--cases ...]``.

Every figure is a median over repeated runs in one process after a warm-up run, reported
with min and max, and every ratio is formed from figures of the same run (the machine is
shared and noisy). Cases:

``morphing``   the leading edge on its defaults: primal, direct (complex-step pseudo-loads),
               direct-fd (the paper's forward-difference pseudo-loads), finite differences with
               n_x + 1 primal runs; the ratios (the paper's Table 2).
``startup``    import time, and fresh-process time to the first morphing result with an empty
               (cold) and a filled (warm) Numba cache.
``elements``   the skin meshed with 30 ... 3000 elements: time per step of primal and direct,
               Newton iterations per step, peak memory (fresh process each), fitted exponent.
``variables``  1, 5, 20, 50, 200 design variables on a 240-element skin (thickness per group
               of elements and the bell-crank points), three responses: primal, direct,
               adjoint and finite differences against n_x, and the crossover
               (:mod:`morphlab.bench.variables`).
``memory``     peak memory and time of the adjoint, 3000-element skin over 10 000 steps
               (:mod:`morphlab.bench.memory`).
``profile``    where the time of the morphing direct run goes (cProfile, grouped).
``exudyn``     the same flexible pendulum in Exudyn (optional extra ``bench``), if installed.
``sweep``      parameter studies: morphing designs/s serial, local pool, Dask LocalCluster
               (if installed), the speed-ups, and the overhead per job (:mod:`.sweeps`).

Results go to a JSON file and Markdown tables (:mod:`morphlab.bench_report`; ``BENCHMARKS.md``
holds the latest).
"""

from __future__ import annotations

import argparse
import cProfile
import json
import os
import platform
import pstats
import subprocess
import sys
import tempfile
import time
from datetime import datetime, timezone

import numpy as np

from ..studies.timing import interleaved_times, time_stats, timed
from .memory import case_memory
from .report import table
from .variables import case_variables


def _rounds(fns: dict, repeats: int) -> dict:
    """Median, min and max of each function: a warm-up call each, then interleaved rounds
    (:func:`interleaved_times`; the ratios are formed within one round set)."""
    for fn in fns.values():
        fn()
    return {k: time_stats(v) for k, v in interleaved_times(fns, repeats).items()}


def _morphing():
    from ..morphing import leading_edge as morphing

    return morphing


# ---------------------------------------------------------------------------------------------
def case_morphing(repeats: int, quick: bool) -> dict:
    """Table 2 on this machine.

    ``primal`` is what one analysis of a design costs a user: build and compile the model from
    the design dict, simulate, evaluate the three responses (as notebook 04 times it); the
    sensitivity methods start from the same dict and return the values and the gradients.
    ``primal_solver_only`` (simulate a compiled model, no responses) is kept for reference.
    All runs use full Newton; ``primal_modified_newton`` is the faster primal alone.
    """
    import morphlab as ml

    mo = _morphing()
    settings = dict(mo.SETTINGS)
    p0 = dict(mo.DEFAULTS)
    resp = mo.RESPONSES
    system = ml.compile_model(mo.build(p0))

    def primal():
        r = ml.simulate(mo.build(p0), **settings)
        return {k: f(r) for k, f in resp.items()}

    def sens(method):
        return lambda: ml.sensitivities(mo.build, p0, resp, method=method, **settings)

    out = {"n_x": len(p0), "settings": settings}
    out.update(_rounds({
        "primal": primal,
        "primal_solver_only": lambda: ml.simulate(system, **settings),
        "primal_modified_newton": lambda: ml.simulate(system, newton="modified", **settings),
        "direct": sens("direct"),
        "direct_fd": sens("direct-fd"),
        "adjoint": sens("adjoint"),
    }, repeats))
    out["finite_difference"] = timed(sens("forward-difference"), max(1, repeats // 2))[0]
    prim = out["primal"]["median"]
    solver = out["primal_solver_only"]["median"]
    out["ratios"] = {
        "direct_over_primal": out["direct"]["median"] / prim,
        "direct_fd_over_primal": out["direct_fd"]["median"] / prim,
        "finite_difference_over_primal": out["finite_difference"]["median"] / prim,
        "finite_difference_over_direct": (out["finite_difference"]["median"]
                                          / out["direct"]["median"]),
        "adjoint_over_primal": out["adjoint"]["median"] / prim,
        "finite_difference_over_best": (out["finite_difference"]["median"]
                                        / min(out["direct"]["median"],
                                              out["adjoint"]["median"])),
        "direct_over_primal_solver_only": out["direct"]["median"] / solver,
    }
    # where the extra time of a direct run goes (its own timers, median over runs)
    parts = [ml.sensitivities(mo.build, p0, resp, method="direct", **settings).timing
             for _ in range(max(1, repeats))]
    out["direct_parts_s"] = {k: float(np.median([t[k] for t in parts])) for k in parts[0]}
    res = ml.simulate(system, **settings)
    out["steps"] = int(res.n_t - 1)
    out["newton_iterations_per_step"] = float(np.mean(res.newton_iterations[1:]))
    return out


# ---------------------------------------------------------------------------------------------
_FIRST_RESULT = (
    "import time; t0 = time.perf_counter(); import morphlab as ml; "
    "from morphlab import morphing as mo; "
    "r = ml.simulate(mo.build(mo.DEFAULTS), **mo.SETTINGS); "
    "print(time.perf_counter() - t0)"
)


def _fresh(code: str, env: dict | None = None) -> float:
    """Wall time of ``python -c code`` in a fresh process (seconds, whole process)."""
    t0 = time.perf_counter()
    subprocess.run([sys.executable, "-c", code], check=True, env=env, capture_output=True)
    return time.perf_counter() - t0


def case_startup(repeats: int, quick: bool) -> dict:
    out = {}
    out["import"] = time_stats([_fresh("import morphlab") for _ in range(repeats)])
    cold = []
    for _ in range(1 if quick else 2):
        with tempfile.TemporaryDirectory() as cache:
            env = dict(os.environ, NUMBA_CACHE_DIR=cache)
            cold.append(_fresh(_FIRST_RESULT, env))
    out["cold_first_result"] = time_stats(cold)
    _fresh(_FIRST_RESULT)  # fill the default cache
    out["warm_first_result"] = time_stats([_fresh(_FIRST_RESULT) for _ in range(repeats)])
    return out


# ---------------------------------------------------------------------------------------------
_SIZE_RUN = """
import json, resource, sys, time
import numpy as np
import morphlab as ml
from morphlab import morphing as mo
n_el, n_steps, repeats = int(sys.argv[1]), int(sys.argv[2]), int(sys.argv[3])
settings = dict(mo.SETTINGS)
settings["t_end"] = settings["dt"] * n_steps
p0 = dict(mo.DEFAULTS)
build = lambda p: mo.build(p, n_elements=n_el)
system = ml.compile_model(build(p0))
def med(fn):
    fn(); ts = []
    for _ in range(repeats):
        t0 = time.perf_counter(); fn(); ts.append(time.perf_counter() - t0)
    return float(np.median(ts)), float(min(ts)), float(max(ts))
res = ml.simulate(system, **settings)
primal = med(lambda: ml.simulate(system, **settings))
runs = []
direct = med(lambda: runs.append(ml.sensitivities(build, p0, mo.RESPONSES, method="direct",
                                                  **settings).timing))
part = {k: float(np.median([t[k] for t in runs])) for k in ("run", "setup", "responses")}
peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0
print(json.dumps({"n_elements": n_el, "n_dof": system.n_dof, "steps": n_steps,
                  "newton_iterations_per_step": float(np.mean(res.newton_iterations[1:])),
                  "primal_per_step": [x / n_steps for x in primal],
                  "direct_per_step": part["run"] / n_steps,
                  "direct_total_per_step": [x / n_steps for x in direct],
                  "direct_setup_s": part["setup"], "direct_responses_s": part["responses"],
                  "peak_memory_MiB": peak}))
"""


def case_elements(repeats: int, quick: bool) -> dict:
    sizes = [30, 100, 300] if quick else [30, 100, 300, 1000, 3000]
    n_steps = 20 if quick else 50
    rows = []
    for n_el in sizes:
        rep = repeats if n_el <= 300 else max(1, repeats // 2)
        proc = subprocess.run([sys.executable, "-c", _SIZE_RUN, str(n_el), str(n_steps),
                               str(rep)], check=True, capture_output=True, text=True)
        rows.append(json.loads(proc.stdout.strip().splitlines()[-1]))
    ne = np.array([r["n_elements"] for r in rows], dtype=float)
    fit = {}
    for key in ("primal_per_step", "direct_per_step"):
        t = np.array([r[key][0] if isinstance(r[key], list) else r[key] for r in rows])
        big = ne >= 100
        fit[key] = float(np.polyfit(np.log(ne[big]), np.log(t[big]), 1)[0]) if big.sum() >= 2 \
            else float("nan")
    return {"rows": rows, "fitted_exponent": fit}


# ---------------------------------------------------------------------------------------------
_GROUPS = (
    ("compiled Newton loops (residual, matrix, factorization, solve per iteration)",
     ("newton_loop",)),
    ("assembly kernels (residual, Newton matrix)",
     ("step_residual", "step_matrix", "add_residual", "fill_matrix", "apply_correction")),
    ("sensitivity kernels (pseudo-loads, recursion, update, refinement residual)",
     ("state_loads", "explicit_loads", "explicit_block", "block_recursion",
      "update_sensitivities", "csc_residual")),
    ("factorization", ("gstrf", "lu_factor", "csc_to_dense", "sparse_lu.py:refactor",
                       "sparse_lu.py:symbolic")),
    ("solves", ("'solve' of 'SuperLU'", "dense.py:lu_solve", "sparse_lu.py:solve")),
    ("sparse matrix construction", ("scipy/sparse/_compressed.py", "scipy/sparse/_csc.py",
                                    "scipy/sparse/_sputils.py", "scipy/sparse/_base.py")),
    ("stacking a block's kept factors and states (np.stack)", ("shape_base.py:stack",)),
    ("compile (model -> arrays)", ("compile.py",)),
    ("time tables", ("time_table", "profiles.py")),
)


def case_profile(repeats: int, quick: bool) -> dict:
    import morphlab as ml

    mo = _morphing()
    settings = dict(mo.SETTINGS)
    p0 = dict(mo.DEFAULTS)
    ml.sensitivities(mo.build, p0, mo.RESPONSES, method="direct", **settings)
    prof = cProfile.Profile()
    prof.enable()
    ml.sensitivities(mo.build, p0, mo.RESPONSES, method="direct", **settings)
    prof.disable()
    st = pstats.Stats(prof)
    total = sum(v[2] for v in st.stats.values())  # tottime
    out = {name: 0.0 for name, _ in _GROUPS}
    other = 0.0
    for (file, _line, func), v in st.stats.items():
        label = f"{file}:{func}"
        for name, keys in _GROUPS:
            if any(k in label for k in keys):
                out[name] += v[2]
                break
        else:
            other += v[2]
    out["python and numpy (other)"] = other
    return {"total_s": total, "seconds": out,
            "fractions": {k: v / total for k, v in out.items()}}


# ---------------------------------------------------------------------------------------------


# ---------------------------------------------------------------------------------------------
def case_exudyn(repeats: int, quick: bool) -> dict:
    try:
        import exudyn  # noqa: F401
    except ImportError:
        return {"skipped": "exudyn is not installed (pip install -e '.[bench]')"}
    from . import exudyn as _bench_exudyn

    return _bench_exudyn.run(repeats, quick)


def case_sweep(repeats: int, quick: bool) -> dict:
    from . import sweeps

    return sweeps.run(repeats, quick)


CASES = {"morphing": case_morphing, "startup": case_startup, "elements": case_elements,
         "variables": case_variables, "memory": case_memory, "profile": case_profile,
         "exudyn": case_exudyn, "sweep": case_sweep}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="python -m morphlab.bench", description=__doc__.split(
        "\n")[0])
    ap.add_argument("--quick", action="store_true", help="smaller sizes and fewer repeats")
    ap.add_argument("--repeats", type=int, default=None, help="runs per figure (default 7; "
                    "quick: 3)")
    ap.add_argument("--cases", default=",".join(CASES), help="comma-separated subset of "
                    + ", ".join(CASES))
    ap.add_argument("--out", default="benchmarks.json", help="JSON output file")
    args = ap.parse_args(argv)
    repeats = args.repeats or (3 if args.quick else 7)
    chosen = [c.strip() for c in args.cases.split(",") if c.strip()]
    unknown = [c for c in chosen if c not in CASES]
    if unknown:
        print(f"morphlab.bench: unknown cases {unknown}; choose from {list(CASES)}",
              file=sys.stderr)
        return 2
    from ..warmup import warmup

    warmup()
    import morphlab

    results = {
        "command": "python -m morphlab.bench " + " ".join(argv if argv is not None
                                                          else sys.argv[1:]),
        "date": datetime.now(timezone.utc).isoformat(timespec="seconds"),
        "machine": {"platform": platform.platform(), "processor": platform.processor(),
                    "cpus": os.cpu_count(), "python": platform.python_version()},
        "versions": {"morphlab": morphlab.__version__, "numpy": np.__version__},
        "repeats": repeats,
        "cases": {},
    }
    for c in chosen:
        t0 = time.perf_counter()
        try:
            results["cases"][c] = CASES[c](repeats, args.quick)
        except (Exception, KeyboardInterrupt) as exc:  # keep the other cases' figures
            results["cases"][c] = {"error": f"{type(exc).__name__}: {exc}"[:2000]}
            print(f"[{c}: failed: {type(exc).__name__}]", file=sys.stderr)
        print(f"[{c}: {time.perf_counter() - t0:.1f} s]", file=sys.stderr)
    with open(args.out, "w", encoding="utf-8") as fh:
        json.dump(results, fh, indent=2)
    ok = {k: v for k, v in results["cases"].items() if "error" not in v}
    print(table(dict(results, cases=ok)))
    for k, v in results["cases"].items():
        if "error" in v:
            print(f"case {k} failed: {v['error']}")
    return 0
