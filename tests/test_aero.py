"""The flow analysis of the wing section (NeuralFoil + panel method): published airfoil data,
exact potential flow, frame handling, the pressure on the skin and the smoothness the design
gradients need."""

import pickle

import numpy as np
import pytest

import morphlab as ml
from morphlab.errors import ModelError
from morphlab.morphing import aero, flight
from morphlab.morphing import geometry as geo
from morphlab.morphing.flight import FlightCondition
from morphlab.morphing.panel import karman_trefftz, panel_solution
from morphlab.morphing.profile import Contour


def naca4(code: str, n: int = 161, chord: float = 550.0) -> np.ndarray:
    """NACA four-digit section (Abbott & von Doenhoff, Theory of Wing Sections, §6.4, with the
    original blunt trailing edge), Selig order, cosine spacing [mm]."""
    m, p, t = int(code[0]) / 100, int(code[1]) / 10, int(code[2:]) / 100
    x = 0.5 * (1.0 - np.cos(np.linspace(0.0, np.pi, n)))
    yt = 5 * t * (0.2969 * np.sqrt(x) - 0.1260 * x - 0.3516 * x**2 + 0.2843 * x**3
                  - 0.1015 * x**4)
    if m > 0:
        yc = np.where(x < p, m / p**2 * (2 * p * x - x**2),
                      m / (1 - p) ** 2 * ((1 - 2 * p) + 2 * p * x - x**2))
        dyc = np.where(x < p, 2 * m / p**2 * (p - x), 2 * m / (1 - p) ** 2 * (p - x))
    else:
        yc, dyc = np.zeros_like(x), np.zeros_like(x)
    th = np.arctan(dyc)
    upper = np.column_stack([x - yt * np.sin(th), yc + yt * np.cos(th)])
    lower = np.column_stack([x + yt * np.sin(th), yc - yt * np.cos(th)])
    return chord * np.vstack([upper[::-1], lower[1:]])


def at_reynolds(re: float, alpha: float) -> FlightCondition:
    """Sea-level air at the speed that gives Reynolds number ``re`` on the 550 mm chord."""
    return FlightCondition(speed=re * 1.789e-5 / (1.225 * 0.55), alpha=alpha)


def lift_line(xy, re):
    """Lift-curve slope [1/deg] and zero-lift angle [deg] from a fit over -2 ... 6 deg."""
    alphas = np.arange(-2.0, 6.5, 2.0)
    cl = [aero.analyze(xy, at_reynolds(re, a)).cl for a in alphas]
    slope, c0 = np.polyfit(alphas, cl, 1)
    return slope, -c0 / slope


def thin_airfoil_zero_lift_deg(code: str) -> float:
    """Thin-airfoil theory: alpha_L0 = -(1/pi) int_0^pi dyc/dx (cos(theta) - 1) dtheta, with
    x = (1 - cos(theta))/2, for the NACA camber line (a closed form of the geometry)."""
    m, p = int(code[0]) / 100, int(code[1]) / 10
    th = np.linspace(0.0, np.pi, 200001)
    x = 0.5 * (1.0 - np.cos(th))
    dyc = np.where(x < p, 2 * m / p**2 * (p - x), 2 * m / (1 - p) ** 2 * (p - x))
    f = dyc * (np.cos(th) - 1.0)
    integral = np.sum(0.5 * (f[1:] + f[:-1]) * np.diff(th))
    return float(np.degrees(-integral / np.pi))


def test_naca2412_lift_against_abbott_and_von_doenhoff():
    """Measured (Abbott & von Doenhoff, Theory of Wing Sections, App. IV; read by Anderson,
    Aircraft Performance and Design, 1999, §2.4, and Fundamentals of Aerodynamics, Ex. 4.1):
    a0 = 0.105 /deg, alpha_L0 = -2.2 deg; at Re = 3.1e6 and 4 deg: cl = 0.65, cd = 0.0068."""
    xy = naca4("2412")
    slope, a0 = lift_line(xy, 3.1e6)
    # NeuralFoil reproduces XFoil, whose lift slope on NACA sections is a few per cent above
    # the tunnel's (measured here: 0.1108, +5.5 %); 8 % = that bias + the 2 % of reading a
    # slope off the published figure: a wrong chord frame or alpha sign is far outside it
    assert slope == pytest.approx(0.105, rel=0.08)
    # a zero-lift angle reads to about +-0.2 deg off the figure; thickness and viscosity move
    # it by ~0.1 deg (measured -2.21)
    assert a0 == pytest.approx(-2.2, abs=0.3)
    r = aero.analyze(xy, at_reynolds(3.1e6, 4.0))
    assert r.cl == pytest.approx(0.65, rel=0.08)  # same bias as the slope
    # XFoil-type codes under-predict the drag of NACA sections measured in the NACA
    # low-turbulence tunnels by about 9 % (Timmer, AIAA 2009-268, for RFOIL); NeuralFoil
    # adds ~2.4 % (its ln(CD) error against XFoil); a drag read off the figure is good to
    # +-0.0002 (3 %): accepted band -20 % ... +5 % (measured 0.00591, -13 %)
    assert -0.20 < r.cd / 0.0068 - 1.0 < 0.05
    assert r.confidence > 0.9


