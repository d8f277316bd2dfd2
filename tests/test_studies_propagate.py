"""The front door ``propagate`` (morphlab.studies.propagate) and every new study function on
a Dask cluster.

* FOSM through ``propagate`` on a linear function of correlated normals: mean and std are
  the closed forms ``aᵀμ`` and ``sqrt(aᵀ C a)``.
* Monte Carlo of a lognormal product: the exact exceedance probability lies in the
  Clopper–Pearson interval, the exact mean and std in their bootstrap intervals.
* FORM and importance sampling through ``propagate`` agree with ``form`` and
  ``importance_sampling``.
* Every function that evaluates a model runs through ``sweep`` and gives bitwise the same
  result in-process and on a Dask LocalCluster of two worker processes (a simulation task
  with gradients, so worker processes compile or load the kernels and run sensitivities).
"""

import math

import numpy as np
import pytest
from models import tip_loaded_cantilever
from scipy import stats
from scipy.special import ndtr

import morphlab as ml
from morphlab.studies import (
    Constraint,
    FunctionTask,
    JointDistribution,
    Problem,
    SimulationTask,
    StudyError,
    form,
    importance_sampling,
    multistart,
    propagate,
    sobol_indices,
)

A = np.array([2.0, -3.0, 0.5])
MU = np.array([1.0, -2.0, 4.0])
SD = np.array([0.5, 0.3, 1.0])
R = np.array([[1.0, 0.4, 0.0], [0.4, 1.0, -0.3], [0.0, -0.3, 1.0]])


def linear(p):
    x = np.array([p["a"], p["b"], p["c"]])
    return {"r": float(A @ x) + p["k"]}, {"r": {"a": 2.0, "b": -3.0, "c": 0.5, "k": 1.0}}


def normals():
    return JointDistribution({v: stats.norm(m, s) for v, m, s in zip("abc", MU, SD)},
                             correlation=R)


def test_fosm_through_propagate_is_the_closed_form():
    res = propagate(FunctionTask(linear), normals(), "fosm", fixed={"k": 0.5},
                    allowables={"r": (None, 14.0)}, executor="serial")
    C = np.outer(SD, SD) * R
    s = math.sqrt(A @ C @ A)
    assert res.mean["r"] == A @ MU + 0.5
    assert res.std["r"] == pytest.approx(s, rel=1e-14)
    assert res.p_exceed["r"] == pytest.approx(ndtr(-(14.0 - A @ MU - 0.5) / s), rel=1e-12)


def product(p):
    return {"xy": p["x"] * p["y"]}


LOGNORMALS = {"x": stats.lognorm(0.3, scale=2.0), "y": stats.lognorm(0.2, scale=3.0)}


def test_monte_carlo_intervals_hold_the_exact_values():
    # x y is lognormal(ln 6, sqrt(0.13)): mean, std and P(xy < 4) in closed form
    s2 = 0.3**2 + 0.2**2
    mean = 6.0 * math.exp(s2 / 2)
    std = mean * math.sqrt(math.exp(s2) - 1.0)
    p_low = ndtr((math.log(4.0) - math.log(6.0)) / math.sqrt(s2))
    res = propagate(product, LOGNORMALS, "monte-carlo", n=2000, sampling="mc", seed=7,
                    allowables={"xy": (4.0, None)}, executor="serial")
    assert res.n == 2000 and res.failed == 0
    # 95 % intervals and a fixed seed: each holds its exact value (they fail for a wrong
    # mapping of the marginals, e.g. a 5 % error of a log-std moves the std by ~4 SE)
    assert res.mean_ci["xy"][0] < mean < res.mean_ci["xy"][1]
    assert res.std_ci["xy"][0] < std < res.std_ci["xy"][1]
    assert res.p_ci["xy"][0] < p_low < res.p_ci["xy"][1]
    assert res.p_sides["xy"] == (res.p_exceed["xy"], 0.0)
    assert "monte-carlo (mc)" in repr(res)


def test_form_and_importance_sampling_through_propagate():
    J = JointDistribution({"x1": stats.norm(10.0, 5.0), "x2": stats.norm(9.9, 5.0)})

    def cubic(p):
        x1, x2 = p["x1"], p["x2"]
        return {"g": x1**3 + x2**3}, {"g": {"x1": 3 * x1 * x1, "x2": 3 * x2 * x2}}

    allow = {"g": (18.0, None)}
    a = propagate(FunctionTask(cubic), J, "importance-sampling", allowables=allow, n=64,
                  seed=2, executor="serial")
    b = importance_sampling(FunctionTask(cubic), J,
                            form(FunctionTask(cubic), J, allow, executor="serial"), 64,
                            seed=2, executor="serial")
    assert a.p_exceed == b.p_exceed and a.runs == b.runs


