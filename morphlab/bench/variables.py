"""Benchmark case ``variables``: the cost of gradients against the number of design variables.

The morphing leading edge with a finer skin (:data:`N_ELEMENTS` elements), three responses (KS
stress, RMS and max shape error) and ``n_x`` variables: ``n_x - 4`` skin thicknesses, each of
a group of adjacent elements, and the bell-crank points ``x_B, y_B, x_D, y_D`` (for
``n_x = 1``: one thickness for the whole skin). For each ``n_x``: one primal run (build,
compile, simulate, responses), direct differentiation, the adjoint,
``auto`` and, where affordable, finite differences (n_x + 1 primal runs), all from the design
dict to the gradients.

The direct method's cost grows with the variables, the adjoint's with the responses, so the
case also measures direct, adjoint and ``auto`` at a few ``(n_x, m)`` with other numbers of
responses (:data:`RESPONSE_COUNTS`: the first ``m`` of the three, or the three and
displacements of skin nodes at the end of the run): where :class:`morphlab.Auto`'s crossover
comes from.
"""

from __future__ import annotations

import dataclasses

import numpy as np

import morphlab as ml

from ..morphing import leading_edge as mo
from ..studies.timing import interleaved_times, time_stats
from .gradients import gradient_difference, rounds

#: Skin elements of the model (groups of ~1 element at 200 variables).
N_ELEMENTS = 240
LINK_POINTS = ("x_B", "y_B", "x_D", "y_D")
#: The ``(n_x, m)`` of the rows with other numbers of responses (module docstring).
RESPONSE_COUNTS = ((1, 1), (1, 6), (1, 12), (5, 15))


def problem(n_x: int, n_elements: int = N_ELEMENTS, n_responses: int = 3):
    """``(build, p0, responses)`` with ``n_x`` variables and ``n_responses`` responses
    (module docstring)."""
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
    return build, p0, _responses(build, p0, n_responses)


def _responses(build, p0, m: int) -> dict:
    """The first ``m`` of the study's three responses; beyond three, the x and y
    displacements, in turn, of skin nodes spread along it at the end of the run."""
    resp = dict(list(mo.RESPONSES.items())[:m])
    if m > len(resp):
        step = ml.simulate(build(p0), settings=dataclasses.replace(mo.SETTINGS,
                                                                    t_end=mo.SETTINGS.dt))
        nodes = np.real(step.node_positions("skin", 0))
        extra = m - len(resp)
        for j, i in enumerate(np.linspace(5, nodes.shape[0] - 6, extra).astype(int)):
            resp[f"u{j}"] = ml.responses.point_displacement("skin", tuple(nodes[i]), j % 2)
    return resp


def _timed(build, p0, resp, settings, repeats: int) -> tuple:
    """The primal (build, compile, simulate, responses), direct, adjoint and ``auto`` of one
    problem in interleaved rounds: ``(times, values, sens)`` as :func:`~morphlab.bench.
    gradients.rounds` gives them, and ``sens(method)`` the gradient's call."""
    def primal():
        r = ml.simulate(build(p0), settings=settings)
        return {k: f(r) for k, f in resp.items()}

    def sens(method):
        return lambda: ml.sensitivities(build, p0, resp, method=method, settings=settings)

    t, values = rounds({"primal": primal, "direct": sens("direct"), "adjoint": sens("adjoint"),
                        "auto": sens("auto")}, repeats)
    return t, values, sens


def _row(n_x: int, n_el: int, settings, repeats: int) -> dict:
    """The figures of one ``n_x`` (:func:`case_variables`)."""
    build, p0, resp = problem(n_x, n_el)
    t, values, sens = _timed(build, p0, resp, settings, repeats)
    fd_runs = 1 if n_x > 20 else max(1, repeats // 2)
    t["finite_difference"] = time_stats(interleaved_times(
        {"fd": sens("forward-difference")}, fd_runs)["fd"])
    med = {k: v["median"] for k, v in t.items()}
    over = {k: v / med["primal"] for k, v in med.items()}
    over["best"] = min(med["direct"], med["adjoint"]) / med["primal"]
    return {"n_x": n_x, "seconds": t, "over_primal": over, "auto_chose": values["auto"].method,
            "faster": "direct" if med["direct"] <= med["adjoint"] else "adjoint",
            "adjoint_vs_direct": gradient_difference(values["adjoint"], values["direct"]),
            "auto_vs_direct": gradient_difference(values["auto"], values["direct"]),
            "responses": list(resp)}


def case_variables(repeats: int, quick: bool) -> dict:
    """Wall time of primal, direct, adjoint, auto and finite differences against ``n_x``.

    For each ``n_x``: one untimed call of each method, then interleaved rounds (medians, min,
    max); finite differences (n_x + 1 primal runs) in rounds of their own, once where
    ``n_x > 20``. Every ratio is formed from medians of the same ``n_x``'s rounds. The
    gradients of the untimed calls are compared (adjoint and auto against direct), and
    ``auto_chose`` is the method :class:`morphlab.Auto` ran. An ``n_x`` that fails keeps its
    error in its row (the case fails when all do). ``quick``: a 60-element skin and ``n_x`` up
    to 20.
    """
    settings = mo.SETTINGS
    n_el = 60 if quick else N_ELEMENTS
    rows = []
    for n_x in ([1, 5, 20] if quick else [1, 5, 20, 50, 200]):
        try:
            rows.append(_row(n_x, n_el, settings, repeats))
        except Exception as exc:  # the other rows stay measurable
            rows.append({"n_x": n_x, "error": f"{type(exc).__name__}: {exc}"[:500]})
    good = [r for r in rows if "error" not in r]
    if not good:
        raise RuntimeError(f"every n_x failed, e.g. n_x = {rows[0]['n_x']}: {rows[0]['error']}")
    by_responses = []
    for n_x, m in (RESPONSE_COUNTS[:2] if quick else RESPONSE_COUNTS):
        try:
            by_responses.append(_responses_row(n_x, m, n_el, settings, repeats))
        except Exception as exc:  # the other rows stay measurable
            by_responses.append({"n_x": n_x, "m": m,
                                 "error": f"{type(exc).__name__}: {exc}"[:500]})
    return {"n_elements": n_el, "responses": good[0]["responses"],
            "settings": dataclasses.asdict(settings), "rows": rows,
            "crossover": _crossover(good), "by_responses": by_responses}


def _responses_row(n_x: int, m: int, n_el: int, settings, repeats: int) -> dict:
    """Direct, adjoint and ``auto`` at ``n_x`` variables and ``m`` responses, in primal runs
    (medians of interleaved rounds)."""
    t, values, _ = _timed(*problem(n_x, n_el, m), settings, repeats)
    med = {k: v["median"] for k, v in t.items()}
    return {"n_x": n_x, "m": m, "seconds": t, "auto_chose": values["auto"].method,
            "faster": "direct" if med["direct"] <= med["adjoint"] else "adjoint",
            "adjoint_vs_direct": gradient_difference(values["adjoint"], values["direct"])}


def _crossover(rows: list) -> float | None:
    """The n_x above which the adjoint is faster than direct (linear interpolation of the
    measured difference), None if it is never or always faster."""
    nx = np.array([r["n_x"] for r in rows], dtype=float)
    diff = np.array([r["seconds"]["adjoint"]["median"] - r["seconds"]["direct"]["median"]
                     for r in rows])
    for k in range(len(nx) - 1):
        if diff[k] > 0 >= diff[k + 1]:
            return float(nx[k] + (nx[k + 1] - nx[k]) * diff[k] / (diff[k] - diff[k + 1]))
    return None
