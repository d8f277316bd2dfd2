"""Benchmark case ``memory``: peak memory of the adjoint on a long run of a fine skin.

The morphing leading edge with a :data:`N_ELEMENTS`-element skin over :data:`N_STEPS` steps
(the study's 0.15 s with a step 300/N_STEPS times the study's), its three responses, gradients
with respect to the five variables of the paper by the adjoint, with a budget of
:data:`BUDGET_MIB` for the states and factorizations it keeps; beyond it the run keeps
checkpoints and the sweep recomputes segments (:mod:`morphlab.sensitivity.adjoint`). The
responses read the skin's whole history of coordinates (the KS stress aggregates all steps),
which the run keeps as well (the KS stress's gradient is formed over chunks of steps, its
derivative with respect to each step's coordinates when the sweep reaches it). The case runs
in a fresh process whose peak resident memory is read from the operating system
(:func:`morphlab.bench.elements.peak_memory_mib`); a primal run
of the same process is timed beside it.
"""

from __future__ import annotations

import json
import subprocess
import sys

N_ELEMENTS = 3000
N_STEPS = 10_000
BUDGET_MIB = 512

_RUN = """
import json, sys, time
import morphlab as ml
from morphlab import morphing as mo
from morphlab import Adjoint
from morphlab.bench.elements import peak_memory_mib
n_el, n_steps, budget = int(sys.argv[1]), int(sys.argv[2]), int(sys.argv[3])
settings = ml.Settings.of(mo.SETTINGS, dt=mo.SETTINGS.t_end / n_steps)
build = lambda p: mo.build(p, n_elements=n_el, skin="paper")
p0 = dict(mo.DEFAULTS)
t0 = time.perf_counter()
res = ml.simulate(build(p0), settings=settings, store=("q",))
primal = time.perf_counter() - t0
n_dof = res.system.n_dof
del res
t0 = time.perf_counter()
s = ml.sensitivities(build, p0, mo.RESPONSES, method=Adjoint(memory=budget * 2**20),
                     settings=settings)
adjoint = time.perf_counter() - t0
peak = peak_memory_mib()
print(json.dumps({"n_elements": n_el, "n_dof": n_dof, "steps": n_steps,
                  "budget_MiB": budget, "primal_s": primal, "adjoint_s": adjoint,
                  "segment_steps": s.stats.get("segment_steps"),
                  "peak_memory_MiB": peak}))
"""


def case_memory(repeats: int, quick: bool) -> dict:
    """Peak memory and time of the adjoint (module docstring); ``quick``: 300 elements over
    1000 steps."""
    n_el, n_steps = (300, 1000) if quick else (N_ELEMENTS, N_STEPS)
    proc = subprocess.run([sys.executable, "-c", _RUN, str(n_el), str(n_steps),
                           str(BUDGET_MIB)], capture_output=True, text=True)
    if proc.returncode != 0:
        tail = " | ".join(proc.stderr.strip().splitlines()[-3:])
        raise RuntimeError(f"the adjoint run failed: {tail}")
    return json.loads(proc.stdout.strip().splitlines()[-1])
