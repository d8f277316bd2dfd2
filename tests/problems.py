"""Analytic design problems shared by the study tests (each evaluates in microseconds)."""

from morphlab.studies import Constraint, Problem


def rosenbrock(p):
    """Rosenbrock's function ``f`` and a constraint value ``g = x + 2 (y - 1/4)^2``, with their
    gradients: ``(values, gradients)`` as a function problem returns them."""
    x, y = p["x"], p["y"]
    values = {"f": (1 - x) ** 2 + 100 * (y - x * x) ** 2, "g": x + 2 * (y - 0.25) ** 2}
    grads = {"f": {"x": -2 * (1 - x) - 400 * x * (y - x * x), "y": 200 * (y - x * x)},
             "g": {"x": 1.0, "y": 4 * (y - 0.25)}}
    return values, grads


def rosenbrock_problem(fn=rosenbrock, **kw) -> Problem:
    """Minimize ``f`` of ``fn`` (by default :func:`rosenbrock`) from (-1.2, 1) subject to
    ``g <= 0.5`` within bounds; the optimum is (0.5, 0.25), on the constraint. ``kw``: more
    keywords of :meth:`Problem.from_function`."""
    return Problem.from_function(fn, {"x": -1.2, "y": 1.0}, "f",
                                 constraints=[Constraint("g", upper=0.5)],
                                 bounds={"x": (-2.0, 2.0), "y": (-1.0, 3.0)}, **kw)
