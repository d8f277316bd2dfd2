"""The morphing leading edge in flight: the aeroelastic equilibria of the two configurations
and what an aerodynamicist reads of them.

Configurations (:data:`CONFIGURATIONS`; flight conditions of
:mod:`~morphlab.morphing.flight`: an ASG 29, 18 m span, 10.5 m², ISA at 1500 m):

* ``"high_speed"``: inter-thermal cruise at 180 km/h, 600 kg (CL 0.42, q 1.32 kPa,
  Re 1.67e6), the nose undeformed (no torque; the reference shape is the undeformed skin);
* ``"thermalling"``: circling at 95 km/h and 30° bank, 400 kg (CL 1.17, q 0.37 kPa,
  Re 0.88e6), the nose drooped by the design's torque (the reference shape is the target).

:func:`flight_loads` tabulates, per configuration, the reference shape, the realized skin in
vacuum and under the air load (the study's accurate skin, with the torque held and with the
crank locked) and the paper's single-frame skin: CL, CD [counts] and its difference from the
reference shape, L/D, transition, the shape errors and the deflection under load.

Units: mm, MPa, N; drag in counts (1e-4); x_tr in x/c of the section's own chord.
"""

from __future__ import annotations

import json
import os
import pathlib
import warnings
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from ..errors import KinematicAccuracyWarning, ModelError
from ..solve.settings import StaticSettings
from . import leading_edge as le
from .aero import AeroResult, analyze, section
from .aeroelastic import TOL_MM, AeroelasticResult, equilibrium
from .flight import HIGH_SPEED, SAILPLANE, THERMALLING, FlightCondition

__all__ = ["CONFIGURATIONS", "configuration", "FlightLoads", "flight_loads", "shape_row"]

#: The two configurations: flight condition, time of the static equilibrium (0: no torque;
#: the end of the torque's ramp: the full torque) and the reference shape of the shape errors.
CONFIGURATIONS = {
    "high_speed": {"condition": HIGH_SPEED, "t": 0.0, "reference": "undeformed"},
    "thermalling": {"condition": THERMALLING, "t": le.T_RAMP_S, "reference": "target"},
}


def _reference(name: str, n_elements: int) -> np.ndarray:
    ref = CONFIGURATIONS[name]["reference"]
    return le.undeformed(n_elements) if ref == "undeformed" else le.target(n_elements=n_elements)


def configuration(name: str, p: dict | None = None, *, skin: str = "accurate",
                  actuator: str = "torque", build: Callable | None = None,
                  n_elements: int = le.N_ELEMENTS, tol: float = TOL_MM, q_start=None,
                  **options) -> AeroelasticResult:
    """Aeroelastic equilibrium of the leading edge in configuration ``name``.

    Parameters
    ----------
    name : {"high_speed", "thermalling"}
        :data:`CONFIGURATIONS`.
    p : dict, optional
        Design (default :data:`~morphlab.morphing.leading_edge.DEFAULTS`).
    skin : {"accurate", "paper"}
        The skin's floating frames (:data:`~morphlab.morphing.leading_edge.SKINS`); the
        paper's single frame is solved without the kinematic accuracy check (its error is
        what it is reported for).
    actuator : {"torque", "locked"}
        :mod:`~morphlab.morphing.aeroelastic`.
    build : callable, optional
        ``build(p) -> Model`` instead of the leading edge's (e.g.
        :func:`morphlab.morphing.optimization.build`); ``skin`` and ``n_elements`` then do
        not apply.
    n_elements : int
        Skin elements.
    q_start : (n_dof,), optional
        The vacuum state to start from (e.g. the last state of a dynamic run of the same
        model): then one Newton solve instead of the torque's continuation.
    tol, **options
        Passed to :func:`~morphlab.morphing.aeroelastic.equilibrium`.
    """
    if name not in CONFIGURATIONS:
        raise ModelError(f"unknown configuration {name!r}; known: {sorted(CONFIGURATIONS)}")
    cfg = CONFIGURATIONS[name]
    design = dict(le.DEFAULTS if p is None else p)
    if build is None:
        def make():
            return le.build(design, skin=skin, n_elements=n_elements)
    else:
        def make():
            return build(design)
    steps = le.STATIC_STEPS if cfg["t"] > 0.0 and q_start is None else 1
    st = StaticSettings(t=cfg["t"], steps=steps,
                        **({"kinematic_tol": None} if skin == "paper" else {}))
    with warnings.catch_warnings():
        if skin == "paper":
            warnings.simplefilter("ignore", KinematicAccuracyWarning)
        return equilibrium(make, cfg["condition"], settings=st, actuator=actuator, tol=tol,
                           q_start=q_start, **options)


