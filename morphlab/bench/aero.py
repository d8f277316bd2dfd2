"""Benchmark case ``aero``: what the flight loads cost.

* one flow evaluation of the target section at the thermalling condition (target CL: the
  angle of attack found by a scan and Newton), with and without the panel method's pressure
  distribution, and from a nearby start angle (what a response's perturbed evaluations and
  the aeroelastic passes do);
* one coupled solve: the static aeroelastic equilibrium of the leading edge at each
  configuration (vacuum statics, then flow <-> statics passes to 1e-6 mm), with the share of
  statics and flow and the number of passes;
* the gradient of the drag and the design problem's responses by the 13 variables of the
  design problem (one direct sensitivity run: the objective's cost per optimizer iteration).

Each function runs once untimed, then in interleaved rounds (:mod:`morphlab.bench.gradients`).
``quick`` times the gradient on 150-step runs (dt 1 ms) instead of the study's 300.

The flow evaluation is timed again in a child process with one BLAS thread
(``OPENBLAS_NUM_THREADS=OMP_NUM_THREADS=1``), the control of
:class:`~morphlab.jit.threads.one_blas_thread`, under which ``analyze`` itself runs:
NeuralFoil's small matrix products and the panel solve gain nothing from a second thread, and
on a machine whose cores are busy the BLAS threads wait for each other (measured 15 ms
single-threaded against a median of 176 ms with two threads at load 4 on 2 cores).
"""

from __future__ import annotations

import json
import os
import subprocess
import sys

from ..solve.settings import Settings

#: The child process of the single-threaded flow timing: prints the times [s] as JSON.
_CHILD = """
import json, sys, time
from morphlab.morphing import aero, flight
from morphlab.morphing import leading_edge as le
xy, cond = aero.section(le.target()), flight.THERMALLING
out = {}
for key, kw in (("target_cl", {}), ("target_cl_no_pressure", {"pressure": False})):
    aero.analyze(xy, cond, **kw)
    times = []
    for _ in range(int(sys.argv[1])):
        t0 = time.perf_counter()
        aero.analyze(xy, cond, **kw)
        times.append(time.perf_counter() - t0)
    out[key] = times
print(json.dumps(out))
"""


def _single_thread_flow(repeats: int) -> dict:
    """Flow evaluations [s] in a child process with one BLAS thread (module docstring)."""
    from ..studies.timing import time_stats

    env = dict(os.environ, OPENBLAS_NUM_THREADS="1", OMP_NUM_THREADS="1",
               MKL_NUM_THREADS="1")
    proc = subprocess.run([sys.executable, "-c", _CHILD, str(max(repeats, 3))], env=env,
                          capture_output=True, text=True, check=True)
    times = json.loads(proc.stdout.strip().splitlines()[-1])
    return {k: time_stats(v) for k, v in times.items()}


def case_aero(repeats: int, quick: bool) -> dict:
    """The case (module docstring): ``{"flow_s": ..., "coupled_s": ..., "passes": ...,
    "share": ..., "gradient_s": ..., ...}`` with :func:`~morphlab.studies.timing.time_stats`
    of each timed figure."""
    import morphlab as ml

    from ..morphing import aero, aero_design, flight, flight_loads
    from ..morphing import leading_edge as le
    from ..morphing import optimization as opt
    from .gradients import rounds

    xy = aero.section(le.target())
    cond = flight.THERMALLING
    alpha = aero.analyze(xy, cond, pressure=False).alpha
    flows, values = rounds({
        "target_cl": lambda: aero.analyze(xy, cond),
        "target_cl_no_pressure": lambda: aero.analyze(xy, cond, pressure=False),
        "from_start_angle": lambda: aero.analyze(xy, cond, alpha_start=alpha + 0.01),
        "fixed_alpha": lambda: aero.analyze(xy, cond.at(alpha=alpha)),
    }, repeats)
    coupled, eqs = rounds({
        name: (lambda name=name: flight_loads.configuration(name))
        for name in flight_loads.CONFIGURATIONS}, repeats)
    settings = Settings.of(le.SETTINGS, dt=1e-3) if quick else le.SETTINGS
    p0, responses = opt.start(), aero_design.responses()
    grad, _ = rounds({
        "design_problem_13": lambda: ml.sensitivities(
            opt.build, p0, responses, variables=list(opt.VARIABLES), method="direct",
            settings=settings),
        "primal": lambda: ml.simulate(opt.build(p0), settings=settings),
    }, repeats)
    return {
        "flow_s": flows, "flow_one_blas_thread_s": _single_thread_flow(repeats),
        "coupled_s": coupled, "gradient_s": grad,
        "settings": {"t_end": settings.t_end, "dt": settings.dt},
        "passes": {k: r.iterations for k, r in eqs.items()},
        "share_s": {k: {"static": r.timing["static"], "flow": r.timing["flow"]}
                    for k, r in eqs.items()},
        "deflection_max_mm": {k: r.deflection_max for k, r in eqs.items()},
        "cd_counts": values["target_cl"].cd_counts,
        "variables": len(opt.VARIABLES),
    }


def render(r: dict, check) -> list[str]:
    """The case's section of the details page (:mod:`morphlab.bench.report_cases`)."""
    from .report_cases import ratio, s3

    f, c, g = r["flow_s"], r["coupled_s"], r["gradient_s"]
    base = f["target_cl"]["median"]
    lines = ["| flow evaluation (target section, thermalling, target CL) | median [s] | "
             "/ with pressure |", "|---|---|---|",
             f"| NeuralFoil + panel method (the pressure on the skin) | {s3(f['target_cl'])} "
             "| 1 |",
             f"| NeuralFoil only (`pressure=False`: CL, CD, transition) | "
             f"{s3(f['target_cl_no_pressure'])} | {ratio(f['target_cl_no_pressure'], base)} |",
             f"| from a nearby start angle (no scan for the CL) | {s3(f['from_start_angle'])} | "
             f"{ratio(f['from_start_angle'], base)} |",
             f"| at a given angle of attack | {s3(f['fixed_alpha'])} | "
             f"{ratio(f['fixed_alpha'], base)} |"]
    one = r.get("flow_one_blas_thread_s")
    if one:
        lines += [f"| one BLAS thread (child process): with pressure | "
                  f"{s3(one['target_cl'])} | {ratio(one['target_cl'], base)} |",
                  f"| one BLAS thread: NeuralFoil only | {s3(one['target_cl_no_pressure'])} | "
                  f"{ratio(one['target_cl_no_pressure'], base)} |"]
    lines += ["",
             "| coupled solve (aeroelastic equilibrium, tol 1e-6 mm) | median [s] | passes | "
             "statics / flow [s] (untimed call) | deflection max [mm] |",
             "|---|---|---|---|---|"]
    for k, st in c.items():
        sh = r["share_s"][k]
        lines.append(f"| {k} | {s3(st)} | {r['passes'][k]} | {sh['static']:.3f} / "
                     f"{sh['flow']:.3f} | {r['deflection_max_mm'][k]:.4f} |")
    prim = g["primal"]["median"]
    lines += ["", f"| drag and the design responses by {r['variables']} variables "
              f"(dt {r['settings']['dt']:g} s) | median [s] | / primal |", "|---|---|---|",
              f"| primal run | {s3(g['primal'])} | 1 |",
              f"| direct sensitivities with the drag (2 flow analyses per variable) | "
              f"{s3(g['design_problem_13'])} | {ratio(g['design_problem_13'], prim)} |", ""]
    return lines
