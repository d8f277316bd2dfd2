"""Results in a notebook: short reprs, summaries with units and the right wording for statics,
the chord deflection of a beam (against the closed form of a pinned-pinned beam), and the
magnified deformation of the run plots."""

import numpy as np
import pytest
from models import E_AL, RHO_AL, flexible_mechanism, straight_nodes, tip_loaded_cantilever

import morphlab as ml
from morphlab.errors import ModelError


@pytest.fixture(scope="module")
def run():
    return ml.simulate(flexible_mechanism(), t_end=0.01, dt=1e-3)


def test_result_repr_is_short_and_says_what_matters(run):
    text = repr(run)
    assert len(text) < 600 and "\n" not in text
    assert run.status in text and "'four-bar'" in text and f"n_dof {run.system.n_dof}" in text
    assert f"({run.n_t}, {run.system.n_dof})" in text and "histories q v a lam" in text


def test_sensitivity_result_repr_is_short():
    sens = ml.sensitivities(tip_loaded_cantilever, {"t": 2.0, "F": 1.0},
                            {"tip": lambda r: r.node_positions("beam", -1)[-1, 1]},
                            t_end=1e-3, dt=5e-4)
    text = repr(sens)
    assert len(text) < 600
    assert "'direct'" in text and "t: 2" in text and "tip: " in text and "1 responses x 2" in text
    assert repr(sens) == str(sens)


def test_summary_of_a_run_names_units_and_steps(run):
    s = run.summary()
    assert "10 steps of 0.001 (time unit of the model)" in s and "in model units" in s
    run.system.model.units = "mm, t, s, N, MPa"
    try:
        assert "in mm, t, s, N, MPa" in run.summary()
    finally:
        del run.system.model.units


def _pinned_beam(F, angle, n_elem=8, length=200.0):
    """A beam pinned at both ends (x, y held) at ``angle`` to the x axis, a force F [N]
    perpendicular to it at mid-span, no gravity (mm, t, s, N, MPa)."""
    m = ml.Model(gravity=(0.0, 0.0), name="pinned")
    nodes = straight_nodes(n_elem, length, angle=angle)
    beam = m.add_beam(nodes, E=E_AL, rho=RHO_AL, thickness=4.0, width=10.0, name="beam")
    m.add_fix(beam, at=tuple(nodes[0]), dofs="xy", name="left")
    m.add_fix(beam, at=tuple(nodes[-1]), dofs="xy", name="right")
    normal = np.array([-np.sin(angle), np.cos(angle)])
    m.add_force(beam, at=tuple(nodes[n_elem // 2]), force=tuple(-F * normal),
                profile=ml.Ramp(0.0, 1.0), name="F")
    return m


def test_static_summary_and_chord_deflection_of_a_pinned_beam():
    """Mid-span deflection F L³/(48 E I) of the inclined pinned-pinned beam (cubic elements
    are nodally exact for point loads; the small load keeps the membrane stiffening of the
    held ends, ~(w/t)², below 1e-4 relative). The chord turns with the beam, so the angle does
    not matter."""
    F, L, angle = 0.05, 200.0, 0.6
    res = ml.static(_pinned_beam(F, angle), t=1.0, steps=4)
    s = res.summary()
    assert "static equilibrium path of 4 load steps up to t=1" in s and "steps of" not in s
    assert "Phi'" not in s and "in model units" in s
    assert "static equilibrium path" in repr(res)
    I = 10.0 * 4.0**3 / 12.0
    w = res.chord_deflection("beam")
    assert w.shape == (5, 9)
    assert w[-1, 4] == pytest.approx(-F * L**3 / (48 * E_AL * I), rel=1e-4)
    assert w[0] == pytest.approx(np.zeros(9), abs=1e-12)
    assert abs(w[-1, 0]) < 1e-12 and abs(w[-1, -1]) < 1e-12
    # linear in the load along the path: w(t=0.5) is half of w(t=1)
    assert w[2, 4] == pytest.approx(0.5 * w[-1, 4], rel=1e-4)


def test_magnify_scales_the_drawn_deformation(run):
    """A beam drawn with magnify=k lies at frame + k·(deformed - frame), the frame shape being
    the one drawn with magnify=0 (positions are linear in the nodal deformation: exact up to
    round-off of 60 mm coordinates); magnify=1 draws the computed positions."""
    import matplotlib

    matplotlib.use("Agg")
    from morphlab import plots

    def drawn(k):
        ax = plots.snapshots(run, times=[run.t[-1]], magnify=k).axes[0]
        (ln,) = [ln for ln in ax.get_lines() if ln.get_gid() == "snapshot:0:coupler"]
        return ln.get_xydata()

    true, frame = drawn(1.0), drawn(0.0)
    assert np.array_equal(true, run.node_positions("coupler")[-1])
    assert np.max(np.abs(true - frame)) > 1e-3  # the beam does deform
    assert np.allclose(drawn(25.0), frame + 25.0 * (true - frame), rtol=0, atol=1e-11)
    # the rigid frame shape: a straight coupler (its chord deflection is zero)
    d = frame[-1] - frame[0]
    assert np.allclose(d[0] * (frame[:, 1] - frame[0, 1]) - d[1] * (frame[:, 0] - frame[0, 0]),
                       0.0, atol=1e-10)
    with pytest.raises(ModelError, match="magnify"):
        plots.snapshots(run, magnify=-1.0)
