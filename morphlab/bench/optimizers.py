"""Benchmark case ``optimizers``: notebook 05's optimizer comparison on its full budget.

The morphing leading edge as a 13-variable design problem
(:func:`morphlab.morphing.optimization.problem`) solved by SLSQP with exact (direct)
gradients, SLSQP with forward-difference gradients and COBYLA (derivative-free), by
:func:`morphlab.morphing.optimization.compare_optimizers` with the notebook's default budget
(60 SLSQP iterations, 400 COBYLA runs, finite differences within SLSQP's own limits). The
notebook shows the comparison on a reduced budget; this case records the whole of it (about
8 minutes on two cores, 7 of them the finite-difference run). For each optimizer: its end
(status, objective, feasibility), its runs and primal simulations and wall time, and what it
took to come within 0.1 % of the exact-gradient optimum's improvement
(:func:`~morphlab.morphing.optimization.reached`). The comparison runs once (``repeats``
does not apply): its figures are counts and one wall time each.
"""

from __future__ import annotations

import dataclasses
import sys

from ..solve.settings import Settings

#: The notebook's budgets: full, and reduced (its ``MORPHLAB_QUICK=1`` sizes).
FULL = {"maxiter": 60, "free_runs": 400, "fd_runs": None}
QUICK = {"maxiter": 30, "free_runs": 60, "fd_runs": 15}


def case_optimizers(repeats: int, quick: bool) -> dict:
    """The comparison (module docstring); ``quick``: the notebook's reduced budget and a time
    step of 1 ms (150 steps)."""
    from ..morphing import leading_edge as le
    from ..morphing import optimization as opt

    settings = Settings.of(le.SETTINGS, dt=1e-3) if quick else le.SETTINGS
    budget = QUICK if quick else FULL
    runs = opt.compare_optimizers(opt.problem(settings=settings), **budget,
                                  progress=sys.stderr.isatty())
    out = {"variables": list(opt.VARIABLES), "budget": budget,
           "settings": dataclasses.asdict(settings),
           "target": next(iter(runs.values()))["target"], "optimizers": {}}
    for name, r in runs.items():
        res = r["result"]
        out["optimizers"][name] = {
            "status": res.status, "message": res.message, "objective": res.objective,
            "feasible": bool(res.feasible),
            "runs": res.n_runs, "simulations": res.n_simulations, "wall_s": res.wall_time,
            "to_target": r["to_target"]}
    return out