@pytest.mark.parametrize("code", ["2412", "4412"])
def test_zero_lift_angle_against_thin_airfoil_theory(code):
    _, a0 = lift_line(naca4(code), 3.1e6)
    # thin-airfoil theory (-2.08 deg for 2412, -4.15 for 4412) ignores thickness and the
    # boundary layer, which shift alpha_L0 by a few tenths of a degree on 12 % sections
    # (measured -2.21 and -4.45)
    assert a0 == pytest.approx(thin_airfoil_zero_lift_deg(code), abs=0.4)


def test_naca0012_lift_slope_between_thin_airfoil_theory_and_inviscid_flow():
    xy = naca4("0012")
    slope, a0 = lift_line(xy, 3.1e6)
    assert abs(a0) < 0.01  # symmetric section: NeuralFoil is symmetrised by construction
    # thin-airfoil theory, 2 pi /rad, is the slope of the zero-thickness section; the exact
    # inviscid slope of the 12 % section (our panel method, verified against the closed
    # form) is ~9 % higher, and the boundary layer takes most of that back: the viscous
    # slope lies between 0.95 * 2 pi and the inviscid one (measured 1.007 * 2 pi)
    inviscid = panel_solution(Contour(xy).resample(400), chord=550.0)
    inviscid_slope = (inviscid.cl(1.0) - inviscid.cl(-1.0)) / 2.0
    assert 0.95 * 2 * np.pi * np.pi / 180 < slope < inviscid_slope


@pytest.mark.parametrize("center, alpha", [(-0.08 + 0.0j, 0.0), (-0.08 + 0.0j, 4.0),
                                           (-0.08 + 0.04j, 2.0)])
def test_neuralfoil_pressure_against_exact_potential_flow(center, alpha):
    """NeuralFoil's Cp = 1 - (ue/V)^2 at its stations against the exact Karman-Trefftz Cp at
    the same lift, at Re = 1e7 (thin boundary layer)."""
    kt = karman_trefftz(center, 1.92, alpha, 801)
    scale = 550.0 / kt["chord"]
    r = aero.analyze(kt["xy"] * scale, at_reynolds(1e7, alpha))
    radius, theta_te = abs(1 - center), np.angle(1 - center)
    # the exact flow at the viscous lift: CL = 8 pi R sin(alpha - theta_TE) / c
    a_match = np.degrees(theta_te + np.arcsin(r.cl * kt["chord"] / (8 * np.pi * radius)))
    exact = karman_trefftz(center, 1.92, a_match, 2001)
    xn = r.contour.normalized(exact["xy"] * scale)
    le = int(np.argmin(xn[:, 0]))
    cp_up = np.interp(r.bl_x, xn[1:le + 1, 0][::-1], exact["cp"][1:le + 1][::-1])
    cp_lo = np.interp(r.bl_x, xn[le:-1, 0], exact["cp"][le:-1])
    keep = (r.bl_x > 0.05) & (r.bl_x < 0.9)
    # the boundary layer's displacement makes the viscous Cp differ from the inviscid one by
    # a few hundredths here (measured 0.024 ... 0.051); swapped sides, a wrong chord frame or
    # station layout give errors of 0.1 ... 1 (the Cp range compared is about 1)
    assert np.max(np.abs(cp_up - r.cp_upper)[keep]) < 0.06
    assert np.max(np.abs(cp_lo - r.cp_lower)[keep]) < 0.06


