"""Compile the kernels ahead of need.

Numba compiles a kernel for each kind of model it meets (the set of item kinds, dense or
sparse step matrices, real or complex numbers) and caches the machine code on disk
(``cache=True``), so later processes only load it. :func:`warmup_for` runs a model's time
loop and sensitivity methods over a few steps, which compiles exactly what the full runs of
that model need (:mod:`morphlab.morphing.warmup` does it for the main command's model);
:func:`warmup`, a tiny model's (the workers of a parameter study call it).
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


def warmup_for(build, p0: dict, responses: dict, settings, methods=("direct",),
               steps: int = 10, report=None) -> dict:
    """Compile what the runs of ``build(p0)`` need: its time loop and the sensitivity
    ``methods``, run over ``steps`` time steps of ``settings`` (their kernels are those of a
    full run: same kinds of items, same kind of step matrices). While a kernel compiles,
    :class:`~morphlab.jit.progress.CompileProgress` reports it.

    Parameters
    ----------
    report : callable, optional
        Called with a line of text before each group (default ``print`` to stderr).

    Returns
    -------
    dict
        Wall seconds per group: ``"time loop"`` and each method's name.
    """
    import sys
    import time

    from .jit.progress import ESTIMATES
    from .sensitivity.api import sensitivities
    from .solve.settings import Settings
    from .solve.timeloop import simulate

    say = report or (lambda t: print(t, file=sys.stderr, flush=True))
    short = Settings.of(settings, t_end=steps * Settings.of(settings).dt)
    groups = ["time loop", *methods]
    known = [g for g in groups if g in ESTIMATES]
    about = (f" (about {sum(ESTIMATES[g] for g in known):.0f} CPU-s on the 2-core reference "
             "machine of the benchmarks when nothing is cached"
             + ("" if len(known) == len(groups) else
                f"; no estimate for {', '.join(g for g in groups if g not in known)}") + ")"
             if known else "")
    say(f"morphlab warmup: {', '.join(groups)}{about}")
    seconds = {}
    for group in groups:
        say(f"morphlab warmup: {group}")
        t0 = time.perf_counter()
        if group == "time loop":
            simulate(build(p0), settings=short)
        else:
            sensitivities(build, p0, responses, method=group, settings=short)
        seconds[group] = time.perf_counter() - t0
    return seconds

