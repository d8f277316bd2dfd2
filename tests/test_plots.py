"""Tests of morphlab.plots: each function returns a labelled Figure that draws exactly the data it
was given (compared with the model input, with hand-computed reductions or with closed-form
values), and rejects malformed input with a ModelError."""

import math

import matplotlib.pyplot as plt
import numpy as np
import pytest
from matplotlib.collections import QuadMesh
from matplotlib.contour import ContourSet
from matplotlib.figure import Figure
from matplotlib.patches import FancyArrowPatch, Polygon, Rectangle
from models import flexible_mechanism, straight_nodes
from PIL import Image

import morphlab as ml
from morphlab import plots
from morphlab.errors import ModelError

# Drawing copies the data into artists without arithmetic, except for float64 conversion, so the
# data read back must equal the input exactly; results of sums/products get 1e-12 relative.
EXACT = 0.0
ROUND = 1e-12


@pytest.fixture(scope="module")
def mech():
    return flexible_mechanism()


@pytest.fixture(scope="module")
def run(mech):
    return ml.simulate(mech, t_end=0.02, dt=1e-3)


def _gid_lines(ax, prefix):
    return [ln for ln in ax.lines if (ln.get_gid() or "").startswith(prefix)]


def _mesh(ax):
    (m,) = [c for c in ax.collections if isinstance(c, QuadMesh)]
    return m


def _grey(rgba):
    # luminance of sRGB primaries (ITU-R BT.601 weights): what a grey print shows
    r, g, b = rgba[:3]
    return 0.299 * r + 0.587 * g + 0.114 * b


def _colorbar_label(fig):
    return [a.get_ylabel() for a in fig.axes if a.get_label() == "<colorbar>"]


# --------------------------------------------------------------------------- model
def test_model_draws_springs_and_line_loads():
    m = ml.Model(gravity=(0.0, 0.0), name="springs")
    nodes = straight_nodes(4, length=40.0)
    beam = m.add_beam(nodes, E=7e4, rho=2.7e-9, thickness=1.0, width=10.0, name="beam")
    arm = m.add_rigid_body(mass=1e-4, inertia=1.0, position=(20.0, 30.0), name="arm")
    pin = m.add_revolute(m.ground, beam, at=(0.0, 0.0), name="pin")
    m.add_revolute(m.ground, arm, at=(20.0, 30.0), name="pivot")
    m.add_spring("k", beam, arm, at_a=(40.0, 0.0), at_b=(30.0, 30.0), stiffness=1.0)
    m.add_rotational_spring("kr", pin, stiffness=2.0)
    m.add_line_load("q", beam, q=(0.0, -0.5), elements=[1, 2])
    ax = plots.model(m).axes[0]
    (zig,) = [ln for ln in ax.lines if ln.get_gid() == "spring:k"]
    xy = zig.get_xydata()
    # from one attachment point to the other, with teeth off the line between them
    assert np.array_equal(xy[0], [40.0, 0.0]) and np.allclose(xy[-1], [30.0, 30.0], atol=ROUND)
    axis = np.array([-10.0, 30.0]) / np.hypot(10.0, 30.0)
    off = (xy - xy[0]) @ np.array([-axis[1], axis[0]])
    assert np.abs(off).max() > 0.0 and abs(off[0]) == 0.0
    (spiral,) = [ln for ln in ax.lines if ln.get_gid() == "spring:kr"]  # around the pin
    r = np.hypot(*spiral.get_xydata().T)
    assert r.min() > 0.0 and np.all(np.diff(r) > 0.0)
    # one arrow per loaded element, pointing at its middle along q
    heads = [(t.xy, t.xyann) for t in ax.texts if t.get_gid() == "line_load:q"]
    assert [tuple(h) for h, _ in heads] == [(15.0, 0.0), (25.0, 0.0)]
    assert all(tail[0] == head[0] and tail[1] > head[1] for head, tail in heads)
    assert [t.get_text() for t in ax.texts if t.get_gid() in ("label:k", "label:kr",
                                                               "label:q")] == ["k", "kr", "q"]


