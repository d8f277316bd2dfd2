"""Response functions: KS bounds, complex-step safety, gradients on a small model, and the
errors :func:`morphlab.sensitivities` raises for unusable input.

References: the Kreisselmeier–Steinhauser bounds max(v) <= KS(v) <= max(v) + ln(N)/rho
(Kreisselmeier & Steinhauser 1979; e.g. Martins & Ning, Engineering Design Optimization, 2021,
§5.7); central differences for the complex-step derivatives of the responses; the chain rule
through the stress and node-position sensitivities for the KS and RMS gradients; the
whole-run complex step for everything on the model.
"""

import warnings

import numpy as np
import pytest

import morphlab as ml

R = ml.responses
RUN = dict(t_end=0.02, dt=1e-3)  # 20 steps, ~2.5 periods of the cantilever's first mode


def cantilever(p, n_elem=3):
    """Aluminium strip clamped at the origin, length L [mm] along x, tip force ramped in 5 ms;
    variables: thickness t [mm], tip force F [N], length L (moves every node)."""
    m = ml.Model(name="cantilever")
    s = np.linspace(0.0, 1.0, n_elem + 1)
    nodes = np.stack([s * p["L"], 0.0 * s], axis=1)
    beam = m.add_beam(nodes, E=70000.0, rho=2.7e-9, thickness=p["t"], width=10.0,
                      damping=1e-4, name="strip")
    m.add_fix(beam, at=(0.0, 0.0), dofs="xyr", name="clamp")
    m.add_force(beam, at=nodes[-1], force=(0.2 * p["F"], -p["F"]),
                profile=ml.SmoothStep(0.0, 0.005), name="F")
    return m


P0 = {"t": 1.0, "F": 0.5, "L": 80.0}
# a fixed target shape: a parabola of 3 mm tip drop over the nominal span (nodes at x = 0..80)
TARGET = np.stack([np.linspace(0.0, 80.0, 4), -3.0 * np.linspace(0.0, 1.0, 4) ** 2], axis=1)
RHO_KS = 0.5  # 1/MPa


@pytest.fixture(scope="module")
def pair():
    resp = {"ks": R.ks_max_stress("strip", RHO_KS), "rms": R.rms_error("strip", TARGET),
            "max_error": R.max_error("strip", TARGET)}
    direct = ml.sensitivities(cantilever, P0, resp, method="direct", **RUN)
    ref = ml.sensitivities(cantilever, P0, resp, method="complex-step", **RUN)
    return direct, ref


# ---------------------------------------------------------------- gradients on the small model
def test_ks_and_rms_gradients_match_complex_step(pair):
    """All entries are strong here (no cancellation), so plain relative agreement; measured
    <= 4e-14. 1e-8 is the project's accuracy goal for the direct method."""
    direct, ref = pair
    for r, g in ref.gradients.items():
        for v in P0:
            assert g[v] != 0.0
            assert abs(direct.gradients[r][v] / g[v] - 1.0) < 1e-8, (r, v)


def test_ks_gradient_is_the_softmax_weighted_stress_gradient(pair):
    """Chain rule by hand: dKS/dp = sum_j w_j dv_j/dp over v = (sigma, -sigma) with softmax
    weights w = exp(rho v) / sum exp(rho v), from the stress sensitivity history. Independent of
    the response's complex step; both use the same state sensitivities, so round-off only."""
    direct, _ = pair
    sigma = direct.result.stress("strip").ravel()
    dsigma = direct.stress("strip").reshape(sigma.size, -1)  # (N, n_x)
    v = np.concatenate([sigma, -sigma])
    dv = np.concatenate([dsigma, -dsigma])
    w = np.exp(RHO_KS * (v - v.max()))
    w /= w.sum()
    by_hand = w @ dv
    for k, name in enumerate(direct.variables):
        assert by_hand[k] == pytest.approx(direct.gradients["ks"][name], rel=1e-10)