def _errors(nodes: np.ndarray, ref: np.ndarray) -> np.ndarray:
    return np.linalg.norm(np.asarray(nodes, dtype=float) - ref, axis=1)


def shape_row(label: str, configuration: str, nodes, flow: AeroResult, ref: np.ndarray,
              cd_ref: float, deflection: np.ndarray | None = None) -> dict:
    """One row of the table: ``configuration``, ``shape``, ``cl``, ``cd_counts``,
    ``dcd_counts`` (minus the reference shape's), ``lift_to_drag``, ``xtr_upper``,
    ``xtr_lower``, ``cp_min``, ``e_rms_mm``, ``e_max_mm`` (node distances from the reference
    shape), ``deflection_max_mm``, ``deflection_rms_mm`` (None in vacuum), ``alpha_deg``."""
    e = _errors(nodes, ref)
    return {"configuration": configuration, "shape": label, "alpha_deg": flow.alpha,
            "cl": flow.cl, "cd_counts": flow.cd_counts, "dcd_counts": flow.cd_counts - cd_ref,
            "lift_to_drag": flow.lift_to_drag, "xtr_upper": flow.xtr_upper,
            "xtr_lower": flow.xtr_lower, "cp_min": flow.cp_min,
            "e_rms_mm": float(np.sqrt(np.mean(e * e))), "e_max_mm": float(e.max()),
            "deflection_max_mm": None if deflection is None else float(deflection.max()),
            "deflection_rms_mm": None if deflection is None else float(
                np.sqrt(np.mean(deflection**2)))}


@dataclass
class FlightLoads:
    """What :func:`flight_loads` computed.

    Attributes
    ----------
    rows : list of dict
        :func:`shape_row` per configuration and shape.
    equilibria : dict
        ``(configuration, skin, actuator) -> AeroelasticResult``.
    flows : dict
        ``(configuration, shape) -> AeroResult`` of the reference shapes.
    summary : dict
        What ``flight_loads.json`` holds.
    report : str
        The text table and notes.
    figures : dict
        Name -> path of the figures written.
    """

    rows: list
    equilibria: dict
    flows: dict
    summary: dict = field(default_factory=dict)
    report: str = ""
    figures: dict = field(default_factory=dict)

    def __str__(self) -> str:
        return self.report


#: Columns of the text table: (key, title, width, format).
_COLUMNS = [("shape", "shape", 39, "{}"), ("cl", "CL", 7, "{:.3f}"),
            ("cd_counts", "CD [cnt]", 9, "{:.2f}"), ("dcd_counts", "dCD", 7, "{:+.2f}"),
            ("lift_to_drag", "L/D", 6, "{:.1f}"), ("xtr_upper", "xtr up", 7, "{:.3f}"),
            ("xtr_lower", "xtr lo", 7, "{:.3f}"), ("e_rms_mm", "e_rms", 7, "{:.4f}"),
            ("e_max_mm", "e_max", 7, "{:.4f}"), ("deflection_max_mm", "defl max", 9, "{:.4f}"),
            ("deflection_rms_mm", "defl rms", 9, "{:.4f}")]


