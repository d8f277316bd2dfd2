"""Compile every kernel once (float64 and complex128) on a tiny model.

Numba caches the machine code on disk (``cache=True``), so after the first call in a fresh
environment later processes only load it. Calling :func:`warmup` up front moves that one-off
cost out of the first real run (and out of timed benchmarks).
"""

from __future__ import annotations

import numpy as np


def _tiny_build(p):
    from .model import Model
    from .model.profiles import SmoothStep

    m = Model(gravity=(0.0, -9.81e3), name="warmup")
    nodes = np.array([[0.0, 0.0], [10.0, 0.0], [20.0, 0.0]]) + np.array([p["x"], 0.0])
    beam = m.add_beam(nodes, E=p["E"], rho=2.7e-9, thickness=1.0, width=10.0, damping=1e-5,
                      name="beam")
    link = m.add_rigid_body(mass=1e-5, inertia=1e-3, position=(p["x"] + 25.0, 0.0),
                            name="link")
    m.add_fix(beam, at=tuple(nodes[0]), dofs="xyr")
    m.add_revolute(beam, link, at=tuple(nodes[2]))
    m.add_fix(link, at=(p["x"] + 25.0, 0.0), dofs="r")  # statically determinate for static()
    m.add_force(beam, at=tuple(nodes[1]), force=(0.0, -1.0), profile=SmoothStep(0.0, 0.01))
    m.add_torque(link, 1.0, profile=SmoothStep(0.0, 0.01))
    return m


def warmup() -> None:
    """Compile (or load from the cache) all kernels for float64 and complex128."""
    from .results.responses import point_displacement
    from .sensitivity.api import sensitivities
    from .solve.statics import static
    from .solve.timeloop import simulate

    p = {"x": 0.0, "E": 7.0e4}
    simulate(_tiny_build(p), t_end=0.002, dt=0.001)
    static(_tiny_build(p), t=0.01)
    resp = {"d": point_displacement("beam", (20.0, 0.0), 1)}
    for method in ("direct", "direct-fd"):
        sensitivities(_tiny_build, p, resp, t_end=0.002, dt=0.001, method=method)
