"""Sobol' indices (morphlab.studies.indices).

* The Ishigami function ``sin x1 + a sin² x2 + b x3⁴ sin x1``, ``x_i ~ U(-π, π)``, a = 7,
  b = 0.1, against its analytic indices (Ishigami & Homma 1990; the values of e.g. Saltelli
  et al., *Global Sensitivity Analysis: The Primer*, Wiley 2008): S = (0.3139, 0.4424, 0),
  S_T = (0.5576, 0.4424, 0.2437).
* A cantilever simulation (t, F and E uniform) against a brute-force reference: the defining
  integrals ``V(E[Y | X_i])`` and ``E(V[Y | X_~i])`` evaluated on a tensor Gauss–Legendre grid
  of the same simulations (6 points per variable: exact for polynomials of degree 11; the
  response is analytic in the box, and 5 points give the same indices to 3e-6).
"""

import numpy as np
import pytest
from models import E_AL, RHO_AL, straight_nodes
from scipy import stats

import morphlab as ml
from morphlab.studies import SimulationTask, StudyError, sobol_indices, sweep

PI = np.pi
ISHIGAMI_FIRST = {"x1": 0.3139, "x2": 0.4424, "x3": 0.0}
ISHIGAMI_TOTAL = {"x1": 0.5576, "x2": 0.4424, "x3": 0.2437}


def ishigami(p):
    x1, x2, x3 = p["x1"], p["x2"], p["x3"]
    return {"y": np.sin(x1) + 7.0 * np.sin(x2) ** 2 + 0.1 * x3**4 * np.sin(x1)}


def test_ishigami_within_the_published_values():
    dists = {k: stats.uniform(-PI, 2 * PI) for k in ("x1", "x2", "x3")}
    res = sobol_indices(ishigami, dists, 4096, executor="serial", seed=1)
    assert res.n == 4096 and res.runs == 5 * 4096
    for v in dists:
        for est, se, ref in ((res.first, res.first_se, ISHIGAMI_FIRST),
                             (res.total, res.total_se, ISHIGAMI_TOTAL)):
            # within 4 bootstrap standard errors (0.007 to 0.02 here) plus the 5e-5 rounding
            # of the published values
            assert abs(est["y"][v] - ref[v]) < 4 * se["y"][v] + 5e-5, (v, est["y"][v], ref[v])
        lo, hi = res.first_ci["y"][v]
        assert lo <= res.first["y"][v] <= hi
    # the variance of the Ishigami function: a²/8 + b π⁴/5 + b² π⁸/18 + 1/2 = 13.845
    assert res.variance["y"] == pytest.approx(13.8446, rel=0.03)
    assert "x3" in repr(res)


# ---------------------------------------------------------------- a simulation
SETTINGS = {"t_end": 0.012, "dt": 5e-4}
BOX = {"t": (1.7, 2.3), "F": (0.5, 1.5), "E": (0.9 * E_AL, 1.1 * E_AL)}
RESPONSES = {"tip": ml.responses.point_displacement("beam", (100.0, 0.0), 1)}


def cantilever(p):
    """The strip of tests/models.tip_loaded_cantilever with its modulus a variable."""
    m = ml.Model(gravity=(0.0, 0.0))
    beam = m.add_beam(straight_nodes(4), E=p["E"], rho=RHO_AL, thickness=p["t"], width=10.0,
                      damping=1e-4, name="beam")
    m.add_fix(beam, at=(0.0, 0.0), dofs="xyr")
    m.add_force(beam, at=(100.0, 0.0), force=(0.0, -p["F"]), profile=ml.SmoothStep(0.0, 4e-3))
    return m


def quadrature_indices(task, k: int):
    """First and total indices of ``tip`` from a k³ Gauss-Legendre grid (module docstring)."""
    x, w = np.polynomial.legendre.leggauss(k)
    w = w / 2.0
    axes = {v: a + (b - a) * (x + 1) / 2 for v, (a, b) in BOX.items()}
    grid = np.meshgrid(*axes.values(), indexing="ij")
    table = sweep(task, {v: g.ravel() for v, g in zip(BOX, grid)}, executor="serial")
    f = table.values["tip"].reshape(k, k, k)
    mean = np.einsum("i,j,k,ijk", w, w, w, f)
    var = np.einsum("i,j,k,ijk", w, w, w, f * f) - mean**2
    first, total = {}, {}
    for v, alone, rest in (("t", "i,j,k,ijk->i", "i,ijk->jk"), ("F", "i,j,k,ijk->j", "j,ijk->ik"),
                           ("E", "i,j,k,ijk->k", "k,ijk->ij")):
        cond = np.einsum(alone, np.ones(k), w, w, f) if v == "t" else None
        if v == "F":
            cond = np.einsum(alone, w, np.ones(k), w, f)
        if v == "E":
            cond = np.einsum(alone, w, w, np.ones(k), f)
        first[v] = (w @ cond**2 - mean**2) / var  # V(E[Y | X_v]) / V
        c = np.einsum(rest, w, f)  # E[Y | the other two], on their grid
        total[v] = 1.0 - (w @ c**2 @ w - mean**2) / var  # E(V[Y | X_~v]) / V
    return first, total


@pytest.mark.slow
def test_simulation_indices_against_quadrature():
    task = SimulationTask(cantilever, RESPONSES, SETTINGS)
    first, total = quadrature_indices(task, 6)
    res = sobol_indices(task, {v: stats.uniform(a, b - a) for v, (a, b) in BOX.items()}, 128,
                        executor="serial", seed=4)
    for v in BOX:
        # 128 rows: bootstrap standard errors 0.01 to 0.05; 4 of them
        assert abs(res.first["tip"][v] - first[v]) < 4 * res.first_se["tip"][v], v
        assert abs(res.total["tip"][v] - total[v]) < 4 * res.total_se["tip"][v], v
    # the deflection ~ F / (E t³): t carries most of the variance, then F, then E
    assert first["t"] > first["F"] > first["E"] > 0.0


@pytest.mark.parametrize("kwargs, match", [
    ({"n": 100}, "power of two"),
    ({"n": 64, "confidence": 2.0}, "confidence"),
    ({"n": 64, "fixed": {"x1": 0.0}}, "both random and fixed"),
])
def test_bad_input(kwargs, match):
    dists = {k: stats.uniform(-PI, 2 * PI) for k in ("x1", "x2", "x3")}
    with pytest.raises(StudyError, match=match):
        sobol_indices(ishigami, dists, executor="serial", **kwargs)


def test_correlated_variables_are_refused():
    from morphlab.studies import JointDistribution

    J = JointDistribution({"a": stats.norm(0, 1), "b": stats.norm(0, 1)},
                          rank_correlation={("a", "b"): 0.5})
    with pytest.raises(StudyError, match="independent"):
        sobol_indices(lambda p: {"y": p["a"]}, J, 16, executor="serial")