def test_model_draws_bodies_joints_and_loads(mech):
    before = plt.get_fignums()
    fig = plots.model(mech)
    assert plt.get_fignums() == before  # a bare Figure: nothing for the caller to close
    assert isinstance(fig, Figure)
    ax = fig.axes[0]
    assert (ax.get_xlabel(), ax.get_ylabel()) == ("x [mm]", "y [mm]")

    (beam,) = _gid_lines(ax, "beam:coupler")
    np.testing.assert_allclose(beam.get_xydata(), mech.body("coupler").nodes, rtol=0, atol=EXACT)
    # crank: centre of mass (0, 10) joined to the joint points A (0, 0) and B (0, 20)
    crank = [ln.get_xydata() for ln in _gid_lines(ax, "body:crank") if not
             ln.get_gid().endswith(":com")]
    assert sorted(tuple(xy[1]) for xy in crank) == [(0.0, 0.0), (0.0, 20.0)]
    assert all(tuple(xy[0]) == (0.0, 10.0) for xy in crank)

    texts = {t.get_text() for t in ax.texts}
    assert {"A", "B", "C", "D", "coupler", "crank", "rocker"} <= texts
    assert "F (2 N)" in texts and "Mt (50 N mm)" in texts
    # A and D pin the mechanism to the ground: one triangle each
    pins = [p for p in ax.patches if p.get_gid() == "ground" and isinstance(p, Polygon)]
    assert sorted(tuple(p.get_xy()[0]) for p in pins) == [(0.0, 0.0), (60 * math.cos(0.1), 0.0)]
    (force,) = [t for t in ax.texts if t.get_gid() == "force:F"]
    np.testing.assert_allclose(force.xy, straight_nodes(6, 60.0, 0.1, (0.0, 20.0))[3],
                               atol=EXACT)
    assert len([p for p in ax.patches if p.get_gid() == "torque:Mt"]) == 1


def test_model_accepts_system_and_result_and_draws_fix_weld_drive(run):
    for obj in (run.system, run):
        ax = plots.model(obj, labels=False, units={"length": "m"}).axes[0]
        assert ax.get_xlabel() == "x [m]"
        assert not any((t.get_gid() or "").startswith("label:") for t in ax.texts)

    m = ml.Model(name="fix-weld-drive")
    beam = m.add_beam(straight_nodes(3, 30.0), E=7e4, rho=2.7e-9, thickness=1.0, width=5.0,
                      name="strip")
    arm = m.add_rigid_body(mass=1e-4, inertia=1.0, position=(30.0, 5.0), name="arm")
    m.add_fix(beam, at=(0.0, 0.0), dofs="xyr", name="F")
    m.add_weld(beam, arm, at=(30.0, 0.0), name="W")
    m.add_drive(beam, angle=ml.Ramp(0.0, 1.0), at=(10.0, 0.0), name="Dr")
    ax = plots.model(m).axes[0]
    texts = {t.get_text() for t in ax.texts}
    assert {"F (xyr)", "W", "Dr (drive)"} <= texts
    # a clamp (rotation held) stands on a hatched block without a pin triangle
    ground = [p for p in ax.patches if p.get_gid() == "ground"]
    assert [type(p) for p in ground] == [Rectangle]
    assert ground[0].get_hatch() == "////"
    assert any(isinstance(p, FancyArrowPatch) and p.get_gid() == "joint:Dr" for p in ax.patches)

    with pytest.raises(ModelError, match="expected a Model"):
        plots.model(np.zeros(3))


