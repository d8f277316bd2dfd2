"""Benchmark case ``variables``: the cost of gradients against the number of design variables.

The morphing leading edge with a finer skin (:data:`N_ELEMENTS` elements), three responses (KS
stress, RMS and max shape error) and ``n_x`` variables: ``n_x - 4`` skin thicknesses, each of
a group of adjacent elements, and the bell-crank points ``x_B, y_B, x_D, y_D`` (for
``n_x = 1``: one thickness for the whole skin). For each ``n_x``: one primal run (build,
compile, simulate, responses), direct differentiation, the adjoint and, where affordable,
finite differences (n_x + 1 primal runs), all from the design dict to the gradients.
"""

from __future__ import annotations

import numpy as np

import morphlab as ml

from ..morphing import leading_edge as mo
from ..studies.timing import interleaved_times

#: Skin elements of the model (groups of ~1 element at 200 variables).
N_ELEMENTS = 240
LINK_POINTS = ("x_B", "y_B", "x_D", "y_D")


def problem(n_x: int, n_elements: int = N_ELEMENTS):
    """``(build, p0, responses)`` with ``n_x`` variables (module docstring)."""
    n_t = 1 if n_x == 1 else n_x - len(LINK_POINTS)
    groups = np.array_split(np.arange(n_elements), n_t)
    links = () if n_x == 1 else LINK_POINTS
    base = {**mo.DEFAULTS, **mo.GEOMETRY}

    def build(p):
        t = np.empty(n_elements, dtype=np.result_type(*(type(p[f"t{k}"]) for k in range(n_t)),
                                                      float))
        for k, g in enumerate(groups):
            t[g] = p[f"t{k}"]
        q = dict(base, t_w=t, **{k: p[k] for k in links})
        return mo.build(q, n_elements=n_elements)

    p0 = {f"t{k}": base["t_w"] for k in range(n_t)}
    p0.update({k: base[k] for k in links})
    return build, p0, dict(mo.RESPONSES)


def case_variables(repeats: int, quick: bool) -> dict:
    """Wall time of primal, direct, adjoint and finite differences against ``n_x``
    (medians of interleaved rounds; finite differences timed once where n_x > 20)."""
    settings = dict(mo.SETTINGS)
    n_el = 60 if quick else N_ELEMENTS
    rows = []
    for n_x in ([1, 5, 20] if quick else [1, 5, 20, 50, 200]):
        build, p0, resp = problem(n_x, n_el)

        def primal(build=build, p0=p0, resp=resp):
            r = ml.simulate(build(p0), **settings)
            return {k: f(r) for k, f in resp.items()}

        def sens(method, build=build, p0=p0, resp=resp):
            return lambda: ml.sensitivities(build, p0, resp, method=method, **settings)

        fns = {"primal": primal, "direct": sens("direct"), "adjoint": sens("adjoint")}
        for fn in fns.values():
            fn()  # warm-up
        t = {k: float(np.median(v)) for k, v in interleaved_times(fns, repeats).items()}
        fd_runs = 1 if n_x > 20 else max(1, repeats // 2)
        t["finite_difference"] = float(np.median(interleaved_times(
            {"fd": sens("forward-difference")}, fd_runs)["fd"]))
        rows.append({"n_x": n_x, "seconds": t,
                     "over_primal": {k: v / t["primal"] for k, v in t.items()}})
    return {"n_elements": n_el, "responses": list(resp), "settings": settings, "rows": rows,
            "crossover": _crossover(rows)}


def _crossover(rows: list) -> float | None:
    """The n_x above which the adjoint is faster than direct (linear interpolation of the
    measured difference), None if it is never or always faster."""
    nx = np.array([r["n_x"] for r in rows], dtype=float)
    diff = np.array([r["seconds"]["adjoint"] - r["seconds"]["direct"] for r in rows])
    for k in range(len(nx) - 1):
        if diff[k] > 0 >= diff[k + 1]:
            return float(nx[k] + (nx[k + 1] - nx[k]) * diff[k] / (diff[k] - diff[k + 1]))
    return None