def test_coefficients_follow_the_section_through_its_frame():
    """Moving the section moves the reference point (c/4, 0) relative to it: statics gives
    the change of CM; rotating it about that point and the freestream with it changes
    nothing."""
    xy = naca4("2412")
    cond = at_reynolds(3e6, 3.0)
    base = aero.analyze(xy, cond)
    dx, dy = 20.0, 15.0  # mm
    moved = aero.analyze(xy + [dx, dy], cond)
    a = np.radians(3.0)
    # lift (normal to the stream) and drag (along it) now act dx aft and dy above the
    # reference point: drag above it and lift aft of it pitch the nose up and down
    lift_arm = dx * np.cos(a) + dy * np.sin(a)
    drag_arm = dy * np.cos(a) - dx * np.sin(a)
    expected = base.cm + (base.cd * drag_arm - base.cl * lift_arm) / 550.0
    assert moved.cl == pytest.approx(base.cl, rel=1e-10)
    assert moved.cm == pytest.approx(expected, abs=1e-10)
    d = np.radians(5.0)  # counter-clockwise about (137.5, 0): nose down by 5 deg
    rot = np.array([[np.cos(d), -np.sin(d)], [np.sin(d), np.cos(d)]])
    turned = (xy - [137.5, 0.0]) @ rot.T + [137.5, 0.0]
    r = aero.analyze(turned, cond.at(alpha=8.0))
    for key in ("cl", "cd", "cm", "xtr_upper", "xtr_lower"):
        assert getattr(r, key) == pytest.approx(getattr(base, key), rel=1e-9, abs=1e-12), key


def test_target_cl_is_met_and_pressure_integrates_to_the_lift():
    r = aero.analyze(aero.section(geo.target()), flight.THERMALLING, cp_match="lift")
    assert r.cl == pytest.approx(flight.THERMALLING.cl, abs=1e-11)  # Newton to 1e-12
    # force of the gauge pressure on the body, -oint p n_out ds, per unit span [N/mm]
    nodes, p = r.nodes[1:-1], flight.THERMALLING.q_mpa * r.cp[1:-1]
    seg = np.diff(nodes, axis=0)
    pm = 0.5 * (p[1:] + p[:-1])
    force = -np.sum(pm[:, None] * np.column_stack([seg[:, 1], -seg[:, 0]]), axis=0)
    a = np.radians(r.alpha_inviscid)
    lift = force[1] * np.cos(a) - force[0] * np.sin(a)
    # pressure integration and Kutta-Joukowski agree to the panel discretisation (~0.5 %)
    assert lift == pytest.approx(flight.THERMALLING.q_mpa * 550.0 * r.cl, rel=0.01)
    # stagnation: the largest Cp is 1 (to the node spacing at the nose)
    assert np.nanmax(r.cp) == pytest.approx(1.0, abs=0.01)


@pytest.mark.parametrize("nodes", [geo.undeformed(), geo.target()])
def test_skin_matched_pressure_follows_the_viscous_one_on_the_skin(nodes):
    """At high lift the boundary layer costs much of the lift aft; the panel solution at the
    viscous lift then misses the suction round the nose, the one fitted to NeuralFoil's Cp on
    the skin does not."""
    skin = aero.analyze(aero.section(nodes), flight.THERMALLING)
    lift = aero.analyze(aero.section(nodes), flight.THERMALLING, cp_match="lift")
    # measured: rms 0.060 (undeformed) and 0.031 (target) against 0.33 and 0.27 at equal lift; 0.1
    # is a quarter of the peak's own change between the two shapes (Cp -6.2 vs -4.3)
    assert skin.cp_match_rms < 0.1
    assert lift.cp_match_rms > 2.0 * skin.cp_match_rms
    # fitting the nose flow puts the inviscid angle between the equal-lift one and the
    # viscous one (the boundary layer decambers the section aft, not at the nose)
    assert lift.alpha_inviscid < skin.alpha_inviscid < skin.alpha
    assert skin.cp_min < lift.cp_min  # stronger suction peak


def test_skin_pressure_at_the_nodes_and_its_sign():
    nodes = geo.target()
    p, r = aero.skin_loads(nodes, flight.THERMALLING)
    assert p.shape == (nodes.shape[0],)
    # the nodes lie on the analysed contour: p is q Cp interpolated there; the nose node
    # (suction side of the drooped nose at high lift) and the lower surface (pressure side)
    assert np.allclose(p, flight.THERMALLING.q_mpa * r.cp_at(nodes), rtol=0, atol=1e-15)
    assert p.min() < 0.0 < p.max() <= flight.THERMALLING.q_mpa * (1.0 + 1e-9)
    upper = nodes[:, 1] > 0.0
    assert np.mean(p[upper]) < np.mean(p[~upper])  # suction above, pressure below