def format_rows(rows: list[dict]) -> str:
    """The rows as a fixed-width text table, one block per configuration (lengths in mm)."""
    head = "".join(t.rjust(w) if k != "shape" else t.ljust(w) for k, t, w, _ in _COLUMNS)
    out = []
    for cname in dict.fromkeys(r["configuration"] for r in rows):
        c = CONFIGURATIONS.get(cname, {}).get("condition")
        title = cname if c is None else (
            f"{cname}: {c.speed * 3.6:.0f} km/h, rho {c.density:.4f} kg/m3, q "
            f"{c.dynamic_pressure:.0f} Pa, Re {c.reynolds:.3g}, CL {c.cl:.3f}, N_crit "
            f"{c.n_crit:g}")
        out += [title, "  " + head]
        for r in rows:
            if r["configuration"] != cname:
                continue
            cells = []
            for k, _, w, fmt in _COLUMNS:
                v = r[k]
                s = "-" if v is None else fmt.format(v)
                cells.append(s.ljust(w) if k == "shape" else s.rjust(w))
            out.append("  " + "".join(cells))
        out.append("")
    return "\n".join(out).rstrip()


def _condition_summary(c: FlightCondition) -> dict:
    return {"name": c.name, "speed_m_s": c.speed, "speed_km_h": c.speed * 3.6,
            "density_kg_m3": c.density, "viscosity_Pa_s": c.viscosity,
            "dynamic_pressure_Pa": c.dynamic_pressure, "reynolds": c.reynolds, "cl": c.cl,
            "alpha_deg": c.alpha, "n_crit": c.n_crit, "chord_mm": c.chord}


def _equilibrium_summary(r: AeroelasticResult) -> dict:
    return {"actuator": r.actuator, "iterations": r.iterations, "tol_mm": r.tol,
            "history": r.history, "pressure_residual_mpa": r.pressure_residual,
            "deflection_max_mm": r.deflection_max, "deflection_rms_mm": r.deflection_rms,
            "deflection_mm": r.deflection.tolist(),
            "deflection_normal_mm": r.deflection_normal.tolist(),
            "pressure_mpa": r.pressure.tolist(), "air_force_N": r.air_force.tolist(),
            "cd_vacuum_counts": r.flow_vacuum.cd_counts, "cd_loaded_counts": r.flow.cd_counts,
            "timing_s": r.timing}


NOTES = """\
Flight conditions: Schleicher ASG 29 (18 m, 10.5 m2; 600 kg ballasted, 400 kg dry: the
manufacturer's type data), ISA at 1500 m; the section carries the wing's mean CL. Flow:
NeuralFoil (CL, CD, transition with N_crit 9) and a panel method fitted to its viscous Cp on
the skin (morphlab.morphing.aero). Deflection: node distance under the air load from the same
skin in vacuum; dCD: minus the reference shape (undeformed at high speed, target in the
thermal). Actuator "torque": the torque held (none at high speed, the crank held by the skin
only); "locked": the crank held at its vacuum angle. Aeroelastic iteration: flow <-> statics
until the nodes move by less than the tolerance between passes."""


