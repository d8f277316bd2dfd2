"""Random variables (morphlab.studies.distributions) and the samplers over them.

* The Nataf transform against closed forms: lognormal marginals, whose Pearson correlation
  under a Gaussian copula of correlation r0 is ``(exp(r0 s1 s2) - 1) / sqrt((exp(s1²) - 1)
  (exp(s2²) - 1))``; normal marginals (Pearson = copula correlation); Spearman ->
  ``2 sin(π ρ_S / 6)``.
* The transform and its Jacobian: round trip, and the Jacobian against central differences.
* Samplers: each marginal passes a Kolmogorov–Smirnov test; stratified samplers (Latin
  hypercube with and without Iman–Conover pairing, Sobol' without copula mixing) keep the KS
  distance below 1/n, which only one sample per stratum guarantees; a correlated Latin
  hypercube reproduces its target rank correlation far closer than random pairing can.
"""

import math

import numpy as np
import pytest
from scipy import stats

from morphlab import studies
from morphlab.studies import JointDistribution, StudyError, normal, uniform

MARGINALS = {"t": stats.norm(2.0, 0.05), "E": stats.lognorm(0.1, scale=70000.0),
             "M": stats.gumbel_r(1.0e4, 300.0), "x": stats.uniform(101.0, 2.0)}
RANK = np.array([[1.0, 0.6, -0.3, 0.0],
                 [0.6, 1.0, 0.2, 0.1],
                 [-0.3, 0.2, 1.0, 0.4],
                 [0.0, 0.1, 0.4, 1.0]])


def lognormal_pearson(r0, s1, s2):
    return (math.exp(r0 * s1 * s2) - 1.0) / math.sqrt((math.exp(s1**2) - 1.0)
                                                      * (math.exp(s2**2) - 1.0))


def test_nataf_correlation_of_lognormals_is_the_closed_form():
    s1, s2, rho = 0.5, 0.8, 0.6
    J = JointDistribution({"a": stats.lognorm(s1, scale=1.0), "b": stats.lognorm(s2, scale=2.0)},
                          correlation=[[1.0, rho], [rho, 1.0]])
    r0 = J.copula_correlation[0, 1]
    exact = math.log(1.0 + rho * math.sqrt((math.exp(s1**2) - 1) * (math.exp(s2**2) - 1))) \
        / (s1 * s2)
    # 48-point Gauss-Hermite quadrature of an entire integrand and Brent to 1e-14: round-off
    assert r0 == pytest.approx(exact, abs=1e-12)
    assert lognormal_pearson(r0, s1, s2) == pytest.approx(rho, abs=1e-12)
    C = J.covariance()
    assert C[0, 1] / math.sqrt(C[0, 0] * C[1, 1]) == pytest.approx(rho, abs=1e-12)


def test_normal_and_rank_correlations_map_to_the_copula_exactly():
    R = [[1.0, -0.45], [-0.45, 1.0]]
    J = JointDistribution({"a": normal(0.0, 2.0), "b": stats.norm(5.0, 0.1)}, correlation=R)
    assert J.copula_correlation[0, 1] == pytest.approx(-0.45, abs=1e-12)
    K = JointDistribution({"a": normal(0.0, 2.0), "b": uniform(0.0, 1.0)},
                          rank_correlation={("a", "b"): 0.5})
    assert K.copula_correlation[0, 1] == 2.0 * math.sin(math.pi * 0.5 / 6.0)


def test_transform_round_trip_and_jacobian():
    J = JointDistribution(MARGINALS, rank_correlation=RANK)
    rng = np.random.default_rng(3)
    u = rng.standard_normal((50, 4)) * 1.5
    x = J.from_standard(u)
    # inverse CDFs of the lower and upper tails: round trip to 1e-9 (the uniform's sf)
    np.testing.assert_allclose(J.to_standard(x), u, atol=1e-8)
    u0 = u[7]
    jac = J.jacobian(u0)
    h = 1e-6  # central differences: truncation ~h² |x'''| and round-off ~1e-16 |x| / h
    for j in range(4):
        e = np.zeros(4)
        e[j] = h
        col = (J.from_standard(u0 + e)[0] - J.from_standard(u0 - e)[0]) / (2 * h)
        tol = 1e-6 * np.abs(col) + 1e-9 * np.abs(x[7])  # 1e-9 |x|: 10 x the round-off
        assert np.all(np.abs(jac[:, j] - col) <= tol), (j, jac[:, j], col)


@pytest.mark.parametrize("method", ["lhs", "sobol", "halton", "mc"])
def test_marginals_pass_a_kolmogorov_smirnov_test(method):
    J = JointDistribution(MARGINALS, rank_correlation=RANK)
    n = 1024
    x = studies.sample(J, n, method, seed=5)
    for name, dist in zip(J.names, J.marginals):
        ks = stats.kstest(x[name], dist.cdf)
        # a fixed seed: the p-value of a correct mapping is uniform on (0, 1); 0.01 fails a
        # wrong scale or location (e.g. a 5 % error of the std gives D ~ 0.02, p < 1e-3)
        assert ks.pvalue > 0.01, (method, name, ks)
        if method == "lhs":  # Iman-Conover re-pairs whole strata: one sample in each
            assert ks.statistic <= 1.0 / n, (name, ks.statistic)


