"""The paper's study of a morphing skin: responses, sensitivities, timing, figures, JSON.

:func:`run_study` is model-agnostic: it takes a parametric ``build(p)``, the design ``p0``, the
responses and solver settings, the beam to report on and its target shape.
:func:`morphlab.morphing.study` calls it with the leading-edge model.
"""

from __future__ import annotations

import dataclasses
import json
import os
import pathlib
import statistics
import warnings
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from ..errors import KinematicAccuracyWarning
from ..results.responses import distance
from ..sensitivity.api import sensitivities
from ..sensitivity.strategies import Direct, FiniteDifference
from ..solve.settings import Settings
from ..studies.timing import interleaved_times


@dataclass
class StudyResult:
    """Everything the study computed; ``summary`` is what the JSON file holds."""

    summary: dict
    sensitivity: object
    node_errors: np.ndarray
    node_error_gradients: np.ndarray
    stress_gradients: np.ndarray
    figures: dict = field(default_factory=dict)
    report: str = ""

    def __str__(self) -> str:
        return self.report


def _fmt(x: float) -> str:
    return f"{x:.4g}" if abs(x) >= 1e-3 or x == 0 else f"{x:.3e}"


def run_study(build, p0: dict, responses: dict, settings: Settings, *, body: str, target,
              undeformed, paper: dict, units: dict, out=None, figures: bool = True,
              timing: bool = True, repeats: int = 3, fd_step: float = 1e-6,
              progress: bool = False, notes: str | Callable[[dict], str] = "",
              compare: dict | None = None) -> StudyResult:
    """Run the study and (with ``out``) write figures and ``out/morphing.json``.

    Parameters
    ----------
    build, p0, responses, settings :
        Parametric model, nominal design, response functions (must include
        ``"ks_max_stress"`` and ``"rms_error"``; ``"max_error"`` is reported too) and the
        run's :class:`~morphlab.solve.settings.Settings`.
    body : str
        The beam whose stress and shape are reported.
    target, undeformed : (n_nodes, 2)
        Target and undeformed node positions [mm].
    paper : dict
        The paper's numbers, reported beside ours.
    units : dict
        Units of the design variables, for the tables.
    out : path, optional
        Output folder (created).
    figures, timing : bool
        Write the figures; time the finite-difference comparison (Table 2).
    repeats : int
        Repetitions of each timed run (the median is reported).
    fd_step : float
        Relative step of the finite differences.
    notes : str or callable
        Text that ends the report, or a function of the study's summary (the dict written to
        ``morphing.json``) that writes it, so that the figures it quotes are this run's.
    compare : dict[str, callable], optional
        Other formulations of the same model, ``{label: build}``: their responses, Table 1
        and kinematic accuracy are reported beside the study's (``summary["formulations"]``),
        with the node offset of their final shape from the study's and how many of the
        paper's Table 1 signs each matches.
    """
    names = list(p0)
    sens = sensitivities(build, p0, responses, method="direct", progress=progress,
                         settings=settings)
    res = sens.result
    final = res.node_positions(body, -1)
    e_k = np.real(distance(final, target))
    de_k = np.real(sens.derivative(lambda r: distance(r.node_positions(body, -1), target)))
    dsig = np.real(sens.stress(body))
    stress = np.real(res.stress(body))

    timing_s = _timing(build, p0, responses, settings, repeats, fd_step) if timing else {}
    summary = _summary(sens, body, e_k, stress, timing_s, p0, settings, paper)
    summary["formulations"] = _formulations(sens, compare or {}, p0, responses, settings,
                                            body, paper)
    report = _report(summary, names, units, paper, notes(summary) if callable(notes) else notes)
    study = StudyResult(summary=summary, sensitivity=sens, node_errors=e_k,
                        node_error_gradients=de_k, stress_gradients=dsig, report=report)
    if out is not None:
        _write(study, out, figures, res, body, target, undeformed, names, units)
    return study