# --------------------------------------------------------------------------- snapshots
def test_snapshots_draw_one_line_per_body_and_time(run, mech):
    target = run.node_positions("coupler")[-1] + [0.0, 3.0]
    fig = plots.snapshots(run, n=4, target=target)
    ax = fig.axes[0]
    assert (ax.get_xlabel(), ax.get_ylabel()) == ("x [mm]", "y [mm]")
    assert _colorbar_label(fig) == ["time t [s]"]
    lines = _gid_lines(ax, "snapshot:")
    assert len(lines) == 4 * 3  # 4 snapshots of 3 bodies

    def line(i, body):
        (ln,) = _gid_lines(ax, f"snapshot:{i}:{body}")
        return ln

    # first snapshot = the model's initial geometry (consistent initial state, to round-off)
    np.testing.assert_allclose(line(0, "coupler").get_xydata(), mech.body("coupler").nodes,
                               atol=ROUND * 100)
    np.testing.assert_allclose(line(3, "coupler").get_xydata(),
                               run.node_positions("coupler")[-1], atol=EXACT)
    # rocker: the line between its joints C and D, initially (60 cos .1, 20 + 60 sin .1)-(.., 0)
    end = straight_nodes(6, 60.0, 0.1, (0.0, 20.0))[-1]
    np.testing.assert_allclose(line(0, "rocker").get_xydata(), [end, [end[0], 0.0]],
                               atol=ROUND * 100)
    # early light, late dark: the grey value falls monotonically
    greys = [_grey(line(i, "coupler").get_color()) for i in range(4)]
    assert all(a > b for a, b in zip(greys, greys[1:])), greys
    (tgt,) = _gid_lines(ax, "target")
    assert tgt.get_linestyle() == "--"
    np.testing.assert_allclose(tgt.get_xydata(), target, atol=EXACT)


def test_snapshots_and_animation_draw_springs_between_their_moving_points(tmp_path):
    # a pendulum beam held at its middle node by a spring from a swinging arm: each snapshot's
    # zigzag runs from that node as drawn (deformation magnified) to the arm's point then
    m = ml.Model(gravity=(0.0, -9.81e3), name="sprung")
    nodes = straight_nodes(4, length=40.0)
    beam = m.add_beam(nodes, E=7e4, rho=2.7e-9, thickness=1.0, width=10.0, name="beam")
    arm = m.add_rigid_body(mass=1e-4, inertia=1.0, position=(20.0, 30.0), name="arm")
    m.add_revolute(m.ground, beam, at=(0.0, 0.0), name="pin")
    m.add_revolute(m.ground, arm, at=(20.0, 30.0), name="pivot")
    m.add_spring("k", beam, arm, at_a=(20.0, 0.0), at_b=(30.0, 30.0), stiffness=0.05)
    res = ml.simulate(m, t_end=0.01, dt=1e-3)
    fig = plots.snapshots(res, n=3, magnify=5.0)
    ax = fig.axes[0]
    t = np.real(res.t)
    for i, k in enumerate(np.unique(np.round(np.linspace(0, t.size - 1, 3)).astype(int))):
        (zig,) = [ln for ln in ax.lines if ln.get_gid() == f"snapshot:{i}:k"]
        (drawn,) = [ln for ln in ax.lines if ln.get_gid() == f"snapshot:{i}:beam"]
        xy = zig.get_xydata()
        assert np.array_equal(xy[0], drawn.get_xydata()[2])
        np.testing.assert_allclose(xy[-1], np.real(res.point_positions("arm", (30.0, 30.0)))[k],
                                   rtol=0, atol=ROUND * 50.0)
    path = plots.animate(res, tmp_path / "sprung.gif", n_frames=4)
    assert Image.open(path).n_frames == 4


def test_snapshots_at_given_times_take_the_nearest_step(run):
    ax = plots.snapshots(run, times=[0.0, 0.0104]).axes[0]
    assert len(_gid_lines(ax, "snapshot:")) == 2 * 3
    (ln,) = _gid_lines(ax, "snapshot:1:coupler")
    np.testing.assert_allclose(ln.get_xydata(), run.node_positions("coupler")[10], atol=EXACT)


@pytest.mark.parametrize("kwargs, match", [
    ({"target": np.zeros((7, 3))}, r"target must have shape \(n, 2\)"),
    ({"target": np.zeros((5, 2))}, "target has 5 points"),
    ({"times": [0.5]}, "outside the run"),
    ({"n": 0}, "positive integer"),
    ({"units": {"lenght": "m"}}, "unknown unit keys"),
])
def test_snapshots_reject_bad_input(run, kwargs, match):
    with pytest.raises(ModelError, match=match):
        plots.snapshots(run, **kwargs)


def test_snapshots_need_a_result():
    with pytest.raises(ModelError, match="expected a morphlab Result"):
        plots.snapshots({"t": [0.0]})


# --------------------------------------------------------------------------- stress map
def _signed_largest(values):
    """Slow reference: the entry of largest magnitude, with its sign."""
    flat = list(np.ravel(values))
    return max(flat, key=abs)


