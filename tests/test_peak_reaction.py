"""ml.responses.peak_reaction: the peak over a run of a joint's reaction (a KS aggregate of a
force component, the force's magnitude or the moment), complex-safe and with a vjp, so its
gradient comes by the direct, the adjoint and the complex-step method alike."""

import numpy as np
import pytest
from models import check_method_by_complex_step, inclined_slider_crank

import morphlab as ml

rs = ml.responses


def slider_crank(p):
    """The shared slider-crank (``models.inclined_slider_crank``): rod 60 mm, crank at 0.4 rad,
    driven from rest to 40 rad/s, rod inertia 60 t mm²."""
    return inclined_slider_crank(p, length=60.0, th0=0.4, speed=40.0, rod_inertia=60.0,
                                 name="slider-crank")


P0 = {"alpha": 0.3, "m": 4e-4, "r": 25.0}
RUN = dict(t_end=0.04, dt=1e-3, tol=1e-12)
RESPONSES = {
    "guide normal": rs.peak_reaction("guide", 1, frame="slider"),  # |N|, scale-free KS
    "motor torque": rs.peak_reaction("motor", 2, rho=1.0),  # absolute rho [1/(N mm)]
    "pin force": rs.peak_reaction("B"),  # sqrt(Fx^2 + Fy^2)
    "pin late": rs.peak_reaction("A", "magnitude", frame="crank", times=slice(10, None)),
}


@pytest.mark.parametrize("method", ["direct", "adjoint"])
def test_peak_reaction_gradients_match_whole_run_complex_step(method):
    """Through the guide angle (which turns the slide row's normal: data u0), the slider
    mass and the crank radius; both exact, so they agree to the Newton tolerance's residue
    (1e-8 of the largest gradient; observed ~1e-14)."""
    got = check_method_by_complex_step(slider_crank, P0, RESPONSES, method, RUN)
    assert got.method == method


def test_peak_reaction_bounds_the_peak_of_the_history():
    """max |value| <= KS <= max |value| + s ln(2N)/rho_rel (s the RMS) for the scale-free form,
    + ln(2N)/rho for the absolute one, against the reactions read off the result."""
    res = ml.simulate(slider_crank(P0), **RUN)
    N = res.reaction("guide", frame="slider")[:, 1]
    T = res.drive_torque("motor")
    F = res.reaction("B")
    mag = np.hypot(F[:, 0], F[:, 1])
    late = res.reaction("A", frame="crank")[10:]
    late = np.hypot(late[:, 0], late[:, 1])
    for fn, v in ((RESPONSES["guide normal"], N), (RESPONSES["pin force"], mag),
                  (RESPONSES["pin late"], late)):
        peak, s = np.max(np.abs(v)), np.sqrt(np.mean(v * v))
        assert peak <= fn(res) <= peak + s * np.log(2 * v.size) / 100.0
    peak = np.max(np.abs(T))
    assert peak <= RESPONSES["motor torque"](res) <= peak + np.log(2 * T.size) / 1.0


def test_peak_reaction_refuses_bad_arguments():
    for bad in (3, "Fz", True):
        with pytest.raises(ml.ModelError, match="component must be 0"):
            rs.peak_reaction("guide", bad)
    with pytest.raises(ml.ModelError, match="rho must be a positive"):
        rs.peak_reaction("guide", rho=0.0)
    res = ml.simulate(slider_crank(P0), **RUN)
    with pytest.raises(ml.ModelError, match="no joint 'nope'"):
        rs.peak_reaction("nope")(res)
    with pytest.raises(ml.ModelError, match="no times to aggregate"):
        rs.peak_reaction("guide", times=slice(100, None))(res)