def test_drag_is_smooth_in_the_shape():
    """Central differences of CD along the morphing path converge at O(h^2) and agree at two
    small steps: the response can be differentiated by central differences."""
    und, tgt = geo.undeformed(), geo.target()
    drag = aero.AeroResponse("drag", flight.THERMALLING)

    def f(t):
        return drag.of_nodes(und + t * (tgt - und))

    def central(h):
        return (f(0.5 + h) - f(0.5 - h)) / (2 * h)

    d2, d3, d4 = central(1e-2), central(1e-3), central(1e-4)
    # h = 1e-3 and 1e-4 of the morphing path (6 and 0.6 micrometres of droop at the nose)
    # agree to 1e-6 relative (measured -47.36326, -47.36327 counts per unit path); the step
    # 1e-2 is off by its O(h^2) truncation (measured 1.2e-3 counts), 100 times that of 1e-3
    assert d4 == pytest.approx(d3, rel=1e-6)
    assert abs(d2 - d4) / abs(d3 - d4) > 30.0


def test_aero_response_carries_a_complex_direction_by_central_differences():
    """A complex skin ``x + i d`` (a complex-step or direct-method state) gives ``f(x) + i
    Df(x)[d]``: against central differences along d of the real response, at a step 100
    times larger than the response's own."""
    drag = aero.AeroResponse("drag", flight.THERMALLING)
    x, d = geo.undeformed(), 1e-20 * (geo.target() - geo.undeformed())
    value = drag.of_nodes(x + 1j * d)
    assert value.real == drag.of_nodes(x)  # the nominal analysis, not a perturbed one
    h = 1e-2 / np.max(np.abs(geo.target() - geo.undeformed()))  # 0.1 mm at the nose
    ref = (drag.of_nodes(x + h * d / 1e-20) - drag.of_nodes(x - h * d / 1e-20)) / (2 * h)
    # both steps are central: the difference is the larger step's O(h^2) truncation, which
    # tests/test_drag_is_smooth_in_the_shape measures at ~1e-4 relative for 60 micrometres
    assert value.imag / 1e-20 == pytest.approx(ref, rel=1e-3)
    assert drag.of_nodes(x + 0j) == complex(drag.of_nodes(x), 0.0)
    # it travels to worker processes (sweeps, Dask) with its options
    copy = pickle.loads(pickle.dumps(drag))
    assert copy.of_nodes(x) == drag.of_nodes(x) and copy.options == drag.options
    assert set(aero.aero_responses(flight.HIGH_SPEED)) == {
        "drag", "lift_to_drag", "transition_upper", "transition_lower"}
    with pytest.raises(ModelError, match="step"):
        aero.AeroResponse("drag", flight.HIGH_SPEED, step=1.0)
    with pytest.raises(ModelError, match="FlightCondition"):
        aero.AeroResponse("drag", {"speed": 30.0})


def test_coefficients_without_the_panel_method_and_from_a_start_angle():
    xy = aero.section(geo.target())
    full = aero.analyze(xy, flight.THERMALLING)
    quick = aero.analyze(xy, flight.THERMALLING, pressure=False)
    started = aero.analyze(xy, flight.THERMALLING, pressure=False, alpha_start=full.alpha + 0.3)
    # the viscous coefficients do not depend on the panel solution; the Newton solve for the
    # target CL stops at |dCL| < 1e-12, from either start (slope ~0.1/deg: 1e-11 deg apart)
    for r in (quick, started):
        assert r.alpha == pytest.approx(full.alpha, abs=1e-9)
        assert r.cd == pytest.approx(full.cd, rel=1e-9)
        assert r.xtr_upper == pytest.approx(full.xtr_upper, rel=1e-9)
    assert not quick.has_pressure and np.isnan(quick.alpha_inviscid)
    assert "Cp_min -" in quick.summary()
    with pytest.raises(ModelError, match="no pressure distribution"):
        quick.cp_at(geo.target())