def test_rms_gradient_by_the_chain_rule(pair):
    """d rms/dp = sum_k (x_k - T_k) . dx_k/dp / (N rms), from the node-position sensitivities
    at the final time. The clamped root node sits on its target (zero error): the response,
    written as sqrt(mean(e²)) with e = sqrt(d.d), must still give the smooth gradient there."""
    direct, _ = pair
    x = direct.result.node_positions("strip")[-1]
    dx = direct.node_positions("strip")[-1]  # (n_nodes, 2, n_x)
    d = x - TARGET
    e = np.sqrt(np.sum(d * d, axis=1))
    assert e[0] < 1e-12  # the root node on its target
    rms = np.sqrt(np.mean(e * e))
    assert rms == pytest.approx(direct.values["rms"], rel=1e-14)
    by_hand = np.einsum("kc,kcx->x", d, dx) / (e.size * rms)
    k_max = int(np.argmax(e))
    de_max = d[k_max] @ dx[k_max] / e[k_max]
    for k, name in enumerate(direct.variables):
        assert by_hand[k] == pytest.approx(direct.gradients["rms"][name], rel=1e-10)
        # max_error: the derivative of the largest node error (unique maximiser here)
        assert de_max[k] == pytest.approx(direct.gradients["max_error"][name], rel=1e-10)


def test_ks_stress_bounds_on_the_run(pair):
    """max|sigma| <= KS <= max|sigma| + ln(2N)/rho over the N stress values of the run
    (ks_abs aggregates sigma and -sigma, 2N values)."""
    direct, _ = pair
    s = direct.result.stress("strip")
    peak = np.max(np.abs(s))
    ks = direct.values["ks"]
    assert peak > 1.0  # the load does bend the strip (40 MPa peak)
    assert peak <= ks <= peak + np.log(2 * s.size) / RHO_KS


# ---------------------------------------------------------------- KS on arrays
@pytest.mark.parametrize("rho", [0.1, 1.0, 10.0, 100.0])
@pytest.mark.parametrize("n", [1, 7, 1000])
def test_ks_bounds_on_random_arrays(rho, n):
    rng = np.random.default_rng(n)
    v = rng.normal(scale=5.0, size=n)
    ks = R.ks(v, rho)
    assert v.max() <= ks <= v.max() + np.log(n) / rho + 1e-12 * abs(v.max())
    # equal entries attain the upper bound exactly (sum of N equal exponentials)
    assert R.ks(np.full(n, 3.0), rho) == pytest.approx(3.0 + np.log(n) / rho, rel=1e-14)
    # ks_abs is the KS of the magnitudes: bounds with max|v| and 2N values
    ka = R.ks_abs(v, rho)
    assert np.abs(v).max() <= ka <= np.abs(v).max() + np.log(2 * n) / rho + 1e-12


def test_ks_is_shift_safe_against_overflow():
    """exp(rho v) overflows for rho v > 709; the shift by max(v) must keep KS finite."""
    v = np.array([1e3, 999.0, -1e3])
    ks = R.ks(v, 10.0)
    # closed form: 1000 + ln(1 + e^-10 + e^-20000)/10
    assert ks == pytest.approx(1000.0 + np.log1p(np.exp(-10.0)) / 10.0, rel=1e-15)


@pytest.mark.parametrize("imag_scale", [1e-30, 0.3])
def test_ks_of_complex_input_equals_the_complex_formula(imag_scale):
    """Complex input is summed with real exponentials times cos/sin (or, for a complex step's
    tiny imaginary parts, without the trigonometry); it must be the complex number
    ``s + ln(sum exp(rho (v - s))) / rho`` formed with NumPy's complex exp, for both KS forms
    and any layout (a transposed view, as Result.stress returns). The terms are O(1) and
    positive-weighted, so the agreement is round-off: 1e-13 relative on the real part, and
    1e-12 on the imaginary part (imag_scale = 1e-30 carries the derivative, scaled back)."""
    rng = np.random.default_rng(3)
    rho = 0.7
    v = (rng.normal(scale=5.0, size=(6, 4, 5))
         + 1j * imag_scale * rng.normal(size=(6, 4, 5))).transpose(2, 0, 1)

    def formula(vals):
        x = vals.ravel()
        s = np.max(np.real(x))
        return s + np.log(np.sum(np.exp(rho * (x - s)))) / rho

    for got, ref in ((R.ks(v, rho), formula(v)),
                     (R.ks_abs(v, rho), formula(np.concatenate([v.ravel(), -v.ravel()])))):
        assert np.real(got) == pytest.approx(np.real(ref), rel=1e-13)
        assert np.imag(got) / imag_scale == pytest.approx(np.imag(ref) / imag_scale, rel=1e-12)


def test_ks_rejects_bad_input():
    with pytest.raises(ml.ModelError):
        R.ks([], 1.0)
    with pytest.raises(ml.ModelError):
        R.ks([1.0, 2.0], 0.0)


