"""Samplers of design tables (morphlab.studies.samplers): bounds, seeds, the defining property
of each (one sample per stratum, low discrepancy, the moments of the distributions)."""

import numpy as np
import pytest

from morphlab.studies import (
    StudyError,
    correlated_normal,
    full_factorial,
    halton,
    latin_hypercube,
    monte_carlo,
    normal,
    sobol,
    uniform,
)

BOUNDS = {"x_A": (101.0, 103.0), "M_t": (9.0e3, 1.1e4), "t_w": (1.5, 2.5)}
SPACE_FILLING = [latin_hypercube, sobol, halton]


@pytest.mark.parametrize("sampler", SPACE_FILLING)
def test_samples_lie_within_the_bounds_and_follow_the_seed(sampler):
    a = sampler(BOUNDS, 64, seed=7)
    assert list(a) == list(BOUNDS)
    for name, (low, high) in BOUNDS.items():
        assert a[name].shape == (64,)
        assert np.all((a[name] >= low) & (a[name] <= high)), name
    b, c = sampler(BOUNDS, 64, seed=7), sampler(BOUNDS, 64, seed=8)
    assert all(np.array_equal(a[k], b[k]) for k in BOUNDS)
    assert not any(np.array_equal(a[k], c[k]) for k in BOUNDS)


def test_latin_hypercube_puts_one_sample_in_each_stratum():
    n = 50
    x = latin_hypercube(BOUNDS, n, seed=3)
    for name, (low, high) in BOUNDS.items():
        strata = np.floor((x[name] - low) / (high - low) * n).astype(int)
        assert sorted(strata) == list(range(n)), name


def _unit(sample):
    names = list(BOUNDS)
    lo = np.array([BOUNDS[k][0] for k in names])
    hi = np.array([BOUNDS[k][1] for k in names])
    return (np.stack([sample[k] for k in names], axis=1) - lo) / (hi - lo)


@pytest.mark.parametrize("sampler", [sobol, halton])
def test_low_discrepancy_beats_the_best_of_twenty_random_sets(sampler):
    """Centred L2 discrepancy: random points have an expected squared discrepancy ~1/n, a
    low-discrepancy sequence ~(log n)^d / n^2, so at n = 128 in 3 dimensions it must beat even
    the best of 20 random sets."""
    from scipy.stats import qmc

    rng = np.random.default_rng(0)
    best_random = min(qmc.discrepancy(rng.random((128, 3))) for _ in range(20))
    assert qmc.discrepancy(_unit(sampler(BOUNDS, 128, seed=1))) < best_random


def test_sobol_needs_a_power_of_two():
    with pytest.raises(StudyError, match="n=100: use 64 or 128"):
        sobol(BOUNDS, 100)
    assert len(sobol(BOUNDS, 1)["x_A"]) == 1


def test_full_factorial_is_every_combination_first_variable_slowest():
    g = full_factorial({"a": [1.0, 2.0], "b": [10.0, 20.0, 30.0]})
    np.testing.assert_array_equal(g["a"], [1, 1, 1, 2, 2, 2])
    np.testing.assert_array_equal(g["b"], [10, 20, 30, 10, 20, 30])
    h = full_factorial({"x_A": (101.0, 103.0), "M_t": (9e3, 1.1e4)}, levels={"x_A": 3, "M_t": 2})
    np.testing.assert_array_equal(h["x_A"], [101, 101, 102, 102, 103, 103])
    np.testing.assert_array_equal(h["M_t"], [9e3, 1.1e4] * 3)
    assert len(full_factorial(BOUNDS, levels=4)["t_w"]) == 64


N_MC = 4000


def test_monte_carlo_moments_within_four_standard_errors():
    """Sample mean: standard error s/sqrt(n). Sample variance: standard error
    sqrt((mu4 - s^4)/n), mu4 = 3 s^4 for a normal, (b - a)^4/80 for a uniform on [a, b]
    (variance (b - a)^2/12). An exponential of scale 2 (SciPy): mean 2, standard deviation 2."""
    from scipy import stats

    x = monte_carlo({"n": normal(5.0, 0.5), "u": uniform(-1.0, 3.0),
                     "e": stats.expon(scale=2.0)}, N_MC, seed=11)
    n = N_MC
    checks = [  # (sample value, expected, standard error)
        (x["n"].mean(), 5.0, 0.5 / np.sqrt(n)),
        (x["n"].var(ddof=1), 0.25, np.sqrt(2.0 * 0.5**4 / n)),
        (x["u"].mean(), 1.0, np.sqrt(16.0 / 12.0 / n)),
        (x["u"].var(ddof=1), 16.0 / 12.0, np.sqrt((4.0**4 / 80.0 - (16.0 / 12.0) ** 2) / n)),
        (x["e"].mean(), 2.0, 2.0 / np.sqrt(n)),
    ]
    for value, expected, se in checks:
        assert abs(value - expected) < 4.0 * se, (value, expected, se)
    assert x["u"].min() >= -1.0 and x["u"].max() < 3.0


def test_correlated_normal_covariance():
    """Sample covariance of a normal pair: Var(s_ij) = (c_ij^2 + c_ii c_jj)/n."""
    cov = np.array([[4.0, 1.2], [1.2, 1.0]])
    x = monte_carlo({("x_A", "y_A"): correlated_normal([102.0, -0.25], cov),
                     "M_t": normal(1e4, 100.0)}, N_MC, seed=5)
    assert list(x) == ["x_A", "y_A", "M_t"]
    sample = np.stack([x["x_A"], x["y_A"]])
    np.testing.assert_array_less(np.abs(sample.mean(axis=1) - [102.0, -0.25]),
                                 4.0 * np.sqrt(np.diag(cov) / N_MC))
    se = np.sqrt((cov**2 + np.outer(np.diag(cov), np.diag(cov))) / N_MC)
    np.testing.assert_array_less(np.abs(np.cov(sample) - cov), 4.0 * se)
    # independent entries: the correlation with M_t is zero within 4/sqrt(n)
    assert abs(np.corrcoef(x["x_A"], x["M_t"])[0, 1]) < 4.0 / np.sqrt(N_MC)


@pytest.mark.parametrize("call, match", [
    (lambda: latin_hypercube({"a": (1.0, 1.0)}, 4), "low < high"),
    (lambda: latin_hypercube({"a": 3.0}, 4), r"\(low, high\)"),
    (lambda: halton(BOUNDS, 0), "positive integer"),
    (lambda: normal(0.0, -1.0), "std > 0"),
    (lambda: uniform(2.0, 1.0), "low < high"),
    (lambda: correlated_normal([0.0, 0.0], [[1.0, 2.0], [2.0, 1.0]]), "positive definite"),
    (lambda: monte_carlo({"a": correlated_normal([0.0, 0.0], np.eye(2))}, 4), "tuple of d"),
    (lambda: monte_carlo({"a": 3.0}, 4), "SciPy frozen distribution"),
    (lambda: full_factorial({"a": []}), "non-empty sequence"),
])
def test_bad_input(call, match):
    with pytest.raises(StudyError, match=match):
        call()