@pytest.mark.parametrize("sampler", [studies.latin_hypercube, studies.sobol])
def test_stratified_marginals_of_independent_variables(sampler):
    J = JointDistribution(MARGINALS)
    n = 256
    x = sampler(J, n, seed=2)
    for name, dist in zip(J.names, J.marginals):
        # one point in each of the n strata of probability: |F_n - F| < 1/n everywhere
        assert stats.kstest(x[name], dist.cdf).statistic <= 1.0 / n, name


def test_correlated_latin_hypercube_reproduces_the_rank_correlation():
    J = JointDistribution(MARGINALS, rank_correlation=RANK)
    n = 1000
    worst_ic, worst_mc = [], []
    for seed in range(5):
        x = np.stack(list(studies.latin_hypercube(J, n, seed=seed).values()), axis=1)
        worst_ic.append(np.max(np.abs(stats.spearmanr(x).statistic - RANK)))
        y = np.stack(list(studies.monte_carlo(J, n, seed=seed).values()), axis=1)
        worst_mc.append(np.max(np.abs(stats.spearmanr(y).statistic - RANK)))
    # random pairing (Monte Carlo through the copula): a sample Spearman coefficient has a
    # standard error of about (1 - ρ²) / sqrt(n) ~ 0.03; its largest of 6 entries must stay
    # within 4 of them (and the copula has no bias)
    assert max(worst_mc) < 4 * 1.0 / math.sqrt(n)
    # Iman-Conover with its corrections: within 1e-3 (measured 2e-5 to 5e-5 at n = 1000)
    assert max(worst_ic) < 1e-3


def test_iman_conover_pairing_or_copula_on_request():
    J = JointDistribution(MARGINALS, rank_correlation=RANK)
    a = studies.latin_hypercube(J, 200, seed=1, pairing="copula")
    b = studies.latin_hypercube(J, 200, seed=1)
    assert not np.array_equal(a["E"], b["E"])
    # the copula mixes the strata of the correlated variables; t is the first (L's row 1)
    assert stats.kstest(a["t"], J.marginals[0].cdf).statistic <= 1.0 / 200


def test_bounds_mixed_with_distributions():
    x = studies.latin_hypercube({"a": (0.0, 2.0), "b": stats.norm(1.0, 0.1)}, 64, seed=0)
    assert np.all((x["a"] >= 0.0) & (x["a"] <= 2.0))
    assert stats.kstest(x["b"], stats.norm(1.0, 0.1).cdf).statistic <= 1.0 / 64
    # plain bounds keep the historical mapping low + unit (high - low), bitwise
    np.testing.assert_array_equal(studies.halton({"a": (0.0, 2.0)}, 8, seed=1)["a"],
                                  0.0 + studies.halton({"a": (0.0, 1.0)}, 8, seed=1)["a"] * 2.0)


@pytest.mark.parametrize("call, match", [
    (lambda: JointDistribution({}), "non-empty"),
    (lambda: JointDistribution({"a": 3.0}), "SciPy frozen"),
    (lambda: JointDistribution({"a": normal(0, 1), "b": normal(0, 1)},
                               correlation=[[1, 0.5], [0.5, 1]],
                               rank_correlation=[[1, 0.5], [0.5, 1]]), "at most one"),
    (lambda: JointDistribution({"a": normal(0, 1), "b": normal(0, 1)},
                               correlation=[[1, 0.5], [0.4, 1]]), "symmetric"),
    (lambda: JointDistribution({"a": normal(0, 1), "b": normal(0, 1)},
                               copula_correlation={("a", "c"): 0.5}), "pairs of two"),
    (lambda: JointDistribution({"a": stats.lognorm(1.5), "b": stats.lognorm(1.5)},
                               correlation={("a", "b"): -0.9}), "cannot be reached"),
    (lambda: JointDistribution({"a": normal(0, 1), "b": normal(0, 1), "c": normal(0, 1)},
                               copula_correlation=[[1, .9, .9], [.9, 1, -.9], [.9, -.9, 1]]),
     "not positive definite"),
    (lambda: studies.sobol({"a": normal(0, 1)}, 8, scramble=False), "scramble=True"),
    (lambda: studies.latin_hypercube({"a": normal(0, 1)}, 8, pairing="x"), "pairing"),
    (lambda: studies.sample({"a": normal(0, 1)}, 8, "grid"), "method must be"),
    (lambda: studies.latin_hypercube(JointDistribution(MARGINALS, rank_correlation=RANK), 5),
     "more samples"),
])
def test_bad_input_is_a_typed_error(call, match):
    with pytest.raises(StudyError, match=match):
        call()