@pytest.mark.parametrize("kwargs, match", [
    ({"method": "sorm"}, "method must be one of"),
    ({"method": "monte-carlo"}, "needs n"),
    ({"method": "monte-carlo", "n": 8, "sampling": "grid"}, "sampling must be"),
    ({"method": "importance-sampling", "allowables": {"xy": (1.0, None)}}, "needs n"),
    ({"method": "fosm"}, "needs gradients"),
    ({"method": "form", "allowables": {"xy": (1.0, None)}}, "needs gradients"),
])
def test_bad_input(kwargs, match):
    with pytest.raises(StudyError, match=match):
        propagate(product, LOGNORMALS, executor="serial", **kwargs)


# ---------------------------------------------------------------- on a Dask cluster
SETTINGS = {"t_end": 0.008, "dt": 5e-4}
RESPONSES = {"stress": ml.responses.ks_max_stress("beam", 2.0),
             "tip": ml.responses.point_displacement("beam", (100.0, 0.0), 1)}
CANTILEVER = {"t": stats.norm(2.0, 0.1), "F": stats.lognorm(0.2, scale=1.0)}


def _all_functions(executor):
    """Every new study function on a small simulation task, on ``executor``."""
    task = SimulationTask(tip_loaded_cantilever, RESPONSES, SETTINGS, gradients=True)
    J = JointDistribution(CANTILEVER, rank_correlation={("t", "F"): 0.3})
    allow = {"stress": (None, 30.0)}
    out = {"fosm": propagate(task, J, "fosm", allowables=allow, executor=executor),
           "mc": propagate(task, J, "monte-carlo", n=12, allowables=allow, executor=executor),
           "is": propagate(task, J, "importance-sampling", n=8, allowables=allow,
                           executor=executor),
           "sobol": sobol_indices(task, CANTILEVER, 4, executor=executor)}
    problem = Problem(tip_loaded_cantilever, {"t": 2.0, "F": 1.0}, RESPONSES, "tip",
                      constraints=[Constraint("stress", upper=30.0)],
                      bounds={"t": (1.8, 2.4), "F": (0.8, 1.2)}, settings=SETTINGS)
    out["multistart"] = multistart(problem, 2, "SLSQP", executor=executor, seed=0,
                                   max_runs=3)
    return out


def _same(a, b) -> bool:
    """Bitwise equality of nested results (floats compared by their bits, NaN = NaN)."""
    if hasattr(a, "__dataclass_fields__"):
        return type(a) is type(b) and all(
            _same(getattr(a, f), getattr(b, f)) for f in a.__dataclass_fields__
            if f not in ("table", "wall_time"))
    if isinstance(a, dict):  # wall-clock times differ from run to run
        return a.keys() == b.keys() and all(_same(a[k], b[k]) for k in a
                                            if k not in ("time", "duration", "wall_time"))
    if isinstance(a, list | tuple):
        return len(a) == len(b) and all(_same(x, y) for x, y in zip(a, b))
    if isinstance(a, np.ndarray | float | np.floating):
        return np.array_equal(np.asarray(a), np.asarray(b), equal_nan=True)
    return a == b


@pytest.mark.slow
def test_bitwise_equal_on_a_dask_cluster():
    """Two worker processes of a LocalCluster against this process: every number of every
    result the same bit for bit, multi-start optimizations included (about 10 s: the
    cluster's start-up and ~130 small runs)."""
    distributed = pytest.importorskip("distributed")
    serial = _all_functions("serial")
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                  dashboard_address=None) as cluster, \
            distributed.Client(cluster) as client:
        dask = _all_functions(client.get_executor())
    for name in serial:
        assert _same(serial[name], dask[name]), name
    for name in ("mc", "sobol"):  # the rows themselves
        assert np.array_equal(serial[name].table.values["stress"],
                              dask[name].table.values["stress"])
    assert serial["is"].limit_states["stress", "upper"].is_n == 8
    assert [r.n_runs for r in serial["multistart"].results] == [3, 3]