@pytest.fixture(scope="module")
def stress():
    rng = np.random.default_rng(3)
    return rng.normal(scale=50.0, size=(5, 4, 2, 2))


def test_stress_map_reduces_to_signed_largest_magnitude(stress):
    t = np.linspace(0.0, 0.4, 5)
    fig = plots.stress_map(t, stress)
    ax = fig.axes[0]
    assert (ax.get_xlabel(), ax.get_ylabel()) == ("element index [-]", "time t [s]")
    assert "stress σ [MPa]" in _colorbar_label(fig)[0]
    ref = np.array([[_signed_largest(stress[i, e]) for e in range(4)] for i in range(5)])
    mesh = _mesh(ax)
    np.testing.assert_allclose(np.asarray(mesh.get_array()).reshape(5, 4), ref, atol=EXACT)
    vmax = np.abs(ref).max()
    assert mesh.get_clim() == (-vmax, vmax)  # symmetric about zero: white means 0 MPa
    assert mesh.get_cmap().name == "RdBu_r"
    # sign also by line style: the contour levels below zero are dashed
    (cs,) = [c for c in ax.collections if isinstance(c, ContourSet)]
    assert any(lv < 0 for lv in cs.levels) and any(lv > 0 for lv in cs.levels)
    for lv, ls in zip(cs.levels, cs.get_linestyles()):
        assert (ls[1] is not None) == (lv < 0)  # dash pattern only on negative levels


def test_stress_map_fibre_abs_and_arc(stress):
    t = np.linspace(0.0, 0.4, 5)
    arc = plots.arc_coordinate(straight_nodes(4, 20.0, angle=0.3))
    np.testing.assert_allclose(arc, [0.0, 5.0, 10.0, 15.0, 20.0], atol=ROUND * 20)
    ax = plots.stress_map(t, stress, arc=arc, fibre=1).axes[0]
    assert ax.get_xlabel() == "arc length s [mm]"
    mesh = _mesh(ax)
    np.testing.assert_allclose(mesh.get_coordinates()[0, :, 0], arc, atol=EXACT)
    ref = np.array([[_signed_largest(stress[i, e, :, 1]) for e in range(4)] for i in range(5)])
    np.testing.assert_allclose(np.asarray(mesh.get_array()).reshape(5, 4), ref, atol=EXACT)

    ax = plots.stress_map(t, stress, fibre="abs").axes[0]
    mesh = _mesh(ax)
    np.testing.assert_allclose(np.asarray(mesh.get_array()).reshape(5, 4),
                               np.abs(stress).max(axis=(2, 3)), atol=EXACT)
    assert mesh.get_cmap().name == "viridis"
    assert not [c for c in ax.collections if isinstance(c, ContourSet)]


def test_stress_map_of_a_run_into_given_axes(run):
    fig = Figure()
    ax = fig.add_subplot()
    assert plots.stress_map(run.t, run.stress("coupler"), ax=ax) is fig
    assert np.asarray(_mesh(ax).get_array()).size == run.n_t * 6


@pytest.mark.parametrize("t, s, kwargs, match", [
    (np.arange(5.0), np.zeros((5, 4, 4)), {}, r"shape \(5, n, 2, 2\)"),
    (np.arange(4.0), np.zeros((5, 4, 2, 2)), {}, r"shape \(4, n, 2, 2\)"),
    (np.arange(5.0), np.zeros((5, 4, 2, 2)), {"arc": np.arange(3.0)}, "arc must hold"),
    (np.arange(5.0), np.zeros((5, 4, 2, 2)), {"fibre": 2}, "fibre must be"),
    (np.arange(5.0), np.zeros((5, 4, 2, 2)), {"fibre": True}, "fibre must be"),
    (np.array([0.0, 1, 1, 2, 3]), np.zeros((5, 4, 2, 2)), {}, "strictly increasing"),
])
def test_stress_map_rejects_bad_shapes(t, s, kwargs, match):
    with pytest.raises(ModelError, match=match):
        plots.stress_map(t, s, **kwargs)


