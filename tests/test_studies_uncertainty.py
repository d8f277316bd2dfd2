"""First-order second-moment propagation (morphlab.studies.uncertainty).

* Linear responses: FOSM is exact, so its standard deviations and covariance must equal the
  hand computation ``sum_ij g_i g_j C_ij`` (done here in exact rational arithmetic) to
  round-off, for independent inputs and for a full covariance.
* Exceedance probabilities: the normal formula ``Phi((mu - limit) / sigma)``, evaluated here
  with ``math.erfc``.
* A nonlinear simulation response (tip deflection ~ F / t³ and KS stress of a cantilever)
  under 1 % input scatter against a serial Monte Carlo run of the same model.
* ``linearization_check`` on quadratics, where the second-order ratio is known exactly.
"""

import math
from fractions import Fraction

import numpy as np
import pytest
from models import tip_loaded_cantilever

import morphlab as ml
from morphlab.studies import (
    UncertaintyResult,
    axis_perturbations,
    exceedance,
    fosm,
    linearization_check,
)

# two responses linear in (a, b, c): r1 = 3 + 2a - b + c/2, r2 = -1 + 4b + c
VALUES = {"r1": 3.0, "r2": -1.0}
GRADS = {"r1": {"a": 2.0, "b": -1.0, "c": 0.5}, "r2": {"a": 0.0, "b": 4.0, "c": 1.0}}
COV = [[Fraction(1, 100), Fraction(1, 200), 0],
       [Fraction(1, 200), Fraction(4, 100), Fraction(-3, 100)],
       [0, Fraction(-3, 100), Fraction(9, 100)]]  # symmetric positive definite


def exact_cov(cov):
    """Response covariance sum_ij g_i g_j C_ij in rational arithmetic."""
    names = ("a", "b", "c")
    g = {k: [Fraction(GRADS[k][v]) for v in names] for k in GRADS}
    return {(k, m): sum(g[k][i] * g[m][j] * cov[i][j] for i in range(3) for j in range(3))
            for k in GRADS for m in GRADS}


def phi(z):
    return 0.5 * math.erfc(-z / math.sqrt(2.0))


def test_linear_response_independent_inputs_exact():
    std = {"a": 0.1, "b": 0.2, "c": 0.3}
    res = fosm((VALUES, GRADS), std=std)
    diag = [[Fraction(0)] * 3 for _ in range(3)]
    for i, s in enumerate((Fraction(1, 10), Fraction(2, 10), Fraction(3, 10))):
        diag[i][i] = s * s
    ref = exact_cov(diag)  # var r1 = 0.1025, var r2 = 0.73, cov = -0.115
    assert res.mean == VALUES
    for k in ("r1", "r2"):
        assert res.std[k] == pytest.approx(math.sqrt(ref[k, k]), rel=4e-16)  # round-off
    assert res.cov[0, 1] == pytest.approx(float(ref["r1", "r2"]), rel=4e-16)
    assert res.correlation()[0, 1] == pytest.approx(
        float(ref["r1", "r2"]) / math.sqrt(ref["r1", "r1"] * ref["r2", "r2"]), rel=1e-15)


def test_linear_response_full_covariance_exact():
    res = fosm((VALUES, GRADS), cov=np.array(COV, dtype=float), variables=["a", "b", "c"])
    ref = exact_cov(COV)
    for i, k in enumerate(("r1", "r2")):
        for j, m in enumerate(("r1", "r2")):
            assert res.cov[i, j] == pytest.approx(float(ref[k, m]), rel=1e-15, abs=1e-16)
    assert res.std["r2"] == pytest.approx(math.sqrt(ref["r2", "r2"]), rel=4e-16)


def test_exceedance_is_the_normal_cdf_formula():
    res = fosm((VALUES, GRADS), std={"a": 0.1, "b": 0.2, "c": 0.3},
               allowables={"r1": (2.5, 3.4), "r2": (None, -0.2)})
    s1, s2 = res.std["r1"], res.std["r2"]
    below, above = res.p_sides["r1"]
    assert below == pytest.approx(phi((2.5 - 3.0) / s1), rel=1e-13)
    assert above == pytest.approx(phi((3.0 - 3.4) / s1), rel=1e-13)
    assert res.p_exceed["r1"] == pytest.approx(below + above, rel=1e-15)
    assert res.p_sides["r2"][0] == 0.0
    assert res.p_exceed["r2"] == pytest.approx(phi((-1.0 + 0.2) / s2), rel=1e-13)
    # deep tails stay accurate (ndtr, not 1 - cdf): 8 sigma
    assert exceedance(0.0, 1.0, None, 8.0)[1] == pytest.approx(6.220960574271785e-16,
                                                               rel=1e-12)
    # a response without scatter is either inside (0) or outside (1)
    assert exceedance(1.0, 0.0, 0.0, 2.0) == (0.0, 0.0)
    assert exceedance(3.0, 0.0, 0.0, 2.0) == (0.0, 1.0)
    text = repr(res)
    assert "r1" in text and f"{res.p_exceed['r1']:.3e}" in text


