"""Benchmark cases ``morphing`` (the paper's Table 2) and ``pendulum``: what a gradient costs
in primal runs.

Every method starts from the design dict, as a user calls it: the primal is build, compile,
simulate and the responses; a sensitivity method returns the values and the gradients. Each
function is called once untimed (kernels loaded, caches warm), then timed in interleaved
rounds (:func:`morphlab.studies.timing.interleaved_times`), and every ratio is formed from
medians of the same rounds. The gradients of the warm-up calls are compared with each other,
so a figure is never that of a method returning something else.
"""

from __future__ import annotations

import dataclasses

import numpy as np

import morphlab as ml

from ..solve.settings import Settings
from ..studies.timing import interleaved_times, time_stats


def rounds(fns: dict, repeats: int) -> tuple[dict, dict]:
    """One untimed call of each function (its value kept), then ``repeats`` interleaved
    rounds: ``({name: time_stats with "cpu_median"}, {name: value of the untimed call})``
    (:func:`with_cpu`)."""
    values = {k: fn() for k, fn in fns.items()}
    cpu: dict = {}
    times = interleaved_times(fns, repeats, cpu=cpu)
    return {k: with_cpu(v, cpu[k]) for k, v in times.items()}, values


def with_cpu(wall: list, cpu: list) -> dict:
    """:func:`~morphlab.studies.timing.time_stats` of the wall times, with the median of the
    process CPU times of the same calls (``cpu_median``: the adjoint forms its design data on
    a second core while the primal runs, which the wall time does not count)."""
    return {**time_stats(wall), "cpu_median": float(np.median(cpu))}


def gradient_difference(a, b) -> float:
    """Largest difference of the gradients of two SensitivityResults, relative to the largest
    entry of ``b``'s gradient of the same response (over all responses)."""
    worst = 0.0
    for r, gb in b.gradients.items():
        ref = max(abs(v) for v in gb.values()) or 1.0
        worst = max(worst, max(abs(a.gradients[r][v] - gb[v]) for v in gb) / ref)
    return float(worst)


def _primal(build, p0, responses, settings):
    def primal():
        res = ml.simulate(build(dict(p0)), settings=settings)
        return {k: f(res) for k, f in responses.items()}

    return primal


def _method(build, p0, responses, settings, method):
    return lambda: ml.sensitivities(build, p0, responses, method=method, settings=settings)


# ---------------------------------------------------------------------------------- morphing
def case_morphing(repeats: int, quick: bool, *, settings: Settings | None = None) -> dict:
    """Table 2 on the morphing defaults (5 variables, 3 responses).

    The study's own timing (:func:`morphlab.morphing.paper._timing`, what ``morphlab
    morphing`` prints: primal, simulate only, direct, direct-fd and adjoint interleaved, then
    finite differences with n_x + 1 primal runs) gives Table 2; a second interleaved set times
    ``auto`` and the whole-run complex step against a primal of its own. ``quick`` doubles
    the time step (as ``morphlab morphing --quick``); ``settings`` replaces the study's.
    """
    from ..morphing import leading_edge as le
    from ..morphing.paper import _timing

    if settings is None:
        settings = Settings.of(le.SETTINGS, dt=2.0 * le.SETTINGS.dt) if quick else le.SETTINGS
    p0, resp, build = dict(le.DEFAULTS), dict(le.RESPONSES), le.build
    fd_step = 1e-6
    methods = {"direct": "direct", "adjoint": "adjoint", "complex-step": "complex-step",
               "direct-fd": ml.Direct(partials="forward-difference", step=fd_step)}
    warm = {}
    for name, method in methods.items():  # untimed; a method that fails is named
        try:
            warm[name] = _method(build, p0, resp, settings, method)()
        except Exception as exc:
            raise RuntimeError(f"method {name!r} failed on the morphing defaults: "
                               f"{type(exc).__name__}: {exc}") from exc
    t2 = _timing(build, p0, resp, settings, repeats, fd_step)
    table2 = {k: with_cpu(t2[f"{k}_runs"], t2[f"{k}_cpu_runs"]) for k in (
        "primal", "primal_solver_only", "direct", "direct_fd", "adjoint", "finite_difference")}
    second, values = rounds({"primal": _primal(build, p0, resp, settings),
                             "auto": _method(build, p0, resp, settings, "auto"),
                             "complex_step": _method(build, p0, resp, settings,
                                                     "complex-step")}, repeats)
    med = {k: v["median"] for k, v in table2.items()}
    best = min(med["direct"], med["adjoint"])
    ratios = {f"{k}_over_primal": med[k] / med["primal"] for k in (
        "direct", "direct_fd", "adjoint", "finite_difference")}
    cpu = {k: v["cpu_median"] for k, v in table2.items()}
    ratios.update({f"{k}_cpu_over_primal": cpu[k] / cpu["primal"] for k in (
        "direct", "direct_fd", "adjoint", "finite_difference")})
    ratios.update({"best_over_primal": best / med["primal"],
                   "finite_difference_over_best": med["finite_difference"] / best,
                   "finite_difference_over_direct": med["finite_difference"] / med["direct"],
                   "auto_over_primal": second["auto"]["median"] / second["primal"]["median"],
                   "complex_step_over_primal": (second["complex_step"]["median"]
                                                / second["primal"]["median"])})
    ref = warm["complex-step"]
    res = ml.simulate(build(p0), settings=settings)
    return {
        "n_x": len(p0), "responses": list(resp), "settings": dataclasses.asdict(settings),
        "steps": int(res.n_t - 1),
        "newton_iterations_per_step": float(np.mean(res.newton_iterations[1:])),
        "table2_s": table2, "second_set_s": second, "ratios": ratios,
        "auto_chose": values["auto"].method, "fd_step": fd_step,
        "paper_table2_s": dict(le.PAPER["table2_s"]),
        "gradient_difference_to_complex_step": {
            "direct": gradient_difference(warm["direct"], ref),
            "adjoint": gradient_difference(warm["adjoint"], ref),
            "auto": gradient_difference(values["auto"], ref),
            "direct-fd": gradient_difference(warm["direct-fd"], ref)},
    }