# --------------------------------------------------------------------------- sensitivity map
def test_sensitivity_map_is_symmetric_about_zero():
    t = np.linspace(0.0, 1.0, 3)
    d = np.array([[3.0, -1.0], [0.5, 0.0], [-0.2, 1.0]])
    fig = plots.sensitivity_map(t, d, "t_w", variable_unit="mm")
    ax = fig.axes[0]
    mesh = _mesh(ax)
    assert mesh.get_clim() == (-3.0, 3.0)  # largest magnitude 3 on both sides
    assert mesh.get_cmap().name == "RdBu_r"
    np.testing.assert_allclose(np.asarray(mesh.get_array()).reshape(3, 2), d, atol=EXACT)
    assert _colorbar_label(fig) == ["dσ/dt_w [MPa / mm]"]
    assert ax.get_ylabel() == "time t [s]" and ax.get_xlabel() == "element index [-]"
    with pytest.raises(ModelError, match=r"dvalue \(n_t, n_elem\)"):
        plots.sensitivity_map(t, d[:, 0], "t_w")
    with pytest.raises(ModelError, match="name"):
        plots.sensitivity_map(t, d, "")


# --------------------------------------------------------------------------- profiles
def test_profile_comparison_errors_and_rms():
    phi = np.linspace(0.0, np.pi, 5)
    undeformed = 50.0 * np.column_stack([np.cos(phi), np.sin(phi)])
    target = undeformed * 1.1
    offset = np.array([[0.0, 0.0], [3.0, 4.0], [0.0, -1.0], [1.0, 0.0], [0.0, 2.0]])
    fig = plots.profile_comparison(undeformed, target, target + offset)
    ax1, ax2 = fig.axes
    for ax in (ax1, ax2):
        assert ax.get_xlabel() and "[" in ax.get_ylabel()
    assert ax2.get_ylabel() == "error e_k [mm]"
    # eq. (41): e_k = |offset_k| = 0, 5, 1, 1, 2; eq. (42): RMS = sqrt(31 / 5)
    e = [0.0, 5.0, 1.0, 1.0, 2.0]
    heights = [p.get_height() for p in ax2.patches]
    np.testing.assert_allclose(heights, e, atol=ROUND * 100)
    rms = math.sqrt(31 / 5)
    (summary,) = [t for t in ax2.texts if t.get_gid() == "error-summary"]
    assert summary.get_text() == f"max e = 5 mm (node 1, hatched)\nRMS e = {rms:.4g} mm"
    assert ax2.patches[1].get_hatch() == "//"
    (rms_line,) = [ln for ln in ax2.lines if ln.get_label().startswith("RMS")]
    assert rms_line.get_ydata()[0] == pytest.approx(rms, rel=ROUND)

    with pytest.raises(ModelError, match=r"simulated must have shape \(5, 2\)"):
        plots.profile_comparison(undeformed, target, target[:4])
    with pytest.raises(ModelError, match="pair of Axes"):
        plots.profile_comparison(undeformed, target, target, ax=ax1)


# --------------------------------------------------------------------------- node sensitivities
def test_node_sensitivities_grouped_bars_and_lines():
    d = {"t_w": np.array([1.0, -2.0, 0.5, 0.0, 4.0]), "M_t": np.arange(5.0),
         "E": -np.ones(5)}
    ax = plots.node_sensitivities(d, variable_units={"t_w": "mm"}).axes[0]
    assert ax.get_xlabel() == "node k [-]" and ax.get_ylabel() == "de_k/dp [mm / unit of p]"
    assert len(ax.patches) == 3 * 5
    for i, a in enumerate(d.values()):
        np.testing.assert_allclose([p.get_height() for p in ax.patches[5 * i:5 * i + 5]], a,
                                   atol=EXACT)
    # each variable has its own hatching, so the groups differ without colour
    assert len({ax.patches[5 * i].get_hatch() for i in range(3)}) == 3
    assert [t.get_text() for t in ax.get_legend().get_texts()] == ["t_w [mm/mm]", "M_t", "E"]

    ax = plots.node_sensitivities(d, kind="lines", normalize=True).axes[0]
    lines = [ln for ln in ax.lines if ln.get_label() in d]
    assert len(lines) == 3
    assert [np.abs(ln.get_ydata()).max() for ln in lines] == [1.0, 1.0, 1.0]

    with pytest.raises(ModelError, match=r"dvalues\['M_t'\] \(n_nodes,\) must have shape \(5\)"):
        plots.node_sensitivities({"t_w": np.zeros(5), "M_t": np.zeros(4)})
    with pytest.raises(ModelError, match="non-empty dict"):
        plots.node_sensitivities({})
    with pytest.raises(ModelError, match="kind"):
        plots.node_sensitivities(d, kind="pie")