# ---------------------------------------------------------------- complex-step safety
H_CS = 1e-30
EPS = 1e-6  # central difference: truncation ~EPS² f''' ~ 1e-12, round-off ~1e-16/EPS ~ 1e-10


def _cs_and_cd(f, x, d):
    """Complex-step and central-difference directional derivatives of f at x along d."""
    cs = np.imag(f(x + 1j * H_CS * d)) / H_CS
    cd = (f(x + EPS * d) - f(x - EPS * d)) / (2.0 * EPS)
    return cs, cd


FUNCS = {
    "ks": lambda x: R.ks(x, 2.0),
    "ks_abs": lambda x: R.ks_abs(x, 2.0),
    "rms": R.rms,
    "distance": lambda x: R.distance(x.reshape(-1, 2), np.ones((x.size // 2, 2))),
    "max_by_real": R.max_by_real,
}


@pytest.mark.parametrize("name", list(FUNCS))
@pytest.mark.parametrize("seed", [0, 1, 2])
def test_responses_are_complex_safe(name, seed):
    """The complex-step derivative (the imaginary part a response keeps) equals the central
    difference to the latter's accuracy (~1e-10 relative; 1e-7 leaves margin). A response that
    dropped the imaginary part would give 0 here."""
    rng = np.random.default_rng(seed)
    x = rng.normal(size=12)
    d = rng.normal(size=12)
    f = FUNCS[name]
    cs, cd = _cs_and_cd(f, x, d)
    assert np.all(np.abs(cd) > 1e-3)  # a non-trivial direction
    np.testing.assert_allclose(cs, cd, rtol=1e-7, atol=0.0)
    # and the real part is the plain value
    np.testing.assert_allclose(np.real(f(x + 1j * H_CS * d)), f(x), rtol=1e-15, atol=0.0)


# ---------------------------------------------------------------- rejected input
SMALL = dict(t_end=0.005, dt=1e-3)


def _sens(responses, **kw):
    return ml.sensitivities(cantilever, P0, responses, **{**SMALL, **kw})


def tip_y(result):
    return result.node_positions("strip")[-1, -1, 1]


@pytest.mark.parametrize("method", ["direct", "complex-step"])
def test_response_with_abs_is_rejected(method):
    with pytest.raises(ml.SensitivityError, match="complex-safe"):
        _sens({"bad": lambda r: np.abs(tip_y(r))}, method=method)


@pytest.mark.parametrize("method", ["direct", "complex-step"])
def test_response_with_float_is_rejected(method):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", np.exceptions.ComplexWarning)  # numpy's own notice
        with pytest.raises(ml.SensitivityError, match="complex-safe"):
            _sens({"bad": lambda r: float(tip_y(r))}, method=method)


def test_complex_safe_version_is_accepted():
    """The same response written with the library helpers passes (control for the two above);
    the sign of the tip drop is known, so -y is its magnitude."""
    s = _sens({"ok": lambda r: -tip_y(r)}, method="direct", variables=["F"])
    assert s.gradients["ok"]["F"] > 0.0


def test_unknown_method_is_rejected():
    with pytest.raises(ml.SensitivityError, match="unknown method"):
        _sens({"y": tip_y}, method="backward-difference")


def test_variable_not_in_p0_is_rejected():
    with pytest.raises(ml.SensitivityError, match="not in p0"):
        _sens({"y": tip_y}, variables=["t", "E"])


def test_variable_unused_by_build_is_rejected():
    with pytest.raises(ml.SensitivityError, match="not used"):
        ml.sensitivities(cantilever, {**P0, "E": 70000.0}, {"y": tip_y}, **SMALL)


def test_non_scalar_response_is_rejected():
    with pytest.raises(ml.SensitivityError, match="scalar"):
        _sens({"y": lambda r: r.node_positions("strip")[-1, :, 1]}, variables=["F"])


def test_node_positions_at_selected_times_equal_the_full_history(pair):
    """``node_positions(body, times)`` computes only the selected times; the values must be the
    full history's rows bit for bit (same operations per row), for the real result and for a
    complex (perturbed) one."""
    direct, _ = pair
    for res in (direct.result, direct._perturbed[0]):
        full = res.node_positions("strip")
        for sel in (-1, 0, slice(2, 9, 3), np.array([1, 4])):
            np.testing.assert_array_equal(res.node_positions("strip", sel), full[sel])