def flight_loads(p: dict | None = None, *, actuators=("torque", "locked"),
                 paper_skin: bool = True, out=None, figures: bool = True,
                 tol: float = TOL_MM, flow_options: dict | None = None) -> FlightLoads:
    """The aerodynamicist's table of the leading edge at both configurations.

    Parameters
    ----------
    p : dict, optional
        Design (default :data:`~morphlab.morphing.leading_edge.DEFAULTS`).
    actuators : sequence of str
        Actuator models of the accurate skin's equilibria (the paper's skin: the first).
    paper_skin : bool
        Add the paper's single-frame skin, in vacuum and under load.
    out : path, optional
        Folder for ``flight_loads.json``, ``flight_loads.txt`` and the figures
        ``fig10_cp.png``, ``fig11_skin_load.png``.
    figures : bool
        Draw the figures (written with ``out``).
    tol : float
        Tolerance [mm] of the aeroelastic iterations.
    flow_options : dict, optional
        Passed to :func:`~morphlab.morphing.aero.analyze` (``model_size``, ``n_panels``).

    Returns
    -------
    FlightLoads
    """
    if not actuators:
        raise ModelError("actuators must name at least one of 'torque', 'locked'")
    rows, eqs, flows = [], {}, {}
    for cname, cfg in CONFIGURATIONS.items():
        cond, ref = cfg["condition"], _reference(cname, le.N_ELEMENTS)
        ref_flow = analyze(section(None if cfg["reference"] == "undeformed" else ref), cond,
                           **(flow_options or {}))
        flows[(cname, cfg["reference"])] = ref_flow
        rows.append(shape_row(cfg["reference"], cname, ref, ref_flow, ref, ref_flow.cd_counts))
        if cfg["reference"] != "undeformed":  # what the droop buys
            und = le.undeformed(le.N_ELEMENTS)
            flows[(cname, "undeformed")] = analyze(section(None), cond, **(flow_options or {}))
            rows.append(shape_row("undeformed (no droop)", cname, und,
                                  flows[(cname, "undeformed")], ref, ref_flow.cd_counts))
        skins = [("accurate", a) for a in actuators]
        if paper_skin:
            skins.append(("paper", actuators[0]))
        for skin, act in skins:
            r = configuration(cname, p, skin=skin, actuator=act, tol=tol,
                              **(flow_options or {}))
            eqs[(cname, skin, act)] = r
            label = "realized" if skin == "accurate" else "paper's single frame"
            if cfg["t"] > 0.0 and act == actuators[0]:
                rows.append(shape_row(f"{label}, vacuum", cname, r.nodes_vacuum, r.flow_vacuum,
                                      ref, ref_flow.cd_counts))
            rows.append(shape_row(f"{label}, loaded ({act})", cname, r.nodes_loaded, r.flow,
                                  ref, ref_flow.cd_counts, r.deflection))
    summary = {
        "conditions": {k: _condition_summary(v["condition"]) for k, v in CONFIGURATIONS.items()},
        "sailplane": SAILPLANE, "design": dict(le.DEFAULTS if p is None else p),
        "rows": rows, "tol_mm": tol,
        "equilibria": {f"{c}/{s}/{a}": _equilibrium_summary(r) for (c, s, a), r in eqs.items()},
    }
    report = "\n".join(["Flight loads and aerodynamics of the morphing leading edge "
                        "(lengths in mm, drag in counts)", "", format_rows(rows), "",
                        *(f"{c}/{s}/{a}: " + r.summary().split("\n", 1)[0].split(": ", 1)[1]
                          for (c, s, a), r in eqs.items()), "", NOTES])
    result = FlightLoads(rows=rows, equilibria=eqs, flows=flows, summary=summary, report=report)
    if out is not None:
        _write(result, pathlib.Path(out), figures)
    return result


def _write(result: FlightLoads, outp: pathlib.Path, figures: bool) -> None:
    from .aero_study import plot_cp, plot_skin_load

    outp.mkdir(parents=True, exist_ok=True)
    if figures:
        import matplotlib.pyplot as plt

        fig, axes = plt.subplots(1, 2, figsize=(12.0, 4.5))
        for ax, cname in zip(axes, CONFIGURATIONS):
            curves = {shape: f for (c, shape), f in result.flows.items() if c == cname}
            for (c, s, a), r in result.equilibria.items():
                if c == cname and s == "accurate":
                    curves[f"loaded ({a})"] = r.flow
                    break
            plot_cp(curves, ax=ax, xc_max=0.3)
            ax.set_title(f"{cname}: Cp on the skin (x/c < 0.3)", fontsize=9)
        fig.tight_layout()
        fig.savefig(outp / "fig10_cp.png", dpi=120)
        plt.close(fig)
        result.figures["fig10_cp"] = str(outp / "fig10_cp.png")
        fig = plot_skin_load({f"{c}, {s}, {a}": r for (c, s, a), r in
                              result.equilibria.items() if s == "accurate"})
        fig.savefig(outp / "fig11_skin_load.png", dpi=120)
        result.figures["fig11_skin_load"] = str(outp / "fig11_skin_load.png")
    tmp = outp / "flight_loads.json.tmp"
    tmp.write_text(json.dumps(result.summary, indent=2), encoding="utf-8")
    os.replace(tmp, outp / "flight_loads.json")
    (outp / "flight_loads.txt").write_text(result.report + "\n", encoding="utf-8")