def test_aero_response_gradients_against_whole_run_central_differences():
    """The direct method (exact state sensitivities, the flow differenced along them) against
    central differences of whole runs, for a torque, a pivot coordinate and the wall."""
    from morphlab.sensitivity.strategies import FiniteDifference

    mo = ml.morphing
    settings = ml.Settings.of(mo.SETTINGS, dt=1e-3)
    responses = {**aero.aero_responses(flight.THERMALLING),
                 "cp_min": aero.AeroResponse("cp_min", flight.THERMALLING)}
    names = ["M_t", "x_A", "t_w"]
    direct = ml.sensitivities(mo.build, mo.DEFAULTS, responses, variables=names,
                              method="direct", settings=settings)
    central = ml.sensitivities(mo.build, mo.DEFAULTS, responses, variables=names,
                               method=FiniteDifference("central", 1e-6), settings=settings)
    for k in responses:
        assert direct.values[k] == central.values[k]
        for v in names:
            g, ref = direct.gradients[k][v], central.gradients[k][v]
            # measured within 8e-8 relative (the pivot, nearest the mechanism's toggle, has
            # the largest second derivative: 4e-4 at a step of 1e-4, 4e-6 at 1e-5, O(h^2));
            # the transition on the laminar lower surface sits at the trailing edge (0)
            assert g == pytest.approx(ref, rel=1e-6, abs=1e-12), (k, v)
    assert direct.gradients["drag"]["M_t"] < 0.0  # more droop, less drag in the thermal


def test_analysis_input_errors():
    with pytest.raises(ModelError, match="model_size"):
        aero.analyze(aero.section(), flight.HIGH_SPEED, model_size="huge")
    with pytest.raises(ModelError, match="FlightCondition"):
        aero.analyze(aero.section(), {"speed": 30.0})
    with pytest.raises(ModelError, match="outside the section's range"):
        aero.analyze(aero.section(), flight.THERMALLING.at(cl=2.4))
    with pytest.raises(ModelError, match="cp_match"):
        aero.analyze(aero.section(), flight.HIGH_SPEED, cp_match="pressure")
    with pytest.raises(ModelError, match="unknown aerodynamic quantity"):
        aero.AeroResponse("thrust", flight.HIGH_SPEED)


def test_drag_of_the_mechanism_by_whole_run_central_differences():
    """d(CD)/d(M_t) of the realized morphed skin through the whole model (static equilibrium
    of the mechanism at full torque, then the flow): two small steps agree."""
    mo = ml.morphing
    drag = aero.AeroResponse("drag", flight.THERMALLING)

    def cd(m_t):
        p = dict(mo.DEFAULTS, M_t=m_t)
        return drag(ml.static(mo.build(p), t=mo.T_RAMP_S, steps=mo.STATIC_STEPS))

    m0 = mo.DEFAULTS["M_t"]

    def log_derivative(h):  # M_t dCD/dM_t [counts]
        return (cd(m0 * (1 + h)) - cd(m0 * (1 - h))) / (2 * h)

    d3, d4 = log_derivative(1e-3), log_derivative(1e-4)
    # measured -30.75197 and -30.75189 counts: the O(h^2) truncation at 1e-3 is ~1e-4 counts
    # (from 1e-2: -30.7593), the statics' and the flow's round-off far below; 1e-5 relative
    # holds both with the margin of a factor 3
    assert d4 == pytest.approx(d3, rel=1e-5)
    assert d4 < 0.0  # more torque droops the nose further: less drag in the thermal


def test_aero_table_and_cp_plot():
    from morphlab.morphing.aero_study import aero_table, format_table, plot_cp

    rows = aero_table({"undeformed": None, "target": geo.target()},
                      {"thermalling": flight.THERMALLING})
    assert [r["shape"] for r in rows] == ["undeformed", "target"]
    direct = aero.analyze(aero.section(geo.target()), flight.THERMALLING)
    assert rows[1]["cd_counts"] == pytest.approx(direct.cd_counts, rel=1e-12)
    # line load = nodal pressure times the 1000 mm span
    assert rows[1]["line_load_min"] == pytest.approx(1000.0 * rows[1]["p_min_mpa"], rel=1e-12)
    # the drooped nose is the point of the mechanism: less drag and a weaker suction peak at
    # the thermalling lift (measured 194 vs 239 counts, Cp -4.3 vs -6.2)
    assert rows[1]["cd_counts"] < rows[0]["cd_counts"]
    assert rows[1]["cp_min_skin"] > rows[0]["cp_min_skin"]
    text = format_table(rows)
    assert text.count("\n") == 3 and "CD [counts]" in text
    fig = plot_cp({r["shape"]: r["result"] for r in rows}, xc_max=0.3)
    assert len(fig.axes[0].lines) == 2 * 3 + 1  # panel line + 2 station sets each, spar line