def test_linearization_check_on_quadratics():
    # f = 2 t + 3 t² (ratio |b| d / |a| = 1.5 d), g = -t linear, h = t² (no first-order term)
    def vals(t):
        return {"f": 2 * t + 3 * t * t, "g": -t, "h": t * t}

    grads = {"f": {"t": 2.0}, "g": {"t": -1.0}, "h": {"t": 0.0}}
    deltas = axis_perturbations({"t": 0.1}, k=2.0)
    assert deltas == [{"t": pytest.approx(0.2)}]
    chk = linearization_check((vals(0.0), grads), deltas, [vals(0.2)], [vals(-0.2)])
    assert chk.ratio["f"][0] == pytest.approx(1.5 * 0.2, rel=1e-14)
    assert chk.ratio["g"][0] == 0.0
    assert chk.ratio["h"][0] == np.inf
    assert chk.worst()["f"] == chk.ratio["f"][0]
    assert chk.first_order["f"][0] == pytest.approx(0.4, rel=1e-15)


@pytest.mark.parametrize("kwargs, match", [
    ({"std": {"a": 0.1}, "cov": np.eye(1)}, "exactly one"),
    ({}, "exactly one"),
    ({"std": {"a": -0.1}}, ">= 0"),
    ({"std": {"z": 0.1}}, r"no gradients with respect to \['z'\]"),
    ({"cov": np.eye(2)}, r"\(3, 3\)"),
    ({"cov": np.array([[1.0, 0.5, 0], [0.0, 1, 0], [0, 0, 1]])}, "symmetric"),
    ({"cov": np.diag([1.0, -1.0, 1.0])}, "positive semi-definite"),
    ({"std": {"a": 0.1}, "allowables": {"r3": (0, 1)}}, "unknown response 'r3'"),
    ({"std": {"a": 0.1}, "allowables": {"r1": (2, 1)}}, "lower 2.0 > upper 1.0"),
])
def test_bad_input_is_a_typed_error(kwargs, match):
    with pytest.raises(ml.SensitivityError, match=match):
        fosm((VALUES, GRADS), **kwargs)


# ---------------------------------------------------------------- against Monte Carlo
SETTINGS = {"t_end": 0.012, "dt": 2.5e-4}
NOMINAL = {"t": 2.0, "F": 1.0}  # mm, N
STD = {"t": 0.02, "F": 0.01}  # 1 % scatter of each
N_MC = 400
RESPONSES = {"tip": ml.responses.point_displacement("beam", (100.0, 0.0), 1),
             "stress": ml.responses.ks_max_stress("beam", 2.0)}


def run_values(p):
    res = ml.simulate(tip_loaded_cantilever(p), **SETTINGS)
    return {k: float(np.real(f(res))) for k, f in RESPONSES.items()}


@pytest.mark.slow
def test_fosm_matches_monte_carlo_on_a_nonlinear_simulation():
    sens = ml.sensitivities(tip_loaded_cantilever, NOMINAL, RESPONSES, **SETTINGS)
    res = fosm(sens, std=STD, allowables={"stress": (None, 27.0)})
    assert isinstance(res, UncertaintyResult) and res.mean == sens.values
    rng = np.random.default_rng(20240522)
    sample = {v: NOMINAL[v] + STD[v] * rng.standard_normal(N_MC) for v in STD}
    mc = {k: np.empty(N_MC) for k in RESPONSES}
    for i in range(N_MC):
        vals = run_values({v: float(sample[v][i]) for v in STD})
        for k in RESPONSES:
            mc[k][i] = vals[k]
    # how far from linear over +-1 sigma (second-order term / first-order term)
    deltas = axis_perturbations(STD)
    plus = [run_values({v: NOMINAL[v] + d.get(v, 0.0) for v in NOMINAL}) for d in deltas]
    minus = [run_values({v: NOMINAL[v] - d.get(v, 0.0) for v in NOMINAL}) for d in deltas]
    rho = linearization_check(sens, deltas, plus, minus).worst()
    for k in RESPONSES:
        sigma = res.std[k]
        s_mc = np.std(mc[k], ddof=1)
        assert rho[k] < 0.05  # 1 % scatter: F/t³ curves by 2 sigma_t / t = 2 % per sigma
        # standard error of a sample std of N normal values: sigma / sqrt(2 (N - 1)) (3.5 %);
        # 3 of them (a fixed seed: the test is deterministic; 3 SE keeps it meaningful)
        assert abs(s_mc - sigma) < 3 * sigma / math.sqrt(2 * (N_MC - 1)), k
        # the sample mean: standard error sigma / sqrt(N) plus the second-order mean shift
        # of about rho sigma (linearization_check docstring)
        assert abs(np.mean(mc[k]) - res.mean[k]) < 3 * sigma / math.sqrt(N_MC) \
            + 2 * rho[k] * sigma, k
        # sharper, sample for sample: the linearised response on the same draws differs from
        # the simulations by the nonlinearity alone, so the two sample stds agree to about
        # rho² + 2 sqrt(2) rho / sqrt(N) (the quadratic remainder's own spread and its
        # sample correlation with the linear part); assert 3 x that
        g = np.array([sens.gradients[k][v] for v in STD])
        lin = res.mean[k] + g @ np.array([sample[v] - NOMINAL[v] for v in STD])
        s_lin = np.std(lin, ddof=1)
        bound = rho[k] ** 2 + 2 * math.sqrt(2) * rho[k] / math.sqrt(N_MC)
        assert abs(s_mc / s_lin - 1.0) < 3 * bound, k
    # exceedance of a stress allowable: normal approximation against the sample frequency
    # (binomial standard error sqrt(p (1 - p) / N), 4 of them)
    p = res.p_exceed["stress"]
    freq = float(np.mean(mc["stress"] > 27.0))
    assert abs(freq - p) < 4 * math.sqrt(p * (1 - p) / N_MC) + 1.0 / N_MC