def _timing(build, p0: dict, responses: dict, settings: Settings, repeats: int,
            fd_step: float) -> dict:
    """Table 2: medians [s] of interleaved rounds of the primal (as a user runs it: build,
    simulate, responses), the solver alone, direct with complex-step and with
    forward-difference partials, and finite differences; with their ratios (of wall times)
    and each run's process CPU times (``*_cpu_runs``)."""
    from ..compile import compile_model
    from ..solve.timeloop import simulate

    sys0 = compile_model(build(dict(p0)))

    def primal():  # one analysis of the design, as a user runs it (BENCHMARKS.md)
        r = simulate(build(dict(p0)), settings=settings)
        return {k: f(r) for k, f in responses.items()}

    runs = {
        "primal": primal,
        "primal_solver_only": lambda: simulate(sys0, settings=settings),
        "direct": lambda: sensitivities(build, p0, responses, method="direct",
                                        settings=settings),
        "direct_fd": lambda: sensitivities(build, p0, responses, settings=settings,
                                           method=Direct(partials="forward-difference",
                                                         step=fd_step)),
        "adjoint": lambda: sensitivities(build, p0, responses, method="adjoint",
                                         settings=settings),
    }
    timing_s: dict = {}
    cpu: dict = {}
    for k, times in interleaved_times(runs, repeats, cpu=cpu).items():
        timing_s[k], timing_s[f"{k}_runs"] = statistics.median(times), times
        timing_s[f"{k}_cpu_runs"] = cpu[k]
    fd_cpu: dict = {}
    fd = interleaved_times({"fd": lambda: sensitivities(
        build, p0, responses, method=FiniteDifference("forward", fd_step), settings=settings)},
        max(1, repeats // 2), cpu=fd_cpu)["fd"]
    timing_s["finite_difference"], timing_s["finite_difference_runs"] = (
        statistics.median(fd), fd)
    timing_s["finite_difference_cpu_runs"] = fd_cpu["fd"]
    cpu_primal = statistics.median(timing_s["primal_cpu_runs"])
    for k in ("direct", "direct_fd", "adjoint", "finite_difference"):
        timing_s[f"{k}_over_primal"] = timing_s[k] / timing_s["primal"]
        timing_s[f"{k}_cpu_over_primal"] = (statistics.median(timing_s[f"{k}_cpu_runs"])
                                            / cpu_primal)
    timing_s["finite_difference_over_direct"] = (timing_s["finite_difference"]
                                                 / timing_s["direct"])
    best = min(timing_s["direct"], timing_s["adjoint"])
    timing_s["finite_difference_over_best"] = timing_s["finite_difference"] / best
    return timing_s


def _summary(sens, body: str, e_k, stress, timing_s: dict, p0: dict, settings: Settings,
             paper: dict) -> dict:
    """What ``morphing.json`` holds: responses, node errors, Table 1, Table 2, the design,
    the settings, the run's diagnostics and the paper's numbers."""
    res = sens.result
    final = res.node_positions(body, -1)
    rot = np.real(res.node_rotations(body)[-1])
    seg0 = np.sqrt(np.sum(np.diff(np.real(res.node_positions(body)[0]), axis=0) ** 2, axis=1))
    seg1 = np.sqrt(np.sum(np.diff(np.real(final), axis=0) ** 2, axis=1))
    summary = {
        "ks_max_stress_MPa": sens.values["ks_max_stress"],
        "max_stress_MPa": float(np.max(np.abs(stress))),
        "max_error_mm": float(np.max(e_k)),
        "rms_error_mm": float(np.sqrt(np.mean(e_k**2))),
        "node_errors_mm": e_k.tolist(),
        "sensitivities": {
            "ks_max_stress_MPa": dict(sens.gradients["ks_max_stress"]),
            "rms_error_mm": dict(sens.gradients["rms_error"]),
        },
        "timing_s": {k: v for k, v in timing_s.items()},
        "design": dict(p0),
        "settings": dataclasses.asdict(settings),
        "diagnostics": {
            "newton_iterations_mean": float(np.mean(res.newton_iterations[1:])),
            "max_constraint_violation_mm": float(np.max(res.constraint_violation)),
            "largest_node_rotation_rad": float(np.max(np.abs(rot))),
            "arc_length_change_mm": float(np.sum(seg1) - np.sum(seg0)),
            "factorizations": int(res.n_factorizations),
        },
        "paper": paper,
    }
    if "max_error" in sens.gradients:
        summary["sensitivities"]["max_error_mm"] = dict(sens.gradients["max_error"])
    return summary


def signs_matched(table1: dict, paper: dict) -> int:
    """How many Table 1 entries have the paper's sign."""
    ref = paper.get("table1", {})
    return sum(int(np.sign(table1[k][v]) == np.sign(ref[k][v]))
               for k in ("ks_max_stress_MPa", "rms_error_mm") if k in ref
               for v in ref[k] if v in table1.get(k, {}))


def _formulation(sens, body: str, paper: dict, final_ref=None) -> dict:
    res = sens.result
    kin = res.kinematics.get(body)
    table1 = {"ks_max_stress_MPa": dict(sens.gradients["ks_max_stress"]),
              "rms_error_mm": dict(sens.gradients["rms_error"])}
    out = {"values": dict(sens.values), "table1": table1,
           "table1_signs_as_paper": signs_matched(table1, paper),
           "frames": kin.frames if kin is not None else None,
           "kinematic_error_estimate_mm": kin.estimate if kin is not None else None,
           "status": res.status}
    if final_ref is not None:
        d = np.real(res.node_positions(body, -1)) - final_ref
        out["node_offset_from_study_mm"] = float(np.max(np.hypot(d[:, 0], d[:, 1])))
    return out


def _formulations(sens, builds: dict, p0: dict, responses: dict, settings: Settings, body: str,
                  paper: dict) -> dict:
    """The study's formulation and the ``builds`` beside it (``compare`` of
    :func:`run_study`), keyed ``"study"`` and by label."""
    final = np.real(sens.result.node_positions(body, -1))
    out = {"study": _formulation(sens, body, paper)}
    for label, b in builds.items():
        with warnings.catch_warnings():  # its kinematic error is reported in the table
            warnings.simplefilter("ignore", KinematicAccuracyWarning)
            other = sensitivities(b, p0, responses, method="direct", settings=settings)
        out[label] = _formulation(other, body, paper, final)
    return out


def _write(study: StudyResult, out, figures: bool, res, body, target, undeformed, names,
           units) -> None:
    """Figures, ``morphing.json`` (written atomically) and ``report.txt`` into ``out``."""
    outp = pathlib.Path(out)
    outp.mkdir(parents=True, exist_ok=True)
    if figures:
        study.figures = _figures(study, res, body, target, undeformed, names, units, outp)
    tmp = outp / "morphing.json.tmp"
    tmp.write_text(json.dumps(study.summary, indent=2), encoding="utf-8")
    os.replace(tmp, outp / "morphing.json")
    (outp / "report.txt").write_text(study.report + "\n", encoding="utf-8")


def _report(s: dict, names, units, paper, notes) -> str:
    lines = ["Morphing leading edge: primal responses (ours | paper)"]
    lines.append(f"  KS max stress   {s['ks_max_stress_MPa']:10.4g} MPa | "
                 f"{paper.get('ks_max_stress_MPa', float('nan')):.5g} MPa")
    lines.append(f"  max shape error {s['max_error_mm']:10.4g} mm  | "
                 f"{paper.get('max_error_mm', float('nan')):.4g} mm")
    lines.append(f"  RMS shape error {s['rms_error_mm']:10.4g} mm  | "
                 f"{paper.get('rms_error_mm', float('nan')):.4g} mm")
    lines.append("")
    lines.append("Table 1: design sensitivities, ours and (paper)")
    lines.append("  variable     unit        dσ_KS [MPa/unit]            de_rms [mm/unit]")
    t1 = paper.get("table1", {})
    for n in names:
        cells = []
        for key in ("ks_max_stress_MPa", "rms_error_mm"):
            ref = t1.get(key, {}).get(n)
            cells.append(f"{_fmt(s['sensitivities'][key][n]):>11s} "
                         f"({_fmt(ref) if ref is not None else '-':>10s})")
        lines.append(f"  {n:12s} {units.get(n, '-'):8s} " + "     ".join(cells))
    t = s["timing_s"]
    if t:
        lines.append("")
        lines.append("Table 2: wall time, median of repeated runs on this machine (paper: "
                     "i7-8700)")
        p2 = paper.get("table2_s", {})
        for key, label in (("primal", "one primal run (build, simulate, responses)"),
                           ("direct", "direct differentiation (complex-step pseudo-loads)"),
                           ("direct_fd", "direct differentiation (FD partials, paper)"),
                           ("finite_difference", f"finite differences ({len(names) + 1} runs)"),
                           ("primal_solver_only", "simulate a compiled model only")):
            if key not in t:
                continue
            ratio = t[key] / t["primal"]
            # the paper's semi-analytical method is our direct_fd (FD partial derivatives)
            ref = {"direct": None, "direct_fd": p2.get("direct")}.get(key, p2.get(key))
            ref_s = f"{ref:8.1f} s ({ref / p2['primal']:.2f}x)" if ref else "       -"
            lines.append(f"  {label:52s} {t[key]:8.3f} s ({ratio:5.2f}x) | paper {ref_s}")
        lines.append(f"  finite differences / direct: {t['finite_difference_over_direct']:.2f}"
                     f" (paper {p2.get('finite_difference', 0) / p2.get('direct', 1):.2f})")
    forms = s.get("formulations", {})
    if len(forms) > 1:
        lines.append("")
        lines.append("The skin's floating frames: the study's skin and the others beside it")
        lines.append(f"  {'':26s}{'frames':>8s}{'KS [MPa]':>10s}{'e_max [mm]':>11s}"
                     f"{'e_rms [mm]':>11s}{'kin. error [mm]':>16s}{'offset [mm]':>12s}"
                     f"{'signs as paper':>16s}")
        for label, f in forms.items():
            v = f["values"]
            off = f.get("node_offset_from_study_mm")
            lines.append(f"  {label:26s}{f['frames']!s:>8s}{v['ks_max_stress']:10.4g}"
                         f"{v.get('max_error', float('nan')):11.4g}{v['rms_error']:11.4g}"
                         f"{f['kinematic_error_estimate_mm'] or 0.0:16.3g}"
                         f"{'-' if off is None else f'{off:.3g}':>12s}"
                         f"{f['table1_signs_as_paper']:>13d}/10")
    d = s["diagnostics"]
    lines.append("")
    lines.append(f"Diagnostics: Newton iterations/step {d['newton_iterations_mean']:.2f}, max "
                 f"|Phi| {d['max_constraint_violation_mm']:.2e} mm, largest node rotation "
                 f"{d['largest_node_rotation_rad']:.3f} rad, skin arc-length change "
                 f"{d['arc_length_change_mm']:+.3f} mm")
    if notes:
        lines.append("")
        lines.append(notes)
    return "\n".join(lines)


def _figures(study: StudyResult, res, body, target, undeformed, names, units, outp) -> dict:
    from .. import plots

    written = {}
    arc = plots.arc_coordinate(np.real(undeformed))

    def save(fig, name):
        path = outp / f"{name}.png"
        fig.savefig(path, dpi=120)
        written[name] = str(path)

    save(plots.snapshots(res, n=6, target=target), "fig5b_motion")
    save(plots.stress_map(res.t, np.real(res.stress(body)), arc=arc), "fig6_stress")
    save(plots.profile_comparison(undeformed, target, np.real(res.node_positions(body)[-1])),
         "fig7_profiles")
    # one value per element and time, at the end and fibre where |stress| is largest (the
    # same point the stress map shows)
    sig = np.real(res.stress(body))
    idx = np.argmax(np.abs(sig.reshape(sig.shape[0], sig.shape[1], -1)), axis=-1)
    for i, n in enumerate(names):
        flat = study.stress_gradients[..., i].reshape(sig.shape[0], sig.shape[1], -1)
        val = np.take_along_axis(flat, idx[..., None], axis=-1)[..., 0]
        save(plots.sensitivity_map(res.t, val, n, arc=arc, quantity_unit="MPa",
                                   variable_unit=units.get(n)), f"fig8_stress_sens_{n}")
    save(plots.node_sensitivities({n: study.node_error_gradients[:, i]
                                   for i, n in enumerate(names)}, normalize=True),
         "fig9_error_sens")
    return written