# ---------------------------------------------------------------------------------- pendulum
#: Elements of the pendulum, one thickness variable each.
PENDULUM_ELEMENTS = 32


class PendulumBuild:
    """The flexible pendulum of :mod:`morphlab.bench.exudyn` with one thickness variable per
    element, ``p["t0"] ... p["t{n-1}"]`` [mm] (complex-safe)."""

    def __init__(self, n_elements: int):
        self.n_elements = n_elements

    def __call__(self, p: dict):
        from . import exudyn as pendulum

        t = np.array([p[f"t{k}"] for k in range(self.n_elements)])
        return pendulum.build({"t": t, "E": pendulum.E_MOD}, self.n_elements)


def case_pendulum(repeats: int, quick: bool) -> dict:
    """The flexible pendulum of the Exudyn comparison (a 500 mm aluminium strip pinned at one
    end, released under gravity, 0.2 s in 1000 steps) with :data:`PENDULUM_ELEMENTS`
    thickness variables and one response, the final vertical displacement of the tip: primal,
    direct, adjoint and auto in interleaved rounds. ``quick``: 8 elements over 250 steps of
    the same length."""
    from . import exudyn as pendulum

    n_el = 8 if quick else PENDULUM_ELEMENTS
    n_steps = 250 if quick else pendulum.N_STEPS
    dt = pendulum.T_END / pendulum.N_STEPS
    settings = Settings.of(None, t_end=n_steps * dt, dt=dt, rho_inf=pendulum.RHO_INF)
    build = PendulumBuild(n_el)
    p0 = {f"t{k}": pendulum.THICKNESS for k in range(n_el)}
    resp = {"tip_y": ml.responses.point_displacement("strip", (pendulum.LENGTH, 0.0), 1)}
    fns = {"primal": _primal(build, p0, resp, settings)}
    fns.update({m: _method(build, p0, resp, settings, m) for m in ("direct", "adjoint", "auto")})
    t, values = rounds(fns, repeats)
    prim = t["primal"]["median"]
    best = min(t["direct"]["median"], t["adjoint"]["median"])
    return {
        "n_elements": n_el, "n_x": n_el, "steps": n_steps, "responses": list(resp),
        "settings": dataclasses.asdict(settings), "seconds": t,
        "ratios": {**{f"{m}_over_primal": t[m]["median"] / prim
                      for m in ("direct", "adjoint", "auto")},
                   **{f"{m}_cpu_over_primal": t[m]["cpu_median"] / t["primal"]["cpu_median"]
                      for m in ("direct", "adjoint", "auto")},
                   "best_over_primal": best / prim},
        "auto_chose": values["auto"].method,
        "adjoint_vs_direct": gradient_difference(values["adjoint"], values["direct"]),
    }
