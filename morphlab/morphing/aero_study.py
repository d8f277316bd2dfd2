"""What an aerodynamicist reads of the morphing leading edge: CL, CD, L/D, transition, the
suction peak and the air load on the skin for several skin shapes at the flight conditions,
as table rows, a Markdown table and a Cp figure.

Units: drag in counts (1e-4), transition in x/c of the section's own chord, pressure in MPa,
line load on the 1000 mm span in N/mm.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from ..errors import ModelError
from .aero import AeroResult, analyze, section, skin_pressure
from .airfoil import X_SPAR_MM
from .flight import CONDITIONS, FlightCondition
from .geometry import SPAN_MM, undeformed

__all__ = ["aero_table", "format_table", "plot_cp", "plot_skin_load"]

#: (key, title, format) of the columns of :func:`format_table`.
_COLUMNS = [
    ("condition", "condition", "{}"),
    ("shape", "shape", "{}"),
    ("alpha_deg", "alpha [deg]", "{:.2f}"),
    ("cl", "CL", "{:.4f}"),
    ("cd_counts", "CD [counts]", "{:.2f}"),
    ("lift_to_drag", "L/D", "{:.1f}"),
    ("cm", "CM", "{:+.4f}"),
    ("xtr_upper", "x_tr/c upper", "{:.3f}"),
    ("xtr_lower", "x_tr/c lower", "{:.3f}"),
    ("cp_min_skin", "Cp min (skin)", "{:.2f}"),
    ("line_load_min", "min load [N/mm]", "{:.2f}"),
    ("line_load_max", "max load [N/mm]", "{:.2f}"),
]


def _row(name: str, cname: str, nodes, res: AeroResult) -> dict:
    p = skin_pressure(res, nodes)
    on_skin = res.nodes[:, 0] < X_SPAR_MM
    return {
        "condition": cname, "shape": name, "alpha_deg": res.alpha, "cl": res.cl,
        "cd_counts": res.cd_counts, "lift_to_drag": res.lift_to_drag, "cm": res.cm,
        "xtr_upper": res.xtr_upper, "xtr_lower": res.xtr_lower,
        "cp_min_skin": float(np.nanmin(res.cp[on_skin])),
        "p_min_mpa": float(p.min()), "p_max_mpa": float(p.max()),
        "line_load_min": float(p.min() * SPAN_MM), "line_load_max": float(p.max() * SPAN_MM),
        "confidence": res.confidence, "result": res,
    }


def aero_table(shapes: dict[str, ArrayLike | None],
               conditions: dict[str, FlightCondition] | None = None, **options) -> list[dict]:
    """Flow about each skin shape at each flight condition.

    Parameters
    ----------
    shapes : dict
        Name -> skin nodes (n_nodes, 2) [mm] F -> nose -> G (``None``: the undeformed section,
        its loads at the 31 nodes of the undeformed mesh), e.g.
        ``{"undeformed": None, "target": geometry.target(),
        "realized": res.node_positions("skin")[-1]}``.
    conditions : dict, optional
        Name -> FlightCondition; default :data:`~morphlab.morphing.flight.CONDITIONS`.
    **options
        Passed to :func:`~morphlab.morphing.aero.analyze`.

    Returns
    -------
    list of dict
        One row per (condition, shape): ``condition``, ``shape``, ``alpha_deg``, ``cl``,
        ``cd_counts``, ``lift_to_drag``, ``cm``, ``xtr_upper``, ``xtr_lower``,
        ``cp_min_skin`` (peak suction in front of the spar), ``p_min_mpa``, ``p_max_mpa``
        (extreme nodal pressure), ``line_load_min``, ``line_load_max`` [N/mm over the span],
        ``confidence`` and the ``result`` (:class:`~morphlab.morphing.aero.AeroResult`).
    """
    if not shapes:
        raise ModelError("shapes must name at least one skin shape")
    conds = CONDITIONS if conditions is None else conditions
    rows = []
    for cname, cond in conds.items():
        for name, nodes in shapes.items():
            pts = undeformed() if nodes is None else np.real(np.asarray(nodes))
            res = analyze(section(None if nodes is None else pts), cond, **options)
            rows.append(_row(name, cname, pts, res))
    return rows


def format_table(rows: list[dict]) -> str:
    """The rows of :func:`aero_table` as a Markdown table (loads at the skin's nodes)."""
    head = "| " + " | ".join(title for _, title, _ in _COLUMNS) + " |"
    rule = "|" + "|".join("---" for _ in _COLUMNS) + "|"
    body = ["| " + " | ".join(fmt.format(r[key]) for key, _, fmt in _COLUMNS) + " |"
            for r in rows]
    return "\n".join([head, rule, *body])


def plot_cp(results: dict[str, AeroResult], ax=None, *, xc_max: float = 1.0):
    """Cp along the chord for several analyses: the panel solution (lines, the inverted Cp
    axis aerodynamicists use) and NeuralFoil's viscous stations (dots).

    Parameters
    ----------
    results : dict
        Label -> AeroResult.
    ax : matplotlib Axes, optional
        Drawn into; default a new figure.
    xc_max : float, optional
        Right end of the x/c axis (0.3 shows the skin).

    Returns
    -------
    matplotlib.figure.Figure
    """
    import matplotlib.pyplot as plt

    if not results:
        raise ModelError("results must hold at least one AeroResult")
    if ax is None:
        _, ax = plt.subplots(figsize=(7.0, 4.5))
    for label, res in results.items():
        xc = res.contour.normalized(res.nodes)[:, 0]
        (line,) = ax.plot(xc[1:-1], res.cp[1:-1], lw=1.2, label=f"{label} (panel)")
        ax.plot(res.bl_x, res.cp_upper, "o", ms=3, color=line.get_color())
        ax.plot(res.bl_x, res.cp_lower, "o", ms=3, mfc="none", color=line.get_color())
    ax.set_xlim(-0.01, xc_max)
    ax.invert_yaxis()
    ax.set_xlabel("x/c")
    ax.set_ylabel("Cp")
    ax.axvline(X_SPAR_MM / 550.0, color="0.6", lw=0.8, ls="--")
    ax.legend(fontsize=8)
    ax.set_title("Cp: panel method (lines), NeuralFoil stations (dots: upper filled)")
    return ax.figure


def plot_skin_load(results: dict, *, scale: float | None = None):
    """The skin under its air load: shapes with the deflection magnified, the line load on the
    span and the deflection along the outward normal, per node.

    Parameters
    ----------
    results : dict
        Label -> :class:`~morphlab.morphing.aeroelastic.AeroelasticResult`.
    scale : float, optional
        Magnification of the deflection in the shape panel; default: the largest deflection
        drawn as 5 mm.

    Returns
    -------
    matplotlib.figure.Figure
        Three panels: (a) the vacuum skins (grey) and ``vacuum + scale * deflection``; (b)
        the nodal pressure times the span [N/mm] (negative: suction, pulling outwards);
        (c) the deflection along the vacuum skin's outward normal [mm] by node (F = 0).
    """
    from matplotlib.figure import Figure

    if not results:
        raise ModelError("results must hold at least one AeroelasticResult")
    if scale is None:
        largest = max(r.deflection_max for r in results.values())
        scale = 5.0 / largest if largest > 0.0 else 1.0
    if not scale > 0.0:
        raise ModelError(f"scale must be positive, got {scale!r}")
    fig = Figure(figsize=(13.0, 4.2), layout="constrained")
    ax = fig.subplots(1, 3, gridspec_kw={"width_ratios": [1.1, 1.0, 1.0]})
    for label, r in results.items():
        x0, x1 = r.nodes_vacuum, r.nodes_loaded
        ax[0].plot(*x0.T, color="0.75", lw=0.8)
        (line,) = ax[0].plot(*(x0 + scale * (x1 - x0)).T, ".-", ms=3, lw=1.0, label=label)
        c = line.get_color()
        nodes = np.arange(x0.shape[0])
        ax[1].plot(nodes, r.pressure * r.width[0], ".-", ms=3, color=c, label=label)
        ax[2].plot(nodes, r.deflection_normal, ".-", ms=3, color=c,
                   label=f"{label}: max {r.deflection_max:.3f}, RMS {r.deflection_rms:.3f} mm")
    ax[0].set(aspect="equal", xlabel="x [mm]", ylabel="y [mm]",
              title=f"skin in vacuum (grey) and loaded, deflection x {scale:.0f}")
    ax[1].axhline(0.0, color="0.6", lw=0.6)
    ax[1].set(xlabel="skin node (F = 0, G last)", ylabel="pressure x span [N/mm]",
              title="air load (negative: suction, outwards)")
    ax[2].axhline(0.0, color="0.6", lw=0.6)
    ax[2].set(xlabel="skin node (F = 0, G last)", ylabel="deflection along outward normal [mm]",
              title="deflection under the air load")
    ax[0].legend(fontsize=7)
    ax[2].legend(fontsize=7)
    return fig
