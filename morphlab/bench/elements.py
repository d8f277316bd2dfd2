"""Benchmark case ``elements``: time per step, Newton iterations and memory against the skin's
number of elements.

The morphing leading edge with a skin of 30 ... 3000 elements over a fixed number of steps of
the study's length, each size in a fresh process (its peak resident memory is the operating
system's): the primal run of a compiled model and a direct sensitivity run from the design
dict, each a median of interleaved rounds after a warm-up call; the exponent of a power law
fitted to the sizes of at least 100 elements.
"""

from __future__ import annotations

import json
import subprocess
import sys

import numpy as np


def peak_memory_mib() -> float:
    """Peak resident memory of this process [MiB]: ``VmHWM`` of ``/proc/self/status`` on Linux
    (``getrusage``'s ``ru_maxrss`` is no measure for a child process there: it starts from its
    parent's peak at the fork, so it reports a large parent's memory). Elsewhere
    ``ru_maxrss``, which may include the parent's peak."""
    try:
        with open("/proc/self/status", encoding="ascii") as fh:
            for line in fh:
                if line.startswith("VmHWM:"):
                    return int(line.split()[1]) / 1024.0
    except (OSError, ValueError, IndexError):
        pass
    import resource

    unit = 2.0**20 if sys.platform == "darwin" else 1024.0  # bytes on macOS, else KiB
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / unit


_SIZE_RUN = """
import json, sys
import numpy as np
import morphlab as ml
from morphlab import morphing as mo
from morphlab.bench.elements import peak_memory_mib
from morphlab.studies.timing import interleaved_times, time_stats
n_el, n_steps, repeats = int(sys.argv[1]), int(sys.argv[2]), int(sys.argv[3])
settings = ml.Settings.of(mo.SETTINGS, t_end=mo.SETTINGS.dt * n_steps)
p0 = dict(mo.DEFAULTS)
build = lambda p: mo.build(p, n_elements=n_el)
system = ml.compile_model(build(p0))
res = ml.simulate(system, settings=settings)
parts = []
def direct():
    parts.append(ml.sensitivities(build, p0, mo.RESPONSES, method="direct",
                                  settings=settings).timing)
direct()
t = interleaved_times({"primal": lambda: ml.simulate(system, settings=settings),
                       "direct": direct}, repeats)
per = {k: {s: v / n_steps for s, v in time_stats(ts).items() if s != "runs"}
       for k, ts in t.items()}
peak = peak_memory_mib()
print(json.dumps({"n_elements": n_el, "n_dof": system.n_dof, "steps": n_steps,
                  "newton_iterations_per_step": float(np.mean(res.newton_iterations[1:])),
                  "primal_per_step_s": per["primal"], "direct_per_step_s": per["direct"],
                  "direct_setup_s": float(np.median([p["setup"] for p in parts[1:]])),
                  "peak_memory_MiB": peak}))
"""


def case_elements(repeats: int, quick: bool) -> dict:
    """Rows per skin size (module docstring); ``quick``: 30, 100 and 300 elements over 20
    steps (else up to 3000 over 50, with half the repeats above 300 elements)."""
    sizes = [30, 100, 300] if quick else [30, 100, 300, 1000, 3000]
    n_steps = 20 if quick else 50
    rows = []
    for n_el in sizes:
        rep = repeats if n_el <= 300 else max(1, repeats // 2)
        proc = subprocess.run([sys.executable, "-c", _SIZE_RUN, str(n_el), str(n_steps),
                               str(rep)], capture_output=True, text=True)
        if proc.returncode != 0:
            tail = " | ".join(proc.stderr.strip().splitlines()[-3:])
            raise RuntimeError(f"{n_el} elements: the run failed: {tail}")
        rows.append(json.loads(proc.stdout.strip().splitlines()[-1]))
    ne = np.array([r["n_elements"] for r in rows], dtype=float)
    fit = {}
    big = ne >= 100
    for key in ("primal_per_step_s", "direct_per_step_s"):
        t = np.array([r[key]["median"] for r in rows])
        fit[key] = (float(np.polyfit(np.log(ne[big]), np.log(t[big]), 1)[0])
                    if big.sum() >= 2 else None)
    return {"steps": n_steps, "rows": rows, "fitted_exponent": fit}