# --------------------------------------------------------------------------- timings
def test_timing_bars_annotate_ratios():
    timings = {"primal": 2.0, "semi-analytical": 3.0, "numerical": 8.0}
    ax = plots.timing_bars(timings).axes[0]
    assert ax.get_ylabel() == "wall time [s]" and ax.get_xlabel() == "method"
    assert [p.get_height() for p in ax.patches] == [2.0, 3.0, 8.0]
    ratios = [t.get_text() for t in ax.texts if (t.get_gid() or "").startswith("ratio:")]
    assert ratios == ["1.00×", "1.50×", "4.00×"]
    ax = plots.timing_bars(timings, reference="numerical").axes[0]
    assert [t.get_text() for t in ax.texts] == ["0.25×", "0.38×", "1.00×"]
    ax = plots.timing_bars({"a": 1.0, "b": 2.0}).axes[0]
    assert len(ax.texts) == 0  # no 'primal', no reference: nothing to compare with
    with pytest.raises(ModelError, match="reference 'x' is not among"):
        plots.timing_bars(timings, reference="x")
    with pytest.raises(ModelError, match="finite and >= 0"):
        plots.timing_bars({"primal": -1.0})


def test_timing_curves_report_growth_exponent():
    x = np.array([10.0, 20.0, 40.0, 80.0])
    series = {"primal": 1e-3 * x, "direct": 2e-5 * x**2}
    ax = plots.timing_curves(x, series, "number of elements [-]").axes[0]
    assert ax.get_xscale() == "log" and ax.get_yscale() == "log"
    assert ax.get_xlabel() == "number of elements [-]" and ax.get_ylabel() == "wall time [s]"
    # exact power laws: the least-squares slope in log-log is the exponent (to round-off)
    labels = [t.get_text() for t in ax.get_legend().get_texts()]
    assert labels == ["primal (slope 1.00)", "direct (slope 2.00)"]
    ax = plots.timing_curves(x, {"zero": 0 * x}, "n [-]", loglog=False).axes[0]
    assert ax.get_xscale() == "linear"
    with pytest.raises(ModelError, match="> 0"):
        plots.timing_curves(x, {"zero": 0 * x}, "n [-]")
    with pytest.raises(ModelError, match="same length as x"):
        plots.timing_curves(x, {"short": x[:3]}, "n [-]")


# --------------------------------------------------------------------------- energy, animation
def test_energy_lines(run):
    fig = plots.energy(run, units={"energy": "mJ"})
    ax = fig.axes[0]
    assert ax.get_xlabel() == "time t [s]" and ax.get_ylabel() == "energy [mJ]"
    e = run.energy
    by_label = {ln.get_label(): ln.get_ydata() for ln in ax.lines}
    np.testing.assert_allclose(by_label["kinetic"], e["kinetic"], atol=EXACT)
    np.testing.assert_allclose(by_label["gravity (from t0)"], e["gravity"] - e["gravity"][0],
                               atol=EXACT)
    bal = e["total"] - e["work"] + e["damping"]
    # the coupler is damped, so the balance including the dissipated energy is drawn too
    np.testing.assert_allclose(by_label["total − work + dissipated (from t0)"], bal - bal[0],
                               atol=ROUND * np.abs(e["total"]).max())
    assert len(ax.lines) == 7


def test_animate_writes_gif(run, tmp_path):
    path = plots.animate(run, tmp_path / "motion.gif", fps=10, n_frames=5,
                         target=run.node_positions("coupler")[-1])
    assert path == tmp_path / "motion.gif"
    data = path.read_bytes()
    assert data[:6] in (b"GIF87a", b"GIF89a")
    with Image.open(path) as im:
        assert im.n_frames == 5
    with pytest.raises(ModelError, match=r"\.gif"):
        plots.animate(run, tmp_path / "motion.mp4")
    with pytest.raises(ModelError, match="n_frames"):
        plots.animate(run, tmp_path / "m.gif", n_frames=0)
